"""The joint-torque loop against the actuator (issue 19): the corrections get only what the motors' peak
current leaves beside the desired torque, the integrator does not wind up behind the current clamp, the
clamps follow who is on the device, and the law renders the commanded damping."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from ankle_rt.bench.impedance import Experiment, bench_config, run_impedance
from ankle_rt.config import load_config
from ankle_rt.config_schema import MAX_CORRECTION_BENCH, MAX_CORRECTION_WALKED
from ankle_rt.control.torque_loop import JointTorqueLoop, TorqueLoopGains, correction_room
from ankle_rt.lead import law_damping, loop_lag
from ankle_rt.loop_setup import ReflectedActuator
from ankle_rt.paths import default_config_path
from tests.conftest import ROOT


def test_the_correction_room_takes_back_only_what_passes_the_limit():
    """Element-wise, floats and arrays alike: 1 where the motor torque fits or the correction pulls it
    back, the share that lands the total on the limit where it pushes beyond, 0 where the rest alone is
    beyond the limit."""
    total = np.array([10.0, 18.0, 18.0, -18.0, 25.0])
    correction = np.array([5.0, 6.0, -6.0, -6.0, 5.0])
    room = correction_room(total, correction, 15.0)
    assert room.tolist() == pytest.approx([1.0, 0.5, 1.0, 0.5, 0.0])
    rest = total - correction
    assert abs(rest[1] + room[1] * correction[1]) == pytest.approx(15.0)
    assert [correction_room(float(t), float(c), 15.0) for t, c in zip(total, correction)] == pytest.approx(room)


@pytest.fixture(scope="module")
def base():
    return load_config(default_config_path())


def test_at_the_current_clamp_the_integral_holds(base):
    """A torque error the motors cannot close (fit scales every correction to nothing): the integral
    keeps its value instead of winding up, the output is the desired torque, and the loop integrates
    again once the room is back."""
    gains = TorqueLoopGains.from_config(base["controller"]["torque_loop"], base["transmission"]["cable_stiffness"])
    loop = JointTorqueLoop(gains, 1e-3, ReflectedActuator.from_config(base), motor_limit=10.0)
    free = JointTorqueLoop(gains, 1e-3, ReflectedActuator.from_config(base), motor_limit=10.0)
    for _ in range(200):
        free.update(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, True)
        loop.update(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, True)
        u0, _ = loop.fit(0.0)
        assert u0 == pytest.approx(1.0)
    assert loop.i0 == pytest.approx(0.0, abs=1e-12)
    assert free.i0 > 0.5                     # the same error unclamped: the integral grows
    loop.update(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, True)
    assert loop.i0 > 0.0
    half = loop.c0 * 0.5
    assert loop.fit(0.5)[0] == pytest.approx(1.0 + half)


def write(tmp_path, body: dict):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump({"include": [str(ROOT / "config" / "sim.yaml")], **body}))
    return path


def test_unset_clamps_follow_who_walks(tmp_path):
    """The bench's clamps where nobody walks, the walked ones in the walking scenario and on the device;
    a configured clamp is kept."""
    bench = load_config(write(tmp_path, {}))["controller"]["torque_loop"]
    assert (bench["max_correction_dp"], bench["max_correction_ie"]) == MAX_CORRECTION_BENCH
    walking = load_config(ROOT / "config" / "walk.yaml")["controller"]["torque_loop"]
    assert (walking["max_correction_dp"], walking["max_correction_ie"]) == MAX_CORRECTION_WALKED
    for hw in ("hw-serial.yaml", "hw-can.yaml"):
        if (ROOT / "config" / hw).exists():
            tl = load_config(ROOT / "config" / hw)["controller"]["torque_loop"]
            assert (tl["max_correction_dp"], tl["max_correction_ie"]) == MAX_CORRECTION_WALKED, hw
    kept = load_config(write(tmp_path, {"controller": {"torque_loop": {"max_correction_dp": 12.0}}}))
    assert kept["controller"]["torque_loop"]["max_correction_dp"] == 12.0
    assert kept["controller"]["torque_loop"]["max_correction_ie"] == MAX_CORRECTION_BENCH[1]


@pytest.mark.parametrize("k_dp", [50.0, 200.0])
def test_the_law_renders_the_commanded_damping(base, k_dp):
    """Lockstep sines of 6 N m DP / 3 N m IE at 0.5 and 1 Hz with the identified friction compensated: the
    damping the ankle renders (Im Z / w) is the commanded one within the issue's 30 % (the law leads the
    loop's lag on the spring torque and makes up for the cable's share of the motor's motion)."""
    cfg = bench_config(base, stiffness=(k_dp, k_dp / 2), damping=(0.5, 0.25), torque_feedback="auto",
                       friction_ff="identified", effects=[])
    exp = Experiment(pulses_nm=((), ()), sine_hz=(0.5, 1.0), sine_nm=((6.0,), (3.0,)), axes=("dp", "ie"),
                     sine_cycles=3, analysed_cycles=2, rest_s=0.5, step_nm=(0.0, 0.0))
    res = run_impedance(cfg, exp)
    assert res.fault == "NONE"
    for s in res.sines:
        commanded = 0.5 if s["axis"] == "dp" else 0.25
        assert s["damping"] == pytest.approx(commanded, rel=0.3), (s["axis"], s["freq_hz"])


def test_the_law_damping_leads_the_lag_and_the_cable():
    """B_law = (B + K lag) / (1 - K / k_c), the lag the rate term's less the filter's delay."""
    assert loop_lag(9.0, 0.1, 1.0, 1e-3) == pytest.approx(0.01)
    assert loop_lag(9.0, 0.1, 0.5, 1e-3) == pytest.approx(0.01 - 1e-3)
    assert law_damping(100.0, 0.25, 0.01, float("inf")) == pytest.approx(1.25)
    assert law_damping(100.0, 0.25, 0.0, 200.0) == pytest.approx(0.5)
