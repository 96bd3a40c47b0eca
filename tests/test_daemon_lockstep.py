"""The daemon's lockstep contract: run_lockstep on the simulator with the configured PD, RunResult
columns with interchange names, and a custom CycleController plugged in."""

from __future__ import annotations


import numpy as np
import pytest

from ankle_rt.control import CycleController
from ankle_rt.daemon import run_lockstep
from ankle_rt.estimation import Estimate
from ankle_rt.interchange import read_csv, write_csv
from ankle_rt.safety import State


def test_section7_default_run_tracks_steps_and_exports(sim_cfg, tmp_path):
    res = run_lockstep(sim_cfg, 2.0)
    assert len(res) == 2000
    cols = res.columns
    for name in ("t", "motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2", "sg_torque_dp",
                 "sg_torque_ie", "ankle_dp", "ankle_ie", "ref_dp", "ref_ie", "est_ankle_dp", "est_ankle_ie",
                 "motor_vel_1", "motor_vel_2", "state", "fault"):
        assert name in cols, name
    # tare with the amplifiers off, then active; nothing sent before activation
    assert cols["state"][0] == State.CONFIGURED and cols["state"][-1] == State.ACTIVE
    assert np.all(cols["current_cmd_1"][cols["state"] != State.ACTIVE] == 0.0)
    # steps of 10 deg DP and 5 deg IE at 0.5 s, reached within 0.1 deg by 1.9 s
    assert np.degrees(cols["ref_dp"][-1]) == pytest.approx(10.0, abs=1e-3)
    assert np.degrees(cols["ref_ie"][-1]) == pytest.approx(5.0, abs=1e-3)
    assert np.degrees(abs(cols["ankle_dp"][1900] - cols["ref_dp"][1900])) < 0.1
    assert np.degrees(abs(cols["ankle_ie"][1900] - cols["ref_ie"][1900])) < 0.1
    out = tmp_path / "run.csv"
    write_csv(out, res.interchange())
    rec = read_csv(out)
    assert len(rec) == 2000 and rec.input_kind == "current" and "ankle_dp" in rec


class ConstantTorque:
    """0.1 N m on motor 1 after a reset: a minimal identification-style experiment."""

    def __init__(self):
        self.resets = 0

    def reset(self, est: Estimate) -> None:
        self.resets += 1

    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        out_torque[0] = 0.1
        out_torque[1] = 0.0


def test_custom_controller_output_reaches_the_amplifier_as_current(sim_cfg):
    ctl = ConstantTorque()
    assert isinstance(ctl, CycleController)
    res = run_lockstep(sim_cfg, 0.3, controller=ctl)
    active = res["state"] == State.ACTIVE
    assert ctl.resets == 1 and active.any()
    assert np.allclose(res["current_cmd_1"][active], 0.1 / sim_cfg["actuator"]["torque_constant"])
    assert np.all(np.isnan(res["ref_dp"]))           # no reference of its own
    assert "ref_dp" not in res.interchange()
