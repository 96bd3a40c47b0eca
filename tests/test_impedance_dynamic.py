"""The impedance the wearer feels in motion (issue 19): no amplitude collapse, the dynamic stiffness,
passivity robust to the cable stiffness, joint encoders against cable backlash, and the observer's
energy tank. Short lockstep runs on the simulator with the issue's plant (load-dependent friction
0.12 + Stribeck)."""

from __future__ import annotations

import pytest

from ankle_rt.config import load_config
from ankle_rt.config_schema import MAX_CORRECTION_WALKED
from ankle_rt.control.torque_loop import JointTorqueLoop, TorqueLoopGains
from ankle_rt.loop_setup import ReflectedActuator
from ankle_rt.bench.impedance import Experiment, bench_config, run_impedance
from ankle_rt.paths import default_config_path
from tests.test_joint_blend import BACKLASH, with_play

PLANT = [{"type": "load_dependent_friction", "coefficient": 0.12},
         {"type": "stribeck", "static_excess": 0.15, "stribeck_velocity": 0.1}]
NO_STEP = (0.0, 0.0)


@pytest.fixture(scope="module")
def base():
    return load_config(default_config_path())


def impedance_cfg(base, k_dp, effects=PLANT, **impedance):
    cfg = bench_config(base, stiffness=(k_dp, k_dp / 2), damping=(0.5, 0.25), torque_feedback="auto",
                       friction_ff=None, effects=effects)
    cfg["controller"]["impedance"].update(impedance)
    return cfg


def sines(res, axis):
    return {(s["amplitude_nm"], s["freq_hz"]): s for s in res.sines if s["axis"] == axis}


def test_a_large_fast_push_renders_the_same_stiffness(base):
    """K_dp 200: a 15 N m, 2 Hz push renders the stiffness a 6 N m one does (the old loop's clamp and
    integrator wind-up made it 9 N m/rad against 158), and at 1 Hz both are within the issue's 15 %."""
    exp = Experiment(pulses_nm=((), ()), sine_hz=(1.0, 2.0), sine_nm=((6.0, 15.0), ()), axes=("dp",),
                     sine_cycles=3, analysed_cycles=2, rest_s=0.5, step_nm=NO_STEP)
    res = run_impedance(impedance_cfg(base, 200.0), exp)
    assert res.fault == "NONE"
    s = sines(res, "dp")
    assert abs(s[15.0, 2.0]["dynamic_stiffness"] / s[6.0, 2.0]["dynamic_stiffness"] - 1.0) < 0.1
    for amp in (6.0, 15.0):
        assert abs(s[amp, 1.0]["dynamic_stiffness_error_pct"]) <= 15.0, amp
        assert s[amp, 1.0]["damping"] > 0.0


@pytest.mark.parametrize("factor", [0.7, 1.3])
def test_passive_with_the_cable_stiffness_off_by_30_percent(base, factor):
    """The plant's cables 30 % softer or stiffer than the controller's model: no sine cycle gives net
    energy back to the foot, including the IE 7.5 N m 2 Hz push at K_ie 100 that did before the law
    led the loop's lag."""
    cfg = impedance_cfg(base, 200.0)
    plant_cfg = cfg.deep_copy()
    plant_cfg["transmission"]["cable_stiffness"] *= factor
    exp = Experiment(pulses_nm=((), ()), sine_hz=(2.0,), sine_nm=((15.0,), (3.0, 7.5)), sine_cycles=3,
                     analysed_cycles=2, rest_s=0.5, step_nm=NO_STEP)
    res = run_impedance(cfg, exp, plant_cfg=plant_cfg)
    assert res.fault == "NONE"
    assert len(res.sines) == 3
    assert res.passive(), [(s["axis"], s["amplitude_nm"], s["loop_energy_j"]) for s in res.sines]


def test_joint_encoders_see_the_cable_backlash(base):
    """0.2 mm of cable slack each way at K_dp 200, with the clamps a device gets: through the cables the
    rendered stiffness is far too soft for small pushes (the estimated angle cannot see slack); with the
    joint encoders in the law it is within the issue's 15 %. (With the simulator bench's clamps, 150 / 60
    N m, the slack's limit cycle grows into OSCILLATION at the 6 N m pulse: docs/daemon.md "Sixth pass".)"""
    effects = PLANT + [BACKLASH]
    exp = Experiment(pulses_nm=((3.0, -3.0, 6.0), ()), pulse_s=1.2, rest_s=0.5, sine_hz=(), axes=("dp",),
                     step_nm=NO_STEP)

    def device(cfg):        # its clamps, and its play stated to the joint cross-check
        cfg["controller"]["torque_loop"].update(zip(("max_correction_dp", "max_correction_ie"), MAX_CORRECTION_WALKED))
        return with_play(cfg)

    encoders = run_impedance(device(impedance_cfg(base, 200.0, effects, angle_source="joint_encoders")), exp)
    cables = run_impedance(device(impedance_cfg(base, 200.0, effects, angle_source="estimated")), exp)
    assert encoders.fault == cables.fault == "NONE"
    assert encoders.stiffness_error_max_pct() <= 15.0
    assert cables.stiffness_error_max_pct() > 15.0


def test_the_empty_tank_lets_the_observer_only_brake(base):
    """The observer pushing along the motion (friction cancelling) drains the tank; once it is empty
    the observer's torque along the motion is cut, while braking stays allowed."""
    tl = dict(base["controller"]["torque_loop"], dob_hz=20.0, tank_j=0.01, tank_friction_credit=0.0,
              kp_dp=0.0, kp_ie=0.0, ki_dp=0.0, ki_ie=0.0, torque_rate_dp=0.0, torque_rate_ie=0.0,
              motor_rate_damping_dp=0.0, motor_rate_damping_ie=0.0)
    gains = TorqueLoopGains.from_config(tl, base["transmission"]["cable_stiffness"])
    loop = JointTorqueLoop(gains, 1e-3, ReflectedActuator.from_config(base))
    loop.reset_state(0.0, 0.0)
    # constant speed, no cable torque: what the loop commands looks like friction to the observer
    outs = [loop.update(2.0, 0.0, 0.0, 0.0, 1.0, 0.0, True)[0] - 2.0 for _ in range(400)]
    assert max(outs) > 0.5                        # it pushed along the motion ...
    assert outs[-1] == 0.0 and loop.e0 == 0.0     # ... until the tank ran dry
    braking = [loop.update(-2.0, 0.0, 0.0, 0.0, 1.0, 0.0, True)[0] + 2.0 for _ in range(400)]
    assert min(braking) < -0.5                    # against the motion it still acts


def test_activation_does_not_read_the_rate_left_from_before_as_a_disturbance(base):
    """The observer differences the motor rate from the last cycle: after a reset at rest, a rate
    left from before (the ankle moving fast when the run was deactivated) must not kick it."""
    tl = dict(base["controller"]["torque_loop"], dob_hz=20.0)
    gains = TorqueLoopGains.from_config(tl, base["transmission"]["cable_stiffness"])
    act = ReflectedActuator.from_config(base)
    used, fresh = JointTorqueLoop(gains, 1e-3, act), JointTorqueLoop(gains, 1e-3, act)
    for _ in range(50):
        used.update(0.0, 0.0, 0.0, 0.0, 8.0, -6.0, True)    # moving fast, then deactivated
    for loop in (used, fresh):
        loop.reset_state(1.0, -0.5, 0.0, 0.0)                  # activation at rest
    first = [loop.update(1.0, -0.5, 1.0, -0.5, 0.0, 0.0, True) for loop in (used, fresh)]
    assert first[0] == first[1]
    assert used.d0 == fresh.d0 == 0.0 and used.d1 == fresh.d1 == 0.0
