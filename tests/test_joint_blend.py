"""The impedance law's angle with joint encoders (ankle_rt.joint_blend): theirs below the crossover, the
estimate through the cables above, so the fast loop stays on the motors and holds still on a slack cable;
and the linear model's estimate dividing by the configured cable, as the daemon's does."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ankle_rt.analysis import ImpedanceLoop, torque_loop_margins
from ankle_rt.backend import open_backend
from ankle_rt.bench.impedance import TorqueProgramBackend, bench_config
from ankle_rt.clock import SimClock
from ankle_rt.config import ConfigError, load_config
from ankle_rt.control import build_controller
from ankle_rt.daemon import run_lockstep
from ankle_rt.estimation import Estimate
from ankle_rt.joint_blend import blended_angle, crossover_alpha, law_crossover_hz
from ankle_rt.kinematics import Kinematics
from ankle_rt.params import PlantParams, TransmissionParams
from ankle_rt.paths import default_config_path
from tests.loop_configs import gauge_loop_config

PLANT = [{"type": "load_dependent_friction", "coefficient": 0.12},
         {"type": "stribeck", "static_excess": 0.15, "stribeck_velocity": 0.1}]
BACKLASH = {"type": "backlash", "half_width": 0.0002}     # m of cable each way
# rad the joint encoders part from the motors' estimate by with that play (IE's shorter lever: 8.9 mrad each way),
# stated for the joint cross-check (safety.joint_mismatch_rad) as a device with play states it
BACKLASH_PLAY_RAD = 0.01
CROSSOVER = {"joint_crossover_hz": 2.0}
# N m s/rad [DP, IE]: at K 200 / 100 the crossover renders negative damping on a cable 30 % softer than
# configured (the estimate above it mis-scaled, the joint encoders below) unless damped by this much: the
# least the passivity check accepts (docs/daemon.md "Passivity"), against the bench's 0.5 / 0.25
CROSSOVER_DAMPING = {"damping_dp": 0.95, "damping_ie": 2.45}
SLACK = 0.05        # of the cable stiffness: a cable that has gone nearly slack


@pytest.fixture(scope="module")
def base():
    return gauge_loop_config()      # the loop the crossover's dampings were found on


def impedance_cfg(base, effects=PLANT, friction_ff="identified", **impedance):
    cfg = bench_config(base, stiffness=(200.0, 100.0), damping=(0.5, 0.25), torque_feedback="auto",
                       friction_ff=friction_ff, effects=effects)
    cfg["controller"]["impedance"].update(impedance)
    return with_play(cfg)


def with_play(cfg):
    """``cfg`` stating its plant's cable play, if it has BACKLASH, to the joint cross-check."""
    if BACKLASH in cfg["sim"]["effects"]:
        cfg["safety"]["joint_mismatch_rad"] = BACKLASH_PLAY_RAD
    return cfg


def slack_margin_db(cfg, **loop) -> float:
    """dB: the least margin of the configured loop with the cables at SLACK of their stiffness, foot free."""
    c = dataclasses.replace(ImpedanceLoop.from_config(cfg, closed=True), **loop)
    return min(m.gain_margin_db for m in torque_loop_margins(PlantParams.from_config(cfg), c,
                                                             stiffness_factors=(SLACK,), feet=("free",)))


def test_the_blend_is_the_joint_angle_at_rest_and_the_estimate_in_a_fast_move():
    alpha = crossover_alpha(2.0, 1e-3)
    angle, lead = 0.0, 0.0
    for _ in range(5000):                  # the estimate 3 mrad off the joint encoders (slack), at rest
        angle, lead = blended_angle(0.103, 0.100, lead, alpha)
    assert angle == pytest.approx(0.100, abs=1e-9)
    # a fast step of the estimate passes at once; the joint encoders' view catches up only slowly
    stepped, _ = blended_angle(0.203, 0.100, lead, alpha)
    assert stepped - angle == pytest.approx(0.1 * (1.0 - alpha))
    assert crossover_alpha(0.0, 1e-3) == 1.0 and blended_angle(0.5, 0.2, 0.0, 1.0)[0] == pytest.approx(0.2)
    assert law_crossover_hz(2.0, torque_loop=False) == 0.0 and law_crossover_hz(2.0, torque_loop=True) == 2.0


def test_the_law_starts_on_the_joint_encoders(base):
    """Activation starts the crossover's state where the law's angle is the joint encoders' (what the hold
    ramps from, Daemon.ankle_now): no torque step from the estimate's cable error."""
    cfg = impedance_cfg(base, **CROSSOVER, **CROSSOVER_DAMPING)
    ctl = build_controller(cfg, Kinematics.from_params(TransmissionParams(**cfg["transmission"])), np.zeros(2))
    est = Estimate()
    est.dp, est.ie, est.joint_dp, est.joint_ie, est.tared = 0.013, -0.004, 0.010, -0.002, True
    ctl.start(est)
    assert ctl.law_angles(est) == pytest.approx((0.010, -0.002))
    assert ctl.angles(est) == (0.010, -0.002)


def test_on_a_slack_cable_the_loop_on_joint_encoders_alone_is_unstable_and_the_blend_is_not(base):
    """Linear model, K 200 / 100, foot free, cables at 5 % of their stiffness (a dead zone's describing
    function sweeps through it): the law on the joint encoders alone closes its fast loop through the
    slack cable and is unstable (the shipped default, joint_crossover_hz 0); with a 2 Hz crossover it keeps
    the required margin."""
    cfg = impedance_cfg(base, **CROSSOVER)
    assert impedance_cfg(base)["controller"]["impedance"]["joint_crossover_hz"] == 0.0
    assert slack_margin_db(cfg, joint_crossover_hz=0.0) == -math.inf
    assert slack_margin_db(cfg) >= 6.0


def test_the_model_estimates_the_angle_with_the_configured_cable_as_the_daemon_does(base):
    """Without joint encoders the daemon divides the measured torque by the configured cable: on a slack
    one the estimate is then nearly the motors' angle, and the loop is stable. The model used to divide by
    the plant's own cable, which on a slack cable is the true ankle angle, non-collocated: unstable."""
    cfg = impedance_cfg(base, angle_source="estimated")
    assert slack_margin_db(cfg) >= 6.0
    assert slack_margin_db(cfg, estimate_cable=None) == -math.inf


def hunt_after_release(cfg, window: tuple[float, float] = (3.0, 4.0)) -> tuple[str, float, float]:
    """(fault, deg, A): the run's fault, the DP ankle's spread and motor 1's set-value spread over ``window``
    (s; default the last second) of a 4 s run in which a 3 N m DP push is held from 1 s to 2.2 s."""
    push = lambda t, x: (3.0 if 1.0 <= t < 2.2 else 0.0, 0.0)   # noqa: E731
    run = run_lockstep(cfg, 4.0, backend=TorqueProgramBackend(open_backend(cfg, SimClock()), push))
    last = (run["t"] >= window[0]) & (run["t"] < window[1])
    return (run.summary["fault"], float(np.degrees(np.std(run["ankle_dp"][last]))),
            float(np.std(run["current_cmd_1"][last])))


def test_after_a_push_a_slack_cable_settles_instead_of_hunting(base):
    """0.2 mm of cable backlash, K 200 / 100, the simulator bench's clamps: released after a push, the law
    on the joint encoders alone (the default) hunts in the dead zone until the oscillation detector faults (with the
    detector's limits raised: a 12-14 Hz cycle of about +-0.26 deg, 2.9 A RMS, docs/daemon.md); with the
    crossover (2 Hz, and the damping that keeps it passive) the ankle comes to rest, the current at its noise
    at rest (0.4 A). With the bench's damping the crossover is refused: not passive."""
    effects = PLANT + [BACKLASH]
    assert hunt_after_release(impedance_cfg(base, effects))[0] == "OSCILLATION"
    with pytest.raises(ConfigError, match="not passive on DP"):
        hunt_after_release(impedance_cfg(base, effects, **CROSSOVER))
    fault, deg, amps = hunt_after_release(impedance_cfg(base, effects, **CROSSOVER, **CROSSOVER_DAMPING))
    assert fault == "NONE" and deg < 0.02 and amps < 0.6, (fault, deg, amps)
