"""The batched control cycle against the real daemon in lockstep, run by run."""

from __future__ import annotations

import numpy as np

from ankle_rt.daemon import run_lockstep
from ankle_rt.safety import Fault
from ankle_rt.sweep.cycle import BatchRun

SECONDS = 3.0


def _variants(base):
    """Different parameters, sensors, references, a friction feed-forward, an effect and a fault."""
    out = []
    c = base.deep_copy()
    out.append(c)
    c = base.deep_copy()
    c["transmission"]["cable_stiffness"] *= 0.7
    c["actuator"]["coulomb"] *= 1.3
    c["sim"]["seed"] = 3
    out.append(c)
    c = base.deep_copy()
    c["reference"]["profile"] = "hold"
    c["reference"]["hold"] = {"dp": 0.05, "ie": -0.03}
    c["controller"]["friction_ff"]["enabled"] = True
    out.append(c)
    c = base.deep_copy()
    c["controller"]["step_gains"]["kp"] = 2500.0      # unstable: the safety layer must stop it
    c["controller"]["step_gains"]["kd"] = 0.0
    out.append(c)
    return out


def _compare(cfgs):
    trace = BatchRun(cfgs, SECONDS).run()
    faults = []
    for j, cfg in enumerate(cfgs):
        run = run_lockstep(cfg, SECONDS)
        assert len(run) == trace.ankle.shape[0]
        for name, got in (("ankle_dp", trace.ankle[:, 0, j]), ("ankle_ie", trace.ankle[:, 1, j]),
                          ("ref_dp", trace.reference[:, 0, j]), ("ref_ie", trace.reference[:, 1, j]),
                          ("current_cmd_1", trace.current[:, 0, j]), ("current_cmd_2", trace.current[:, 1, j])):
            want = run[name]
            span = max(np.ptp(want), 1e-9)
            rms = np.sqrt(np.mean((got - want) ** 2))
            assert rms < 1e-3 * span, (j, name, rms, span)
        assert run.summary["fault"] == Fault(trace.fault[j]).name
        assert run.summary["saturated_cycles"] == trace.saturated[j]
        faults.append(trace.fault[j])
    return faults


def test_batched_pd_cycle_matches_the_daemon(sim_cfg):
    faults = _compare(_variants(sim_cfg))
    assert faults[:3] == [0, 0, 0] and faults[3] != 0


def test_batched_impedance_cycle_matches_the_daemon(sim_cfg):
    sim_cfg["controller"]["type"] = "impedance"
    cfgs = _variants(sim_cfg)[:3]
    cfgs[1]["controller"]["impedance"]["stiffness_dp"] *= 0.5
    cfgs[2]["sim"]["effects"] = []
    _compare(cfgs)


def test_batched_cycle_with_effects_matches_the_daemon(sim_cfg):
    cfgs = []
    for excess, delay, half_width in ((0.2, 0.0025, 1e-4), (0.4, 0.006, 3e-4)):
        c = sim_cfg.deep_copy()
        c["sim"]["effects"] = [{"type": "stribeck", "static_excess": excess, "stribeck_velocity": 0.05},
                               {"type": "delay", "delay": delay},
                               {"type": "backlash", "half_width": half_width}]
        cfgs.append(c)
    assert _compare(cfgs) == [0, 0]
