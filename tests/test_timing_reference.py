"""The benchmarks' machine-independent unit and the daemon-alone measurement (issue 18): what they
compute, not how fast (timing depends on the machine)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ankle_rt.bench.replay import ReplayBackend, daemon_cycle_s, record_frames
from ankle_rt.clock import SimClock
from ankle_rt.daemon import run_lockstep
from ankle_rt.linear_model import LinearModel
from ankle_rt.params import PlantParams
from ankle_rt.timing_reference import H_S, _nominal_model, reference_step, reference_step_s


def test_the_reference_step_is_an_rk4_step_of_the_nominal_cable_model(sim_cfg):
    """The plain-Python step against numpy RK4 on the model's own A and B with the same forces."""
    p = PlantParams.from_config(sim_cfg)
    lin = LinearModel.from_params(p)
    _, grav, kc, vs = _nominal_model()
    assert (grav, kc, vs) == (p.foot.gravity_gain, p.actuator.coulomb, p.actuator.friction_smoothing_velocity)

    def f(x, tau1, tau2):
        forces = np.array([-grav * (math.sin(x[0]) - x[0]), 0.0, tau1 - kc * math.tanh(x[6] / vs),
                           tau2 - kc * math.tanh(x[7] / vs)])
        return lin.A @ x + lin.B @ forces

    x = np.array([0.05, -0.02, 0.3, -0.1, 0.2, 0.1, -0.5, 0.4])
    k1 = f(x, 0.3, -0.2)
    k2 = f(x + 0.5 * H_S * k1, 0.3, -0.2)
    k3 = f(x + 0.5 * H_S * k2, 0.3, -0.2)
    k4 = f(x + H_S * k3, 0.3, -0.2)
    want = x + H_S / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    got = reference_step(x.tolist(), 0.3, -0.2)
    assert np.allclose(got, want, rtol=1e-12, atol=1e-12)
    assert not np.allclose(got, x.tolist())


def test_reference_step_time_is_a_positive_median():
    s = reference_step_s(repeats=5, steps=3)
    assert 0.0 < s < 1.0 and math.isfinite(s)


def test_the_replayed_daemon_computes_what_it_did_in_lockstep(sim_cfg):
    """Replayed frames give the same set values, so the daemon-alone timing runs the real cycle."""
    rows = record_frames(sim_cfg, 1.0)
    assert len(rows) == 1000
    want = run_lockstep(sim_cfg, 1.0)
    got = run_lockstep(sim_cfg, 1.0, backend=ReplayBackend(sim_cfg, SimClock(), rows))
    assert want.summary["fault"] == got.summary["fault"] == "NONE"
    for name in ("current_cmd_1", "current_cmd_2", "ankle_dp", "sg_torque_ie"):
        assert np.array_equal(want[name], got[name]), name
    assert np.ptp(want["current_cmd_1"]) > 0.0
    assert daemon_cycle_s(sim_cfg, 0.1, repeats=1) > 0.0


def test_bench_loop_reports_the_daemon_alone_and_every_time_in_reference_steps(capsys):
    import json

    from ankle_rt.cli import main

    assert main(["bench", "loop", "--duration", "0.2", "--lockstep", "0.2", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    us = result["reference_step_us"]
    assert us > 0
    for name in ("lockstep_cycle", "daemon_cycle"):
        assert result[f"{name}_ref_steps"] == pytest.approx(result[f"{name}_us"] / us)
        assert name + "_ref_steps" in result["goals_met"]
    for q in ("p50", "p99", "p999", "max"):
        assert result[f"compute_{q}_ref_steps"] == pytest.approx(result[f"compute_{q}_us"] / us)
