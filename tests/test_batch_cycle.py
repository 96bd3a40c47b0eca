"""The batched control cycle against the real daemon in lockstep, run by run: the same code on arrays
and on floats, so equal to rounding (1e-9 of each signal's span)."""

from __future__ import annotations


import numpy as np
import pytest

from ankle_rt.config import ConfigError
from ankle_rt.loop_setup import torque_feedback
from ankle_rt.controller_registry import BUILTIN_CONTROLLERS
from ankle_rt.daemon import run_lockstep
from ankle_rt.safety import Fault
from ankle_rt.sweep.cycle import BatchRun
from tests.daemon_helpers import classic_torque_loop
from tests.loop_configs import GAUGE_LOOP, WALK_LOOP

SECONDS = 3.0
# an identified friction model (as diagnose --write-model writes) in the plant and in the feed-forward
IDENTIFIED = [{"type": "stribeck", "static_excess": 0.15, "stribeck_velocity": 0.1},
              {"type": "asymmetric_friction", "coulomb_asymmetry": 0.03, "viscous_asymmetry": 0.01},
              {"type": "load_dependent_friction", "coefficient": 0.12}]


def _variants(base):
    """Different parameters, sensors, references, a friction feed-forward, an effect and a fault."""
    out = []
    c = base.deep_copy()
    out.append(c)
    c = base.deep_copy()
    _cables(c, 0.7)
    c["actuator"]["coulomb"] *= 1.3
    c["sim"]["seed"] = 3
    out.append(c)
    c = base.deep_copy()
    c["reference"]["profile"] = "hold"
    c["reference"]["hold"] = {"dp": 0.05, "ie": -0.03}
    c["controller"]["friction_ff"]["enabled"] = True
    out.append(c)
    c = base.deep_copy()
    c["safety"]["max_sg_step_nm"] = 0.05     # the gauges' noise trips SG_JUMP: the safety layer must stop it
    out.append(c)
    return out


def _cables(cfg, factor):
    """Cable stiffness x ``factor`` (the torque loop's notch follows it, ankle_rt.notch)."""
    cfg["transmission"]["cable_stiffness"] *= factor


def _compare(cfgs, tolerance=1e-9):
    """Fault codes per plant; every signal equal to ``tolerance`` of its span."""
    trace = BatchRun(cfgs, SECONDS).run(np.float64)
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
            assert rms <= tolerance * span, (j, name, rms, span)
        assert run.summary["fault"] == Fault(trace.fault[j]).name
        assert run.summary["saturated_cycles"] == trace.saturated[j]
        faults.append(trace.fault[j])
    return faults


def test_batched_pd_cycle_matches_the_daemon(sim_cfg):
    faults = _compare(_variants(sim_cfg))
    assert faults[:3] == [0, 0, 0] and faults[3] != 0


@pytest.mark.parametrize("feedback", ["auto", "off"])
def test_batched_impedance_cycle_matches_the_daemon(sim_cfg, feedback):
    """The joint-torque loop (auto: on in the simulator, its rate on the joint encoders: sim.yaml's loop) and
    open loop."""
    sim_cfg["controller"]["type"] = "impedance"
    sim_cfg["controller"]["impedance"]["torque_feedback"] = feedback
    if feedback == "off":   # one plant has the feed-forward on: the law's damping outweighs its viscous terms
        sim_cfg["controller"]["impedance"].update(damping_dp=5.0, damping_ie=2.0)
    assert torque_feedback(sim_cfg) == (feedback == "auto")
    cfgs = _variants(sim_cfg)[:3]
    cfgs[1]["controller"]["impedance"]["stiffness_dp"] *= 0.5
    cfgs[2]["sim"]["effects"] = []
    _compare(cfgs)


@pytest.mark.parametrize("feedback", ["on", "off"])
def test_batched_identified_friction_feed_forward_matches_the_daemon(sim_cfg, feedback):
    """Stribeck, asymmetric and load-dependent (on the measured cable torque) terms; loop gains that
    differ between plants; a plant with the feed-forward off in the same batch; one compensating a
    fraction of the model, faded with speed (config/friction-compensation.yaml). On the gauges' loop, whose gains
    the variants change within its margin."""
    sim_cfg["controller"]["torque_loop"].update(GAUGE_LOOP)
    sim_cfg["controller"]["type"] = "impedance"
    sim_cfg["controller"]["impedance"]["torque_feedback"] = feedback
    if feedback == "off":   # the law's damping outweighs the feed-forward's viscous terms (the margin counts them)
        sim_cfg["controller"]["impedance"].update(damping_dp=5.0, damping_ie=2.0)
    sim_cfg["sim"]["effects"] = [dict(e) for e in IDENTIFIED]
    sim_cfg["controller"]["friction_ff"].update(enabled=True, model="identified", model_file="")
    cfgs = [sim_cfg.deep_copy() for _ in range(3)]
    loop = cfgs[1]["controller"]["torque_loop"]
    loop.update(ki_ie=0.5 * loop["ki_ie"], torque_rate_dp=1.05 * loop["torque_rate_dp"], cutoff_hz_dp=350.0,
                max_correction_dp=0.7 * loop["max_correction_dp"], lag_hz_dp=3.0, lag_boost_dp=1.5, cutoff_hz_ie=120.0)
    cfgs[1]["sim"]["effects"][2]["coefficient"] = 0.2
    cfgs[1]["reference"]["profile"] = "hold"
    cfgs[1]["reference"]["hold"] = {"dp": 0.05, "ie": -0.03}
    cfgs[2]["controller"]["friction_ff"]["enabled"] = False
    cfgs[0]["controller"]["friction_ff"].update(fraction=0.7, fade_velocity=0.5, error_band=0.02)
    assert _compare(cfgs) == [0, 0, 0]


def test_batched_observer_and_angle_sources_match_the_daemon(sim_cfg):
    """The disturbance observer with its energy tank (a small tank that runs dry on one plant), and
    the law's angle from the joint encoders on some plants, through the cables on another."""
    sim_cfg["controller"]["type"] = "impedance"
    # on the classic loop: with the shipped notched DP loop the observer keeps 5.5 dB of margin (refused)
    sim_cfg["controller"]["torque_loop"].update(classic_torque_loop(), dob_hz=10.0, ki_dp=0.0, ki_ie=0.0)
    cfgs = [sim_cfg.deep_copy() for _ in range(3)]
    cfgs[1]["controller"]["impedance"]["angle_source"] = "estimated"
    cfgs[2]["controller"]["torque_loop"].update(dob_inertia_dp=0.9, tank_j=0.001, tank_friction_credit=0.2)
    # the observer differences the motor rate each cycle (J_n (w - w_prev) / dt): it magnifies the last-bit
    # differences between libm on floats and numpy on arrays (~1e-8 of span over 3 s), far below any physical effect
    assert _compare(cfgs, tolerance=1e-7) == [0, 0, 0]


def test_a_batch_it_cannot_run_as_the_daemon_does_is_refused_naming_the_key(sim_cfg, monkeypatch):
    sim_cfg["controller"]["type"] = "impedance"
    open_loop = sim_cfg.deep_copy()
    open_loop["controller"]["impedance"]["torque_feedback"] = "off"
    with pytest.raises(ConfigError, match="controller.impedance.torque_feedback"):
        BatchRun([sim_cfg, open_loop], 0.01)
    pd = sim_cfg.deep_copy()
    pd["controller"]["type"] = "pd"
    with pytest.raises(ConfigError, match="controller.type"):
        BatchRun([sim_cfg, pd], 0.01)
    monkeypatch.setitem(BUILTIN_CONTROLLERS, "plugin", "tests.test_controller_plugins:HugeCurrent")
    plugin = sim_cfg.deep_copy()
    plugin["controller"]["type"] = "plugin"
    with pytest.raises(ConfigError, match="controller.type.*'plugin'"):
        BatchRun([plugin], 0.01)


def test_batched_cycle_with_effects_matches_the_daemon(sim_cfg):
    cfgs = []
    for excess, delay, half_width in ((0.2, 0.0025, 1e-4), (0.4, 0.006, 3e-4)):
        c = sim_cfg.deep_copy()
        c["sim"]["effects"] = [{"type": "stribeck", "static_excess": excess, "stribeck_velocity": 0.05},
                               {"type": "delay", "delay": delay},
                               {"type": "backlash", "half_width": half_width}]
        cfgs.append(c)
    # the dead zones magnify the last-bit differences between libm on floats and numpy on arrays, and the joint
    # encoders' counts (12 urad) turn one now and then into a count's difference (~4e-6 of span)
    assert _compare(cfgs, tolerance=1e-5) == [0, 0]


@pytest.mark.parametrize("controller", ["pd", "impedance"])
def test_batched_walking_scenario_matches_the_daemon(sim_cfg, controller):
    """The sweeps' gait scenario: the walking reference with the foot loaded in every stance phase."""
    from ankle_rt.sweep.spec import SCENARIOS

    walking = SCENARIOS["gait"]
    sim_cfg["controller"]["torque_loop"].update(WALK_LOOP)     # the loop that walks (the shipped one: < 6 dB at x1.2)
    sim_cfg["controller"]["type"] = controller
    sim_cfg["reference"]["profile"] = "gait"
    sim_cfg["reference"]["gait"] = dict(walking["reference"]["gait"])
    sim_cfg["sim"]["disturbances"] = [dict(d) for d in walking["sim"]["disturbances"][:3]]
    other = sim_cfg.deep_copy()
    _cables(other, 1.2)
    other["sim"]["seed"] = 5
    assert _compare([sim_cfg, other]) == [0, 0]


def test_stacking_keeps_shared_flags_and_stacks_numbers_lists_and_parts():
    """The rules a batchable controller relies on (ankle_rt.elementwise.stack)."""
    from ankle_rt.elementwise import stack

    class Part:
        def __init__(self, k):
            self.k = k

        @classmethod
        def stack(cls, parts):
            return stack(parts)

    class Law:
        def __init__(self, gain, flag, closed, rows, name):
            self.gain, self.flag, self.closed, self.rows, self.name = gain, flag, closed, rows, name
            self.part = Part(2.0 * gain)

    out = stack([Law(1.0, True, True, [1.0, 2.0], "a"), Law(3.0, False, True, [5.0, 6.0], "a")], columns=("rows",))
    assert out.gain.tolist() == [1.0, 3.0]
    assert out.flag.tolist() == [True, False] and out.closed is True
    assert [r.tolist() for r in out.rows] == [[1.0, 5.0], [2.0, 6.0]]
    assert isinstance(out.part, Part) and out.part.k.tolist() == [2.0, 6.0]
    with pytest.raises(ValueError, match="Law.name differs"):
        stack([Law(1.0, True, True, [1.0], "a"), Law(1.0, True, True, [1.0], "b")])
    with pytest.raises(ValueError, match="Law.rows differs"):
        stack([Law(1.0, True, True, [1.0], "a"), Law(1.0, True, True, [2.0], "a")])


def test_the_batch_runs_the_gauge_cross_check_and_the_oscillation_detector(sim_cfg):
    """SG_MISMATCH (a motor torque the model does not know, 6 N m on motor 1, parts the gauge torque
    from the motors'; 1 N m stays inside the tolerance) and OSCILLATION (the detector set low enough
    for the step's ringing) fault in the batch as in the daemon: the same Safety code on arrays."""
    cfgs = [sim_cfg.deep_copy() for _ in range(2)]
    for cfg, torque in zip(cfgs, (1.0, 6.0)):
        cfg["sim"]["effects"] = [*cfg["sim"]["effects"], {"type": "torque_offset", "torque_1": torque}]
    assert _compare(cfgs) == [0, Fault.SG_MISMATCH]
    cfgs = [sim_cfg.deep_copy() for _ in range(2)]
    cfgs[0]["safety"]["oscillation_rms_a"] = 0.01
    cfgs[0]["safety"]["oscillation_hold_s"] = 0.35      # the shortest hold accepted
    assert _compare(cfgs) == [Fault.OSCILLATION, 0]
