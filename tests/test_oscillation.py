"""Issue 19 item 2, the last line: the run-time oscillation detector (ankle_rt.oscillation) faults a
hot joint-torque loop that the gain checks would refuse (built here around them), and leaves the
shipped loop, walking-like motion and step loads alone."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ankle_rt.config import load_config
from ankle_rt.control.impedance import ImpedanceController
from ankle_rt.control.torque_loop import JointTorqueLoop, TorqueLoopGains
from ankle_rt.daemon import run_lockstep
from ankle_rt.bench.impedance import bench_config
from ankle_rt.kinematics import Kinematics
from ankle_rt.oscillation import OscillationDetector
from ankle_rt.params import TransmissionParams
from ankle_rt.paths import default_config_path
from ankle_rt.safety import Fault, State

PUSH_T = 1.0


@pytest.fixture(scope="module")
def cfg():
    c = bench_config(load_config(default_config_path()), stiffness=(50.0, 25.0), damping=(0.5, 0.25),
                     torque_feedback="auto", friction_ff=None,
                     effects=[{"type": "load_dependent_friction", "coefficient": 0.12},       # the issue's plant
                              {"type": "stribeck", "static_excess": 0.15, "stribeck_velocity": 0.1}])
    c["sim"]["disturbances"] = [{"start": PUSH_T, "stop": PUSH_T + 0.05, "torque_dp": 3.0, "torque_ie": 0.0}]
    return c


def loop_controller(cfg, kp, max_correction):
    """The impedance controller with a joint-torque loop of gain ``kp`` built directly (no margin check:
    the config loader and set_gains refuse kp 100)."""
    g = TorqueLoopGains(kp=(kp, kp), ki=(10.0, 10.0), torque_rate=(0.03, 0.06), cutoff_hz=80.0,
                        max_correction_nm=(max_correction, max_correction))
    kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
    return ImpedanceController(kin, np.zeros(2), cfg["controller"]["impedance"], dt=1e-3, ramp_s=0.2,
                               soft_start_s=0.2, torque_loop=JointTorqueLoop(g, 1e-3))


@pytest.mark.parametrize("max_correction", [100.0, 20.0])
def test_the_issue_oscillations_fault_within_a_second_of_the_push(cfg, max_correction):
    """kp 100: one 3 N m, 50 ms push starts the ~80 Hz oscillation (46.5 s to OVERCURRENT with max
    correction 100, never a fault with 20, before)."""
    rec = run_lockstep(cfg, 3.0, controller=loop_controller(cfg, 100.0, max_correction))
    assert rec.summary["fault"] == Fault.OSCILLATION.name
    t_fault = rec["t"][np.flatnonzero(rec["state"] == int(State.FAULT))[0]]
    assert PUSH_T < t_fault < PUSH_T + 1.0


def test_the_shipped_loop_does_not_fault_on_the_push(cfg):
    rec = run_lockstep(cfg, 3.0, controller=loop_controller(cfg, 6.0, 20.0))
    assert rec.summary["fault"] == "NONE"


def test_detection_time_and_no_fault_on_walking_or_steps():
    dt = 1e-3
    t = np.arange(0.0, 3.0, dt)
    det = OscillationDetector(dt, rms_limit_a=1.0, hold_s=0.5)
    fired = [det.update(i, -i) for i in 4.0 * np.sin(2.0 * math.pi * 80.0 * t)]    # +-4 A at 80 Hz
    assert 0.5 <= fired.index(True) * dt <= 0.55
    for signal in (12.0 * np.sin(2.0 * math.pi * 1.0 * t) + 3.0 * np.sin(2.0 * math.pi * 4.0 * t),   # gait-like
                   np.where((t % 1.0) < 0.5, 15.0, -15.0)):                       # 30 A steps every 0.5 s
        det.reset()
        assert not any(det.update(i, 0.5 * i) for i in signal)


def test_the_detector_runs_element_wise_on_a_batch():
    dt = 1e-3
    t = np.arange(0.0, 1.0, dt)
    amps = np.array([0.5, 2.0, 4.0])          # A at 80 Hz: below, above, far above the 1 A RMS limit
    batch = OscillationDetector(dt, 1.0, 0.25)
    one = [OscillationDetector(dt, 1.0, 0.25) for _ in amps]
    for tk in t:
        i = amps * math.sin(2.0 * math.pi * 80.0 * tk)
        out = batch.update(i, 0.0 * i)
        assert list(out) == [d.update(float(x), 0.0) for d, x in zip(one, i)]
    assert list(out) == [False, True, True]
