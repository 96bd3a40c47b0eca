"""Walking (issue 20): the gait-phase controller's phase machine, bumpless blends, timeouts; the
walking scenario in the simulator and its batch; limits a walker does not trip."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ankle_rt.clock import SimClock
from ankle_rt.config import ConfigError, load_config
from ankle_rt.control.gait_phase import (EARLY_STANCE, EARLY_SWING, LATE_STANCE, LATE_SWING, PARAMS, PHASES, SAFE,
                                         GaitPhaseLaw, heel_strike_hold_s)
from ankle_rt.daemon import Daemon
from ankle_rt.safety import Fault
from tests.conftest import ROOT
from tests.daemon_helpers import reply, traced_memory

WALK = ROOT / "config" / "walk.yaml"
SIM = ROOT / "config" / "sim.yaml"
DT = 0.001
SENSOR_FAULTS = {Fault.SG_JUMP, Fault.SG_RAIL, Fault.SENSOR_INVALID, Fault.SENSOR_STALE, Fault.MOTOR_JUMP}


@pytest.fixture(scope="module")
def walk_cfg():
    return load_config(WALK)


def make_law(cfg) -> GaitPhaseLaw:
    g = cfg["controller"]["gait_phase"]
    return GaitPhaseLaw({p: g[p] for p in PHASES}, g, DT, heel_strike_hold_s(cfg))


def hold(law: GaitPhaseLaw, seconds: float, load: float, dp: float = 0.0, vdp: float = 0.0) -> list[tuple]:
    """Run the law with constant inputs; (phase, tau_dp) per cycle."""
    return [(law.phase, law.update(load, dp, vdp, 0.0, 0.0)[0]) for _ in range(round(seconds / DT))]


def to_early_stance(law: GaitPhaseLaw, g) -> None:
    hold(law, 0.1, g["load_off_nm"] - 1.0)          # unloaded while safe: armed
    hold(law, 0.1, g["load_on_nm"] + 1.0)
    assert law.phase == EARLY_STANCE


def test_phases_follow_the_load_and_the_angle_with_hysteresis(walk_cfg):
    g = walk_cfg["controller"]["gait_phase"]
    law = make_law(walk_cfg)
    between = 0.5 * (g["load_on_nm"] + g["load_off_nm"])
    hold(law, 0.5, g["load_on_nm"] + 1.0)            # loaded from the start: never armed, stays safe
    assert law.phase == SAFE
    to_early_stance(law, g)
    hold(law, 0.3, between)                           # inside the hysteresis band: no toe-off
    assert law.phase == EARLY_STANCE
    hold(law, 0.3, g["late_stance_load_nm"] + 5.0, dp=g["late_stance_angle"] - 0.02)   # load without the angle
    assert law.phase == EARLY_STANCE
    hold(law, 0.1, g["late_stance_load_nm"] - 5.0, dp=g["late_stance_angle"] + 0.02)   # angle without the load
    assert law.phase == EARLY_STANCE
    hold(law, 0.1, g["late_stance_load_nm"] + 5.0, dp=g["late_stance_angle"] + 0.02)
    assert law.phase == LATE_STANCE
    hold(law, 0.3, between, dp=g["late_stance_angle"] - 0.2)   # angle falls back, load in the band: stays
    assert law.phase == LATE_STANCE
    hold(law, 0.1, g["load_off_nm"] - 1.0, dp=-0.3)
    assert law.phase == EARLY_SWING
    hold(law, 0.3, between, dp=-0.3)                  # in the band: not a heel strike
    assert law.phase == EARLY_SWING
    hold(law, 0.1, 0.0, dp=g["late_swing_angle"] + 0.02, vdp=g["late_swing_velocity"] + 1.0)   # still moving fast
    assert law.phase == EARLY_SWING
    hold(law, 0.1, 0.0, dp=g["late_swing_angle"] + 0.02, vdp=0.0)
    assert law.phase == LATE_SWING
    hold(law, 0.1, g["load_on_nm"] + 1.0)
    assert law.phase == EARLY_STANCE


def test_no_transition_before_the_minimum_dwell(walk_cfg):
    g = walk_cfg["controller"]["gait_phase"]
    law = make_law(walk_cfg)
    hold(law, 0.1, g["load_off_nm"] - 1.0)
    while law.phase != EARLY_STANCE:                  # heel strike, to the cycle
        law.update(g["load_on_nm"] + 1.0, 0.0, 0.0, 0.0, 0.0)
    phases = [p for p, _ in hold(law, 0.2, g["load_off_nm"] - 1.0)]   # toe-off at once
    assert phases.index(EARLY_SWING) == round(g["min_dwell_s"] / DT)


def test_a_stuck_load_times_out_to_the_safe_phase_and_stays_there(walk_cfg):
    g = walk_cfg["controller"]["gait_phase"]
    law = make_law(walk_cfg)
    to_early_stance(law, g)
    stuck = g["late_stance_load_nm"] + 10.0           # the load signal freezes high mid-stance
    hold(law, g["late_stance_angle"] and 0.1, stuck, dp=g["late_stance_angle"] + 0.05)
    assert law.phase == LATE_STANCE
    trace = hold(law, g["timeout_s"] + 0.1, stuck, dp=g["late_stance_angle"] + 0.05)
    assert law.phase == SAFE
    hold(law, 5.0, stuck)                              # never unloaded: not armed, no new stance
    assert law.phase == SAFE
    law = make_law(walk_cfg)                          # stuck low (a dead gauge) after a toe-off
    to_early_stance(law, g)
    hold(law, 0.1, 0.0, dp=-0.3)
    assert law.phase == EARLY_SWING
    hold(law, g["timeout_s"] + 0.1, 0.0, dp=-0.3, vdp=2.0)
    assert law.phase == SAFE
    hold(law, 5.0, 0.0)
    assert law.phase == SAFE
    assert all(math.isfinite(t) for _, t in trace)


def test_no_torque_jump_on_a_transition(walk_cfg):
    """At a fixed ankle angle the late-stance equilibrium shift would step the torque by K x 0.5 rad;
    the blend spreads it: no cycle moves the torque by more than its share."""
    g = walk_cfg["controller"]["gait_phase"]
    law = make_law(walk_cfg)
    to_early_stance(law, g)
    dp = g["late_stance_angle"] + 0.02
    hold(law, 0.2, g["late_stance_load_nm"] - 5.0, dp=dp)     # settled in early stance at that angle
    assert law.phase == EARLY_STANCE
    taus = [t for _, t in hold(law, 0.3, g["late_stance_load_nm"] + 5.0, dp=dp)]
    assert law.phase == LATE_STANCE
    es, ls = g["early_stance"], g["late_stance"]
    step = abs(ls["stiffness_dp"] * (ls["equilibrium_dp"] - dp) - es["stiffness_dp"] * (es["equilibrium_dp"] - dp))
    assert step > 40.0                                 # an instant switch would jump this much
    alpha = 1.0 - math.exp(-DT / g["blend_s"])
    assert max(abs(b - a) for a, b in zip(taus, taus[1:])) <= 1.5 * alpha * step
    assert abs(taus[-1] - ls["stiffness_dp"] * (ls["equilibrium_dp"] - dp)) < 0.01 * step   # and it gets there


def test_no_torque_jump_on_a_live_parameter_change_and_limits_hold(walk_cfg):
    from ankle_rt.control import build_controller
    from ankle_rt.control.gains import GainError
    from ankle_rt.estimation import Estimate
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import TransmissionParams

    ctl = build_controller(walk_cfg, Kinematics.from_params(TransmissionParams(**walk_cfg["transmission"])),
                           np.zeros(2))
    est, out = Estimate(), np.zeros(2)
    est.dp = 0.1
    ctl.reset(est)
    torques = []
    for k in range(600):
        if k == 300:
            ctl.set_gains(phase="safe", equilibrium_dp=-0.4, stiffness_dp=300.0)
        ctl.update(est, out)
        torques.append(out[0])
    jumps = np.abs(np.diff(torques))
    assert jumps[300:].max() < 0.1 * abs(torques[-1] - torques[299])
    assert abs(torques[-1] - torques[299]) > 5.0
    with pytest.raises(GainError, match="gain_limits"):
        ctl.set_gains(phase="late_swing", stiffness_dp=1e4)
    with pytest.raises(GainError, match="ankle range"):
        ctl.set_gains(phase="late_swing", equilibrium_dp=1.0)
    with pytest.raises(GainError, match="phase"):
        ctl.set_gains(stiffness_dp=10.0)
    with pytest.raises(GainError, match="joint-torque loop"):
        ctl.set_gains(phase="early_swing", stiffness_ie=300.0)        # above 0.5 x the IE cable stiffness
    assert ctl.gait.phase_params()["late_swing"]["stiffness_dp"] == walk_cfg["controller"]["gait_phase"]["late_swing"]["stiffness_dp"]


def test_the_stacked_law_runs_the_same_numbers_as_each_law(walk_cfg):
    g = walk_cfg["controller"]["gait_phase"]
    laws = [make_law(walk_cfg) for _ in range(3)]
    laws[1].set_phase_params(EARLY_STANCE, stiffness_dp=250.0)
    batch = GaitPhaseLaw.stack([make_law(walk_cfg) for _ in range(3)])
    batch.stiffness_dp[EARLY_STANCE, 1] = 250.0
    rng = np.random.default_rng(1)
    for k in range(3000):
        load = np.array([0.0, 20.0, 90.0]) * (1.0 + math.sin(k * 0.004)) + rng.normal(0.0, 2.0, 3)
        dp = 0.15 * np.sin(k * 0.006 + np.arange(3))
        v = np.cos(k * 0.006 + np.arange(3))
        got = batch.update(load, dp, v, 0.5 * dp, v)
        for i, law in enumerate(laws):
            want = law.update(float(load[i]), float(dp[i]), float(v[i]), float(0.5 * dp[i]), float(v[i]))
            assert law.phase == batch.phase[i]
            assert want[0] == pytest.approx(got[0][i], abs=1e-9) and want[1] == pytest.approx(got[1][i], abs=1e-9)
    assert len({int(p) for p in batch.phase}) >= 1 and g["blend_s"] > 0


@pytest.mark.parametrize("phase", ["early_swing", "late_swing", "safe"])
def test_the_foot_free_in_swing_never_trips_motor_jump(walk_cfg, phase):
    """The swing impedances (and the safe one) hold a free foot released from push-off (-20 deg)
    without a fault: the controller is held in that phase's parameters from activation."""
    g = walk_cfg["controller"]["gait_phase"]
    cfg = load_config(WALK, {"sim": {"scenario": "none"}, "controller": {"gait_phase": {"safe": dict(g[phase])}}})
    daemon = Daemon(cfg, SimClock())
    daemon.backend.plant.model.set_rest_at((-0.35, 0.05))
    try:
        daemon.run(3.0)
    finally:
        daemon.close()
    assert Fault(daemon.safety.fault) == Fault.NONE
    assert abs(daemon.backend.plant.model.x[0] - g[phase]["equilibrium_dp"]) < math.radians(3.0)


def held_torque(cfg, torque: float, rise_s: float = 0.05, hold_s: float = 0.4) -> tuple[Daemon, float]:
    """A DP torque on the foot rising over ``rise_s`` (as a body loads a foot), held ``hold_s``."""
    daemon = Daemon(cfg, SimClock())
    plant = daemon.backend.plant
    peak = [0.0]

    def cycle(t_ns: int) -> None:
        t = plant.t
        up = min(max((t - 1.0) / rise_s, 0.0), 1.0) * min(max((1.0 + rise_s + hold_s - t) / rise_s, 0.0), 1.0)
        plant.extra_disturbance[0] = torque * up
        daemon.cycle(t_ns)
        peak[0] = max(peak[0], abs(daemon.est.sg_torque[0]))

    try:
        daemon.loop.run(cycle, round(2.0e9))
    finally:
        daemon.close()
    return daemon, peak[0]


@pytest.mark.parametrize("torque", [75.0, -75.0])
def test_a_75_nm_dp_torque_held_does_not_trip_a_sensor_fault(torque):
    """config/sim.yaml with the impedance controller: at the stiffest impedance the gain limits allow
    the ankle holds 75 N m without any fault; at the shipped (soft) stiffness the ankle runs into its
    range (ANKLE_RANGE, as it should), never into a strain-gauge fault. With issue 19's torque loop
    (less friction left to brake it) the shoved foot's motors really reach safety.max_motor_speed_rad_s
    (30 rad/s, at 38.7 of the 40 deg range) a cycle or two before the range check: MOTOR_JUMP then
    names a true overspeed, not a glitch."""
    stiff = load_config(SIM, {"controller": {"type": "impedance", "impedance": {"stiffness_dp": 200.0}},
                              "reference": {"profile": "hold"}})
    daemon, peak = held_torque(stiff, torque)
    assert Fault(daemon.safety.fault) == Fault.NONE and peak > 70.0
    soft = load_config(SIM, {"controller": {"type": "impedance"}, "reference": {"profile": "hold"}})
    daemon, _ = held_torque(soft, torque)
    assert Fault(daemon.safety.fault) in (Fault.ANKLE_RANGE, Fault.MOTOR_JUMP)


def test_the_rail_still_catches_a_gauge_at_full_scale_and_fits_the_wearer(tmp_path):
    import yaml

    def cfg(**safety):
        path = tmp_path / "c.yaml"
        path.write_text(yaml.safe_dump({"include": [str(SIM)], "safety": safety}))
        return load_config(path)

    assert cfg()["safety"]["sg_rail_nm"] < cfg()["sensors"]["strain_gauge_range_nm"]
    with pytest.raises(ConfigError) as err:
        cfg(sg_rail_nm=60.0)                          # the old rail: below a 100 kg wearer's push-off
    assert err.value.key == "safety.sg_rail_nm" and "wearer" in err.value.message
    with pytest.raises(ConfigError) as err:
        cfg(sg_rail_nm=260.0)                         # above the gauges' full scale
    assert err.value.key == "safety.sg_rail_nm" and "full scale" in err.value.message
    with pytest.raises(ConfigError) as err:
        load_config(WALK, {"safety": {"max_sg_step_nm": 1.0}})
    assert err.value.key == "safety.max_sg_step_nm"
    with pytest.raises(ConfigError) as err:      # 250 Hz: four times walking's change per sample
        load_config(WALK, {"controller": {"rate_hz": 250}})
    assert err.value.key == "safety.max_sg_step_nm"


def test_load_hysteresis_must_be_positive(tmp_path):
    with pytest.raises(ConfigError) as err:
        load_config(WALK, {"controller": {"gait_phase": {"load_off_nm": 20.0, "load_on_nm": 15.0}}})
    assert err.value.key == "controller.gait_phase.load_off_nm"


@pytest.mark.parametrize("load_off", [-50.0, -1.0, 0.0, 0.09])
def test_toe_off_must_lie_above_what_an_unloaded_foot_reads(load_off):
    """A toe-off threshold at or below what a foot off the ground reads held still (its gravity moment,
    0.465 kg x g x 6.9 mm = 0.031 N m, + 3 x 0.02 N m of gauge noise = 0.092 N m) never fires: on the
    walking scenario load_off_nm -50 kept the first stride in late stance through its swing (foot
    driven to -39.6 deg DP against -14.7 shipped) until the 1.5 s timeout, and then the safe phase for
    good (it re-arms only below load_off_nm), without a fault. Refused naming the key."""
    with pytest.raises(ConfigError) as err:
        load_config(WALK, {"controller": {"gait_phase": {"load_off_nm": load_off}}})
    assert err.value.key == "controller.gait_phase.load_off_nm"
    assert load_off <= 0 or "foot off the ground" in err.value.message   # <= 0: the schema's own bound
    assert load_config(WALK, {"controller": {"gait_phase": {"load_off_nm": 0.1}}})


def test_the_free_foots_cable_mode_never_takes_a_heel_strike_in_swing(tmp_path):
    """Safety8: in swing the free foot rings on the cables at ~98 Hz (+-5 N m after toe-off, decaying
    over the swing). With ``load_on_nm: 1, load_off_nm: 0.5`` (accepted: both above what a foot held
    still reads) each positive half-wave was a heel strike: early stance's 400 N m/rad in mid-swing
    every stride (75 kg normal: at 63 % of the stride, 54 ms after toe-off). The heel strike must now
    hold for one period of that mode, so the ring (which averages out over it) never takes it."""
    from ankle_rt.bench.walk import run_walk

    low = tmp_path / "low.yaml"
    low.write_text(f"include: [{WALK}]\ncontroller: {{gait_phase: {{load_on_nm: 1.0, load_off_nm: 0.5}}}}\n")
    for mass, cadence in ((75.0, "normal"), (100.0, "fast")):
        run = run_walk(str(low), mass, cadence, 3)
        assert run.fault == "NONE"
        c = run.columns
        for s in (1, 2):
            ph = c["phase"][c["stride"] == s].astype(int)
            order = [int(p) for i, p in enumerate(ph) if i == 0 or p != ph[i - 1]]
            assert order == [LATE_SWING, EARLY_STANCE, LATE_STANCE, EARLY_SWING, LATE_SWING]


def test_a_heel_strike_holds_one_period_of_the_feet_cable_mode(walk_cfg):
    """A +-5 N m ring at the mode's frequency (above load_on_nm every half period) never strikes; a
    load held above load_on_nm strikes after heel_strike_hold_s (a period at 0.7 x the cable stiffness)."""
    g = walk_cfg["controller"]["gait_phase"]
    hold_s = heel_strike_hold_s(walk_cfg)
    assert 0.010 < hold_s < 0.013
    law = make_law(walk_cfg)
    to_early_stance(law, g)
    hold(law, 0.1, 0.0, dp=-0.3)
    assert law.phase == EARLY_SWING
    period = hold_s * math.sqrt(0.7)
    for k in range(round(0.5 / DT)):
        law.update(g["load_on_nm"] + 5.0 * math.sin(2.0 * math.pi * k * DT / period), -0.3, 2.0, 0.0, 0.0)
        assert law.phase == EARLY_SWING
    hold(law, 0.01, 0.0, dp=-0.3, vdp=2.0)
    strike = [p for p, _ in hold(law, 0.05, g["load_on_nm"] + 1.0, dp=-0.3, vdp=2.0)]
    assert strike.index(EARLY_STANCE) == math.ceil(hold_s / DT)       # phases are listed before each update


def test_a_wearer_who_stops_in_late_stance_gets_the_safe_phase_within_two_seconds():
    """Safety8: the walking scenario's body frozen 50 ms into the second stride's late stance (the wearer
    stops, on the push-off): late stance's equilibrium (-0.55 rad) pushes 107 N m of plantarflexor
    moment into the wearer at 7.5 A (above the 5 A continuous current), held until the phase times out.
    timeout_s up to 60 s was accepted (60 s of it: the I2t at 1280 of its 4000 A^2 s after 40 s, no
    fault). Now at most 2 s (no walking phase lasts a stride; the longest on bench walk: 0.96 s, late
    swing at 100 kg slow), refused beyond naming the key; with 2 s the safe phase (neutral) takes over
    2 s after the stop."""
    for timeout in (2.5, 60.0):
        with pytest.raises(ConfigError) as err:
            load_config(WALK, {"controller": {"gait_phase": {"timeout_s": timeout}}})
        assert err.value.key == "controller.gait_phase.timeout_s"
    cfg = load_config(WALK, {"controller": {"gait_phase": {"timeout_s": 2.0}}})
    daemon = Daemon(cfg, SimClock())
    plant, ctl = daemon.backend.plant, daemon.controller
    walk = plant.walking
    stopped: list[float] = []
    trace: list[tuple[float, int, float]] = []

    def cycle(t_ns: int) -> None:
        daemon.cycle(t_ns)
        if not stopped and walk.stride == 2 and ctl.phase == LATE_STANCE and ctl.gait.time > 0.05:
            stopped.append(plant.t)
        trace.append((plant.t, ctl.phase, -daemon.est.sg_dp))

    advance = walk.advance
    walk.advance = lambda t: None if stopped else advance(t)     # the body holds still from the stop on
    try:
        daemon.loop.run(cycle, round(7.0e9))
    finally:
        daemon.close()
    assert daemon.safety.fault == Fault.NONE and stopped
    t, phase, load = (np.array(c) for c in zip(*trace))
    held = (t > stopped[0] + 0.1) & (phase == LATE_STANCE)
    assert load[held].min() > 90.0                                  # the push-off equilibrium, held
    safe = np.flatnonzero(phase == SAFE)
    safe = safe[t[safe] > stopped[0]]
    assert stopped[0] + 1.9 < t[safe[0]] < stopped[0] + 2.0
    assert load[t > t[safe[0]] + 1.0].max() < 60.0


def test_walking_strides_run_through_the_phases_without_a_fault():
    from ankle_rt.bench.walk import run_walk

    run = run_walk(str(WALK), 75.0, "normal", 3)
    assert run.fault == "NONE" and len(run.strides) == 3
    c = run.columns
    for s in (1, 2):
        ph = c["phase"][c["stride"] == s].astype(int)
        order = [int(p) for i, p in enumerate(ph) if i == 0 or p != ph[i - 1]]
        assert order == [LATE_SWING, EARLY_STANCE, LATE_STANCE, EARLY_SWING, LATE_SWING]
    assert all(s["push_off_work_j_per_kg"] > 0.0 for s in run.strides)
    assert max(s["current_peak_a"] for s in run.strides) <= 15.0


def test_a_push_off_the_motors_cannot_give_is_refused(tmp_path, monkeypatch):
    """adv11 (lockstep, config/walk.yaml): late stance's stiffness_dp was accepted up to
    controller.gain_limits (430 N m/rad); at its shipped equilibrium (-0.55 rad) the push-off asks the
    spring's K x (12 deg + 0.55 rad) of the motors: 300 N m/rad held the 15 A clamp in 60 cycles (32 in
    a row) of 4 strides at 75 kg and tripped SG_RAIL in the first stride at 100 kg, fast cadence; 428:
    SG_RAIL at 75 kg. That torque, at the walk's most dorsiflexed angle (at least late_stance_angle), must now fit in
    what both motors give at the peak current less max_correction_dp (194 N m): refused naming the key
    at load and by set_gains (ctl gains --phase) at run time; 255 N m/rad walks below the clamp."""
    import yaml

    import ankle_rt.control.gait_phase as gp
    from ankle_rt.bench.walk import run_walk
    from ankle_rt.control import build_controller
    from ankle_rt.control.gains import GainError
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import TransmissionParams

    def late_stance(k: float) -> str:
        path = tmp_path / f"late-{k:g}.yaml"
        path.write_text(yaml.safe_dump({"include": [str(WALK)],
                                        "controller": {"gait_phase": {"late_stance": {"stiffness_dp": k}}}}))
        return str(path)

    def build(path):
        cfg = load_config(path)
        return build_controller(cfg, Kinematics.from_params(TransmissionParams(**cfg["transmission"])), np.zeros(2))

    def saturated(run) -> int:
        return int(np.sum(np.maximum(np.abs(run.columns["i1"]), np.abs(run.columns["i2"])) >= 14.9))

    with pytest.raises(ConfigError) as err:
        build(late_stance(300.0))
    assert err.value.key == "controller.gait_phase.late_stance.stiffness_dp"
    assert "current_limit_peak" in err.value.message
    ctl = build(WALK)
    for gains in ({"stiffness_dp": 300.0}, {"stiffness_dp": 250.0, "equilibrium_dp": -0.69}):
        with pytest.raises(GainError) as gerr:
            ctl.check_gains(phase="late_stance", **gains)
        assert gerr.value.gain == "late_stance.stiffness_dp"
    ctl.check_gains(phase="late_stance", stiffness_dp=250.0)
    assert saturated(run_walk(late_stance(255.0), 75.0, "normal", 3)) == 0
    no_limits = dict.fromkeys(gp.STANCE_PHASES, (math.inf, ""))
    monkeypatch.setattr(gp, "stance_torque_limits", lambda cfg: no_limits)      # as before the check
    assert saturated(run_walk(late_stance(300.0), 75.0, "normal", 3)) > 20


def test_a_stance_spring_the_gauge_rail_would_read_is_refused(tmp_path, monkeypatch):
    """adv11 (lockstep): the rail is sized from the wearer (2 N m/kg x wearer.mass_kg), the stance
    springs were not: a config for a 30 kg wearer (rail 60 N m, jump 4.5 N m, as the checks allow) with
    the shipped 75 kg tuning rendered 66 N m in early stance and tripped SG_RAIL in the first stride at
    fast cadence (50 kg, rail 100 N m: 101 N m, SG_RAIL in the fourth stride). Each stance phase's
    spring at the walk's most dorsiflexed angle must now stay below safety.sg_rail_nm, refused naming
    the phase's stiffness_dp; the tuning scaled to the wearer (`bench walk`'s rule) walks."""
    import yaml

    import ankle_rt.bench.walk as bw
    import ankle_rt.control.gait_phase as gp
    from ankle_rt.control import build_controller
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import TransmissionParams

    path = tmp_path / "light.yaml"
    path.write_text(yaml.safe_dump({"include": [str(WALK)], "wearer": {"mass_kg": 30.0},
                                    "safety": {"sg_rail_nm": 60.0, "max_sg_step_nm": 4.5}}))
    cfg = load_config(path)
    with pytest.raises(ConfigError) as err:
        build_controller(cfg, Kinematics.from_params(TransmissionParams(**cfg["transmission"])), np.zeros(2))
    assert err.value.key == "controller.gait_phase.early_stance.stiffness_dp" and "sg_rail_nm" in err.value.message
    assert bw.run_walk(str(path), 30.0, "fast", 2).fault == "NONE"           # scaled by 30 / 75 kg: accepted
    no_limits = dict.fromkeys(gp.STANCE_PHASES, (math.inf, ""))
    monkeypatch.setattr(gp, "stance_torque_limits", lambda cfg: no_limits)   # as before the check,
    monkeypatch.setattr(bw, "REFERENCE_MASS_KG", 30.0)                       # with the config's own gains
    assert bw.run_walk(str(path), 30.0, "fast", 2).fault == "SG_RAIL"


def test_a_stance_spring_too_soft_for_the_heaviest_wearer_is_refused(monkeypatch):
    """adv11 (lockstep, config/walk.yaml, wearer.mass_kg 100): a stance stiffness was accepted down to
    what the loop renders stably (early stance 14 N m/rad with no damping): the 100 kg wearer
    dorsiflexed the ankle to 25 deg, the load fell below load_off_nm in mid-stance, early swing took
    over under the wearer and the gauges read the body driving the reflected inertia, SG_RAIL in the
    first stride at fast cadence (early stance 60 with damping 10, late stance 0: the same). Each stance
    spring must now hold the heaviest wearer's peak walking moment (1.6 N m/kg x wearer.mass_kg) before
    the ankle reaches its range, refused naming its stiffness_dp at load and at run time."""
    import ankle_rt.bench.walk as bw
    import ankle_rt.control.gait_phase as gp
    from ankle_rt.control import build_controller
    from ankle_rt.control.gains import GainError
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import TransmissionParams

    cfg = load_config(WALK, {"controller": {"gait_phase": {"early_stance": {"stiffness_dp": 14.0, "damping_dp": 0.0}}}})
    kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
    with pytest.raises(ConfigError) as err:
        build_controller(cfg, kin, np.zeros(2))
    assert err.value.key == "controller.gait_phase.early_stance.stiffness_dp" and "wearer.mass_kg" in err.value.message
    ctl = build_controller(load_config(WALK), kin, np.zeros(2))
    for phase, k in (("early_stance", 220.0), ("late_stance", 125.0)):   # 158 and 156 N m held, 160 needed
        with pytest.raises(GainError) as gerr:
            ctl.check_gains(phase=phase, stiffness_dp=k)
        assert gerr.value.gain == f"{phase}.stiffness_dp"
    ctl.check_gains(phase="early_stance", stiffness_dp=225.0)
    monkeypatch.setattr(gp, "WALKING_PEAK_MOMENT", 0.0)                      # as before the check
    monkeypatch.setattr(bw, "wearer_overrides", lambda c, m, cad, seed: {
        "sim": {"scenario": "walking", "walking": {"mass_kg": m, "cadence": cad, "seed": seed}},
        "controller": {"gait_phase": {"early_stance": {"stiffness_dp": 14.0, "damping_dp": 0.0}}}})
    assert bw.run_walk(str(WALK), 100.0, "fast", 2).fault == "SG_RAIL"


def test_a_live_change_to_the_stance_phase_in_force_waits_for_its_next_beginning():
    """adv11 (lockstep, config/walk.yaml, 75 kg at normal cadence): `ctl gains --phase late_stance`
    toggled every 0.3 s between two accepted sets, 250 N m/rad with no damping at equilibrium -0.55 and
    0.05 rad, reached the ankle mid-push-off: the push-off's spring set mid-stance held the 15 A clamp
    and flung the foot through toe-off to ANKLE_RANGE at 4.08 s. A change to the stance phase in force
    now applies from that phase's next beginning (the parameters the checks hold it to as it begins);
    a change checked meanwhile is checked merged with the one waiting."""
    from ankle_rt.control import build_controller
    from ankle_rt.control.gains import GainError
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import TransmissionParams
    from ankle_rt.service import protocol as proto
    from tests.daemon_helpers import lockstep_daemon, run_cycles

    cfg = load_config(WALK)
    ctl = build_controller(cfg, Kinematics.from_params(TransmissionParams(**cfg["transmission"])), np.zeros(2))
    ctl.gait.phase = LATE_STANCE
    ctl.apply_gains(phase="late_stance", equilibrium_dp=0.05)
    assert ctl.deferred == (LATE_STANCE, {"equilibrium_dp": 0.05}) and ctl.gait.equilibrium_dp[LATE_STANCE] == -0.55
    ctl.check_gains(phase="early_stance", stiffness_dp=300.0)
    with pytest.raises(GainError):        # with 0.05 rad waiting, 150 N m/rad holds 97 N m (-0.55: 187)
        ctl.check_gains(phase="late_stance", stiffness_dp=150.0)

    daemon = lockstep_daemon(cfg)
    sets = ({"equilibrium_dp": -0.55}, {"equilibrium_dp": 0.05})
    waited = []
    try:
        run_cycles(daemon, 2000)
        reply(daemon.handle(proto.SetGains(phase="late_stance", stiffness_dp=250.0, damping_dp=0.0)))
        for k in range(9):
            answer = reply(daemon.handle(proto.SetGains(phase="late_stance", **sets[k % 2])))
            ctl = daemon.controller
            waited.append(ctl.deferred is not None)
            assert answer.get("waiting") == ("late_stance" if ctl.deferred is not None else None)
            if ctl.deferred is not None:
                assert daemon.status()["gait_phase"]["waiting"] == {"late_stance": ctl.deferred[1]}
                assert ctl.gait.phase == LATE_STANCE
            run_cycles(daemon, 300)
        assert daemon.safety.fault == Fault.NONE and any(waited)
    finally:
        daemon.close()


def test_the_batch_plant_walks_as_each_plant_alone():
    from sim_backend.batch import BatchPlant
    from sim_backend.plant import SimulatedPlant

    cfgs = [load_config(WALK, {"sim": {"walking": {"mass_kg": m, "cadence": c, "seed": k, "start_s": 0.1}}})
            for k, (m, c) in enumerate([(50.0, "slow"), (100.0, "fast"), (75.0, "normal")])]
    batch = BatchPlant(cfgs)
    singles = [SimulatedPlant(c) for c in cfgs]
    for k in range(2500):
        i = 0.5 * math.sin(k * 0.01)
        batch.step(np.full(3, i), np.full(3, -i))
        for p in singles:
            p.step(i, -i)
    for j, p in enumerate(singles):
        np.testing.assert_allclose(batch.model.x[:, j], p.model.x, rtol=1e-9, atol=1e-12)
        assert batch.walking.stride[j] == p.walking.stride
    assert {int(s) for s in batch.walking.stride} != {0}     # strides went by


def test_the_phase_reaches_the_log_status_and_ctl_gains(tmp_path):
    """The gait phase in the log record (CSV columns follow FIELDS), the status reply, ctl watch,
    and per-phase tuning through the service protocol (checked, then blended)."""
    from ankle_rt.commands.ctl import watch_view
    from ankle_rt.log.export import csv_columns
    from ankle_rt.log.reader import read_log
    from ankle_rt.log.summary import plot_run
    from ankle_rt.service import protocol as proto

    assert proto.GAIT_PHASES == PHASES
    cfg = load_config(WALK, {"sim": {"walking": {"start_s": 0.5}}})
    from ankle_rt.daemon import run_lockstep

    res = run_lockstep(cfg, 2.5, log_path=tmp_path / "w.arlog")
    codes = set(np.unique(res["gait_phase"]).tolist())
    assert {1 + EARLY_STANCE, 1 + LATE_STANCE, 1 + EARLY_SWING, 1 + LATE_SWING} <= codes
    log = read_log(tmp_path / "w.arlog")
    assert np.array_equal(csv_columns(log.records)["gait_phase [code]"], res["gait_phase"])
    assert "plot" in plot_run(log.records, 1.66, str(tmp_path / "run.png"))
    daemon = Daemon(cfg, SimClock())
    try:
        daemon.run(0.2)
        status = daemon.status()
        assert status["gait_phase"]["phase"] == "safe"
        assert any("gait phase: safe" in line for line in watch_view(status, tmp_path))
        limits = proto.CommandLimits.from_config(cfg)
        cmd = proto.parse_command(b'{"cmd": "set_gains", "phase": "late_swing", "stiffness_dp": 80, '
                                  b'"equilibrium_dp": 0.05}', limits)
        reply(daemon.handle(cmd))        # checked off the loop thread (the gain margin), then applied
        assert daemon.status()["gait_phase"]["params"]["late_swing"]["equilibrium_dp"] == 0.05
        for line, field in [(b'{"cmd": "set_gains", "phase": "stance", "kp": 1}', "phase"),
                            (b'{"cmd": "set_gains", "equilibrium_dp": 0.1}', "phase"),
                            (b'{"cmd": "set_gains", "phase": "safe", "equilibrium_dp": 2.0}', "equilibrium_dp")]:
            with pytest.raises(proto.CommandError) as err:
                proto.parse_command(line, limits)
            assert err.value.field == field
        with pytest.raises(proto.CommandError) as err:     # kp is no gait-phase parameter
            reply(daemon.handle(proto.parse_command(b'{"cmd": "set_gains", "phase": "safe", "kp": 1}', limits)))
        assert err.value.field == "kp"
    finally:
        daemon.close()


def test_the_batched_sweep_cycle_and_the_daemon_agree_on_a_walking_run():
    """Three wearers walking under the gait-phase controller: the batched daemon cycle (its stacked
    law and walking scenario) and run_lockstep give the same ankle angles and currents (1e-9 of each
    signal's span: the batch runs the controller's own element-wise law)."""
    from ankle_rt.daemon import run_lockstep
    from ankle_rt.sweep.cycle import BatchRun

    seconds = 3.0
    cfgs = [load_config(WALK, {"sim": {"walking": {"mass_kg": m, "cadence": c, "seed": k, "start_s": 0.5}}})
            for k, (m, c) in enumerate([(60.0, "slow"), (75.0, "normal"), (90.0, "fast")])]
    trace = BatchRun(cfgs, seconds).run(np.float64)
    for j, cfg in enumerate(cfgs):
        run = run_lockstep(cfg, seconds)
        assert Fault(trace.fault[j]) == Fault.NONE and run.summary["fault"] == "NONE"
        for name, got in (("ankle_dp", trace.ankle[:, 0, j]), ("ankle_ie", trace.ankle[:, 1, j]),
                          ("current_cmd_1", trace.current[:, 0, j]), ("current_cmd_2", trace.current[:, 1, j])):
            want = run[name]
            rms = np.sqrt(np.mean((got - want) ** 2))
            assert rms <= 1e-9 * np.ptp(want), (j, name, rms)
        assert np.ptp(run["gait_phase"]) >= 3          # it walked through the phases


def test_the_gait_phase_update_keeps_no_memory(walk_cfg):
    """The daemon's per-cycle call: float temporaries only, across phase changes (a tiny peak)."""
    import gc

    from ankle_rt.control import build_controller
    from ankle_rt.estimation import Estimate
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import TransmissionParams

    ctl = build_controller(walk_cfg, Kinematics.from_params(TransmissionParams(**walk_cfg["transmission"])),
                           np.zeros(2))
    est, out = Estimate(), np.zeros(2)
    ctl.reset(est)
    seen = set()

    def cycles(n):
        for k in range(n):
            est.sg_dp = -100.0 * (k % 700 > 300) + 0.01 * (k % 7)   # stance and swing loads
            est.dp = 0.15 * ((k % 700) / 700)
            est.mv1 = 0.3 * ((k % 5) - 2)
            ctl.update(est, out)
            seen.add(ctl.phase)

    cycles(3000)
    gc.collect()
    current, peak = traced_memory(lambda: cycles(2000))
    assert current < 1024 and peak < 4096
    assert {EARLY_STANCE, EARLY_SWING} <= seen


def test_ctl_gains_with_a_phase_and_bench_walk_json(capsys):
    import json

    from ankle_rt.cli import build_parser, main
    from ankle_rt.commands.ctl import _degree_note, request_from_args

    args = build_parser().parse_args(["ctl", "gains", "--phase", "late_stance", "--stiffness-dp", "180",
                                      "--equilibrium-dp", "-0.5", "--rad"])
    assert request_from_args(args) == {"cmd": "set_gains", "stiffness_dp": 180.0, "phase": "late_stance",
                                       "equilibrium_dp": -0.5}
    args = build_parser().parse_args(["ctl", "gains", "--phase", "late_stance", "--equilibrium-dp", "-30",
                                      "--equilibrium-ie", "5"])    # degrees, as ctl ref and ctl profile take
    req = request_from_args(args)
    assert req["equilibrium_dp"] == pytest.approx(math.radians(-30.0))
    assert req["equilibrium_ie"] == pytest.approx(math.radians(5.0))
    note = _degree_note(build_parser().parse_args(["ctl", "gains", "--phase", "safe", "--equilibrium-dp", "50"]),
                        {"field": "equilibrium_dp"})       # a refusal names the rad the daemon saw
    assert "--equilibrium-dp 50 deg is 0.8727 rad" in note
    assert main(["bench", "walk", "--masses", "75", "--cadences", "normal", "--strides", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["strides"] == 2 and out["faults"] == 0 and out["push_off_work_j_per_kg"] > 0.0
    assert 0.0 < out["current_peak_a"] <= 15.0 and 0.0 < out["i2t_headroom_pct"] <= 100.0
    assert {"moment_rms_error_pct", "angle_rms_error_deg", "current_rms_a"} <= out.keys()
    with pytest.raises(SystemExit, match="cadences"):
        main(["bench", "walk", "--cadences", "brisk"])


def test_a_phase_whose_gains_lose_the_gain_margin_is_refused_naming_it(monkeypatch):
    """Each phase's (K, B) goes through the same gain-margin check as the impedance controller's gains
    (the plant range, the closed torque loop): here a stand-in check refusing K_dp 123 alone."""
    import ankle_rt.control.gait_phase as gp
    from ankle_rt.control import build_controller
    from ankle_rt.control.gains import GainError
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import TransmissionParams

    seen = []

    def refusal(cfg, gains, ff_viscous=0.0, *, noise=True):
        assert not noise                  # the gauges' noise is the loop's, checked with the config
        seen.append(dict(gains))
        return ("stiffness_dp", "loses the margin") if gains["stiffness_dp"] == 123.0 else None

    monkeypatch.setattr(gp, "gain_set_refusal", refusal)
    cfg = load_config(WALK)
    kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
    ctl = build_controller(cfg, kin, np.zeros(2))
    assert ctl.margin_cfg is not None and len(seen) >= len(PHASES)    # every shipped phase checked
    ctl.set_gains(phase="late_swing", stiffness_dp=80.0)
    with pytest.raises(GainError) as err:
        ctl.set_gains(phase="late_swing", stiffness_dp=123.0)
    assert err.value.gain == "late_swing.stiffness_dp"
    assert seen[-1]["stiffness_dp"] == 123.0


def test_the_swing_model_matches_the_closed_form_free_foot(walk_cfg):
    """SwingLimits.excursion (the exact discretisation, built by doubling) against the closed forms:
    with no stiffness the foot coasts to theta_0 + J_f w_0 / B; undamped it swings about its
    equilibrium with amplitude sqrt(x_0^2 + (w_0 / w_n)^2) and peak rate w_n times that."""
    from ankle_rt.control.gait_phase import WALKING_PEAK_DORSIFLEXION
    from ankle_rt.control.swing import SwingLimits

    swing = SwingLimits.from_config(walk_cfg, WALKING_PEAK_DORSIFLEXION)
    swing = SwingLimits(**{**swing.__dict__, "horizon": 2.0})
    j, start = swing.inertia, np.array([[-0.3], [-4.0]])
    coast = swing.excursion(0.0, 5.0, 0.0, start)
    assert coast.low == pytest.approx(-0.3 - 4.0 * j / 5.0, abs=1e-6) and coast.rate == pytest.approx(4.0)
    wn = math.sqrt(60.0 / j)
    ring = swing.excursion(60.0, 0.0, 0.1, start)
    amplitude = math.hypot(-0.4, 4.0 / wn)
    assert ring.low == pytest.approx(0.1 - amplitude, abs=1e-4) and ring.high == pytest.approx(0.1 + amplitude, abs=1e-4)
    assert ring.rate == pytest.approx(wn * amplitude, rel=1e-4)


def test_a_swing_that_lets_the_foot_run_from_toe_off_is_refused(monkeypatch):
    """swing12 (lockstep, config/walk.yaml): early swing with no stiffness and damping 0.09 (the least
    the loop needs) was accepted and ran the free foot from toe-off into ANKLE_RANGE in the first
    stride at 50-100 kg normal cadence (damping 1-2: SG_RAIL or MOTOR_JUMP at 100 kg, early stance's
    spring taking a foot landed at 33 deg of plantarflexion). A swing phase must now keep the foot,
    from any toe-off state, within 3/4 of the ankle range, no faster than it left, and from the
    shortest swing on where the able-bodied heel strike takes it; refused naming the key at load and
    at run time, and a change to the swing phase in force waits for its next beginning."""
    import ankle_rt.bench.walk as bw
    import ankle_rt.control.swing as sw
    from ankle_rt.control import build_controller
    from ankle_rt.control.gains import GainError
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import TransmissionParams

    soft = {"early_swing": {"stiffness_dp": 0.0, "damping_dp": 0.09}}
    cfg = load_config(WALK, {"controller": {"gait_phase": soft}})
    kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
    with pytest.raises(ConfigError) as err:
        build_controller(cfg, kin, np.zeros(2))
    assert err.value.key == "controller.gait_phase.early_swing.damping_dp" and "toe-off" in err.value.message
    ctl = build_controller(load_config(WALK), kin, np.zeros(2))
    for phase, gains, key in (("early_swing", soft["early_swing"], "damping_dp"),
                              ("early_swing", {"stiffness_dp": 0.0, "damping_dp": 10.0}, "stiffness_dp"),
                              ("late_swing", {"equilibrium_dp": 0.52}, "equilibrium_dp"),
                              ("late_swing", {"stiffness_dp": 400.0}, "stiffness_dp")):
        with pytest.raises(GainError) as gerr:
            ctl.check_gains(phase=phase, **gains)
        assert gerr.value.gain == f"{phase}.{key}"
    ctl.gait.phase = EARLY_SWING
    ctl.apply_gains(phase="early_swing", damping_dp=9.0)
    shipped = load_config(WALK)["controller"]["gait_phase"]["early_swing"]["damping_dp"]
    assert ctl.deferred == (EARLY_SWING, {"damping_dp": 9.0}) and ctl.gait.damping_dp[EARLY_SWING] == shipped
    monkeypatch.setattr(sw.SwingLimits, "refusal", lambda *args: None)      # as before the check
    monkeypatch.setattr(bw, "wearer_overrides", lambda c, m, cad, seed: {
        "sim": {"scenario": "walking", "walking": {"mass_kg": m, "cadence": cad, "seed": seed}},
        "controller": {"gait_phase": soft}})
    assert bw.run_walk(str(WALK), 75.0, "normal", 1).fault == "ANKLE_RANGE"


def test_the_softest_swing_the_rule_accepts_walks(tmp_path):
    """At the boundary (the least early-swing damping with any stiffness accepted, 1.33 N m s/rad at
    25 N m/rad, the rendered damping since the law renders the commanded one (1.18 as a law coefficient
    before, which added K kd / (1 + kp) = 0.16); a hundredth less refused): the 100 kg wearer walks
    without a fault (bench walk: 8 strides at 50 / 75 / 100 kg, normal and fast, 0 faults)."""
    import yaml

    import ankle_rt.bench.walk as bw
    from ankle_rt.control import build_controller
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import TransmissionParams

    def early_swing(damping):
        path = tmp_path / f"swing-{damping}.yaml"
        path.write_text(yaml.safe_dump({"include": [str(WALK)], "controller": {"gait_phase": {"early_swing": {
            "stiffness_dp": 25.0, "damping_dp": damping, "equilibrium_dp": 0.0}}}}))
        return path

    cfg = load_config(early_swing(1.32))
    with pytest.raises(ConfigError) as err:
        build_controller(cfg, Kinematics.from_params(TransmissionParams(**cfg["transmission"])), np.zeros(2))
    assert err.value.key.startswith("controller.gait_phase.early_swing.")
    run = bw.run_walk(str(early_swing(1.33)), 100.0, "normal", 2)
    assert run.fault == "NONE" and len(run.strides) == 2
