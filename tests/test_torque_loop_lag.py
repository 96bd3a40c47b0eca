"""The lag (low-frequency boost) on the joint-torque loop's P and rate terms and the per-axis torque filter
(issue 19, fifth pass): the daemon's loop, a batch and the linear model run the same sections; the keys are
bounded; the margin check sees that a large boost makes the loop conditionally stable (the correction's
clamp then limit-cycles it) and refuses it, where a scan of larger gains only did not."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ankle_rt import analysis as an
from ankle_rt.bench.impedance import bench_config
from ankle_rt.config import load_config
from ankle_rt.config_schema import NOTCH_CABLE_STIFFNESS_DEFAULT as K_NOMINAL
from ankle_rt.control.torque_loop import JointTorqueLoop, TorqueLoopGains
from ankle_rt.lag import Lag, lag_section
from ankle_rt.notch import IDENTITY_SECTION
from ankle_rt.paths import default_config_path
from ankle_rt.schema import ConfigError
from tests.loop_configs import walk_loop_config
from tests.test_torque_loop_notch import section_gain

DT = 1e-3
# the DP lag + notch set of the shaping study (cutoff free, IE at its own 80 Hz): boost 2.56 as found, and
# 1.5, what keeps the loop stable both ways (docs/daemon.md, "Fifth pass")
LAG_NOTCH = {"kp_dp": 27.8, "ki_dp": 13.0, "torque_rate_dp": 0.175, "cutoff_hz_dp": 290.0, "lag_hz_dp": 2.9,
             "notch_hz_dp": 74.4, "notch_zeta_dp": 0.85, "notch_depth_dp": 0.40}


@pytest.fixture(scope="module")
def base():
    return walk_loop_config()          # the notched DP loop the lag was studied on


def test_the_lag_boosts_below_its_zero_and_passes_the_cable_modes():
    sec = lag_section(3.0, 2.5, DT)
    assert section_gain(sec, 0.0) == pytest.approx(2.5, rel=1e-12)
    assert section_gain(sec, 80.0) == pytest.approx(1.0, abs=0.01)
    # (s + wz) / (s + wz / b) at its zero: |j wz + wz| / |j wz + wz / b| (Tustin prewarped there: exact)
    assert section_gain(sec, 3.0) == pytest.approx(math.sqrt(2.0) / math.sqrt(1.0 + 1.0 / 2.5 ** 2), rel=1e-9)
    assert lag_section(0.0, 2.5, DT) == lag_section(3.0, 1.0, DT) == IDENTITY_SECTION
    with pytest.raises(ValueError, match="Nyquist"):
        lag_section(600.0, 2.0, DT)


def _correction(tl: dict, f_hz: float, axis: int = 0) -> float:
    """Amplitude (N m) of one axis's correction for a 0.01 N m measured-torque sine at f_hz after the
    transient (integral held: the P and rate terms through the filter, the lag and the notch)."""
    loop = JointTorqueLoop(TorqueLoopGains.from_config(tl, K_NOMINAL), DT)
    sg = [0.0, 0.0]
    out = []
    for k in range(4000):
        sg[axis] = 0.01 * math.sin(2.0 * math.pi * f_hz * k * DT)
        out.append(loop.update(0.0, 0.0, sg[0], sg[1], 0.0, 0.0, False)[axis])
    return float(np.max(np.abs(out[2000:])))


def test_the_daemon_loop_runs_the_lag_on_its_axis_only(base):
    tl = dict(base["controller"]["torque_loop"], torque_rate_dp=0.0, torque_rate_ie=0.0, notch_hz_dp=0.0)
    lagged = dict(tl, lag_hz_dp=5.0, lag_boost_dp=3.0)
    assert _correction(lagged, 0.5) / _correction(tl, 0.5) == pytest.approx(section_gain(lag_section(5.0, 3.0, DT), 0.5),
                                                                        rel=0.01)
    assert _correction(lagged, 0.5) / _correction(tl, 0.5) > 2.8
    assert _correction(lagged, 60.0) / _correction(tl, 60.0) == pytest.approx(1.0, abs=0.01)
    assert _correction(lagged, 0.5, axis=1) == _correction(tl, 0.5, axis=1)


def test_each_axis_filters_the_measured_torque_at_its_own_cutoff(base):
    tl = dict(base["controller"]["torque_loop"], cutoff_hz=80.0, cutoff_hz_dp=290.0)
    gains = TorqueLoopGains.from_config(tl, K_NOMINAL)
    assert gains.cutoff_hz == (290.0, 80.0)
    loop = JointTorqueLoop(gains, DT)
    assert loop.alpha0 == pytest.approx(1.0 - math.exp(-2.0 * math.pi * 290.0 * DT))
    assert loop.alpha1 == pytest.approx(1.0 - math.exp(-2.0 * math.pi * 80.0 * DT))
    unset = TorqueLoopGains.from_config(dict(tl, cutoff_hz_dp=None), K_NOMINAL)
    assert unset.cutoff_hz == (80.0, 80.0)


def test_the_model_runs_the_sections_and_cutoffs_the_daemon_runs(base):
    """One Lag and one Notch serve both: the model's shaping per axis is the daemon's lag then notch (the
    identity ones left out), and its torque filter has the daemon's per-axis cutoffs."""
    from ankle_rt.control.impedance import actuation_from_config

    cfg = walk_loop_config({"controller": {"type": "impedance", "torque_loop": {
        **LAG_NOTCH, "lag_boost_dp": 1.6, "cutoff_hz_ie": 70.0}}})
    loop = actuation_from_config(cfg, None)[0]
    model = an.ImpedanceLoop.from_config(cfg, closed=True)
    assert model.shaping == ((loop.lag0, loop.notch0), ())
    assert loop.lag1 == loop.notch1 == IDENTITY_SECTION
    assert (model.cutoff_hz, model.axis_cutoff_hz) == (80.0, (290.0, 70.0))
    assert (loop.alpha0, loop.alpha1) == tuple(1.0 - math.exp(-2.0 * math.pi * f * DT) for f in (290.0, 70.0))
    # the model's filter rows: the controller's state update at a unit measured torque on each axis
    kin = an._sampled_plant(an.PlantParams.from_config(cfg), DT, foot="free", load_slope=0.0)[3]
    W, _ = model.rows(kin, kin.K)
    n = W.shape[1] - 8
    tau_in = W[4:6, n + 2:n + 4]                       # tau filter (rows 4-5) from the measured torque
    assert np.allclose(np.diag(tau_in), (loop.alpha0, loop.alpha1), rtol=1e-12)


def test_a_batch_mixing_lags_and_cutoffs_runs_each_device_as_alone(base):
    tl = base["controller"]["torque_loop"]
    extras = ({}, {"lag_hz_dp": 3.0, "lag_boost_dp": 2.0, "cutoff_hz_ie": 150.0}, {"lag_hz_ie": 1.0, "lag_boost_ie": 1.5})
    gains = [TorqueLoopGains.from_config(dict(tl, **extra), K_NOMINAL) for extra in extras]
    alone = [JointTorqueLoop(g, DT) for g in gains]
    batch = JointTorqueLoop.stack([JointTorqueLoop(g, DT) for g in gains])
    n = len(gains)
    for k in range(300):
        sg = 0.5 * math.sin(0.05 * k)
        got = batch.update(np.full(n, 1.0), np.full(n, -0.5), np.full(n, sg), np.full(n, -sg), np.zeros(n), np.zeros(n),
                           True)
        for i, loop in enumerate(alone):
            want = loop.update(1.0, -0.5, sg, -sg, 0.0, 0.0, True)
            assert got[0][i] == pytest.approx(want[0], abs=1e-12) and got[1][i] == pytest.approx(want[1], abs=1e-12)


@pytest.mark.parametrize("key, value", [("lag_boost_dp", 0.5), ("lag_boost_ie", 11.0), ("lag_hz_dp", -1.0),
                                        ("lag_hz_ie", 60.0), ("cutoff_hz_dp", 0.5), ("cutoff_hz_ie", 500.0)])
def test_a_lag_or_cutoff_out_of_bounds_is_refused_naming_its_key(key, value):
    with pytest.raises(ConfigError) as err:
        walk_loop_config({"controller": {"torque_loop": {key: value}}})
    assert err.value.key == f"controller.torque_loop.{key}"


@pytest.mark.parametrize("k_dp", [50.0, 200.0])
def test_a_large_boost_is_conditionally_stable_and_refused(base, k_dp):
    """The study's boost 2.56 keeps ~10 dB upwards but the loop is unstable with its correction at a quarter of
    its gain (what the clamp does to a large error: in lockstep the clamped correction limit-cycled the +-12 N m
    pulses); the check now scans the correction's gain down and refuses it naming the boost; boost 1.5
    is stable all the way down and keeps >= 6 dB upwards."""
    cfg = bench_config(base, stiffness=(k_dp, k_dp / 2.0), damping=(0.5, 0.25), torque_feedback="auto",
                       friction_ff=None, effects=[])
    refused = dict(LAG_NOTCH, lag_boost_dp=2.56)
    margin, limit = an.gain_set_margin_db(cfg, refused)
    assert margin < 6.0 and limit == "lag_boost_dp"
    loop = an.ImpedanceLoop.from_config(an._with_gains(cfg, refused), closed=True)
    p = an.PlantParams.from_config(cfg)

    def rho(correction_gain: float) -> float:       # the worst case's spectral radius, the correction scaled
        T0, Tu = an._loop_matrices(p, dataclasses.replace(loop, correction_gain=correction_gain), an.LOAD_FRICTION_RANGE)
        return float(np.abs(np.linalg.eigvals(T0 + Tu)).max())

    assert rho(1.0) < 1.0 and rho(0.25) >= 1.0
    up = min(m.gain_margin_db for m in an.torque_loop_margins(p, loop))
    assert up >= 6.0                                  # what a scan of larger gains only accepted
    kept, none = an.gain_set_margin_db(cfg, dict(LAG_NOTCH, lag_boost_dp=1.5))
    assert kept >= 6.0 and none is None


def test_lag_from_config_reads_both_axes(base):
    tl = dict(base["controller"]["torque_loop"], lag_hz_dp=2.0, lag_boost_dp=1.5)
    lag = Lag.from_config(tl)
    assert lag.hz == (2.0, 0.0) and lag.boost == (1.5, 1.0)
    assert lag.sections(DT) == (lag_section(2.0, 1.5, DT), IDENTITY_SECTION)


@pytest.mark.parametrize("base_file", ["sim.yaml", "walk.yaml"])
def test_the_opt_in_lag_notch_loop_is_accepted_where_shipped_and_runs_its_lag(tmp_path, base_file):
    """config/torque-loop-lag-notch.yaml after sim.yaml and walk.yaml: loaded and its controller built (the
    gait phases' margins checked too), the DP lag and the own DP cutoff in the daemon's loop."""
    from ankle_rt.control import build_controller
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import TransmissionParams
    from ankle_rt.paths import CONFIG_DIR

    path = tmp_path / "opt.yaml"
    path.write_text(f"include: [{CONFIG_DIR / base_file}, {CONFIG_DIR / 'torque-loop-lag-notch.yaml'}]\n")
    cfg = load_config(path, {"controller": {"type": "impedance"}} if base_file == "sim.yaml" else None)
    ctl = build_controller(cfg, Kinematics.from_params(TransmissionParams(**cfg["transmission"])), np.zeros(2))
    loop = ctl.torque_loop
    assert loop.lag0 == lag_section(2.9, 1.5, DT) and loop.lag1 == IDENTITY_SECTION
    assert loop.gains.cutoff_hz == (290.0, 80.0)


@pytest.mark.parametrize("rate_source", [{"torque_rate_source": "gauges"},
                                         {"torque_rate_source": "encoders", "torque_rate_crossover_hz_dp": 5.0,
                                          "torque_rate_crossover_hz_ie": 20.0, "torque_rate_agreement_nm": 10.0}])
def test_the_daemon_loop_and_the_model_controller_give_the_same_torques(base, rate_source):
    """The daemon's JointTorqueLoop and the linear model's controller rows (ImpedanceLoop: the rows the margin
    check closes the loop with) driven by the same measured torques, motor and joint angles and desired torques
    (the law at K = B = 0, so the desired torque is the model's r), with a DP lag and two notches, an IE notch,
    per-axis cutoffs and the high-passed motor-rate damping on both axes, the rate terms on the gauges or on the
    cables' stretch (within its agreement with the gauges: the model is the small-signal loop): the same
    ankle-side torque every cycle (the correction inside its clamp)."""
    tl = dict(base["controller"]["torque_loop"], **LAG_NOTCH, lag_boost_dp=1.8, cutoff_hz_ie=120.0, notch_hz_ie=72.3,
              notch_zeta_ie=0.5, notch_depth_ie=0.58, notch2_hz_dp=140.0, notch2_zeta_dp=0.5, notch2_depth_dp=0.5,
              motor_rate_damping_dp=40.0, motor_rate_damping_hz_dp=30.0, motor_rate_damping_ie=15.0,
              motor_rate_damping_hz_ie=15.0, max_correction_dp=100.0, max_correction_ie=100.0, **rate_source)
    cfg = walk_loop_config({"controller": {"type": "impedance"}})
    cfg["controller"]["torque_loop"].update(tl)
    model = dataclasses.replace(an.ImpedanceLoop.from_config(cfg, closed=True), stiffness=(0.0, 0.0), damping=(0.0, 0.0))
    assert len(model.shaping[0]) == 3 and len(model.shaping[1]) == 1
    kin = an._sampled_plant(an.PlantParams.from_config(cfg), DT, foot="free", load_slope=0.0)[3]
    W, _ = model.rows(kin, kin.K)
    loop = JointTorqueLoop(TorqueLoopGains.from_config(tl, cfg["transmission"]["cable_stiffness"]), DT)
    a_v = 1.0 - math.exp(-2.0 * math.pi * model.velocity_cutoff_hz * DT)     # the estimator's velocity filter
    assert model.rate_from_encoders == (loop.encoder_rate,) * 2
    rng = np.random.default_rng(19)
    freqs, phases = rng.uniform(0.5, 30.0, (8, 2)), rng.uniform(0.0, 2.0 * math.pi, (8, 2))
    w, v, th_prev, largest = np.zeros(W.shape[0]), np.zeros(2), np.zeros(2), 0.0
    for k in range(1500):
        tau, r, th, slack = (a * np.sin(2.0 * math.pi * freqs[j:j + 2] * k * DT + phases[j:j + 2]).sum(axis=0)
                             for a, j in ((0.2, 0), (1.0, 2), (0.005, 4), (1e-4, 6)))
        joint = kin.R_inv @ th - slack        # the cables stretched by slack (rad at the ankle)
        w = W @ np.concatenate([w, th, tau, joint, r])
        v = v + a_v * ((th - th_prev) / DT - v)
        th_prev = th
        rate = kin.R_inv @ v
        stretch = kin.K @ (kin.R_inv @ th - joint)
        got = loop.update(r[0], r[1], tau[0], tau[1], rate[0], rate[1], True, stretch[0], stretch[1])
        assert np.allclose(got, w[10:12], rtol=0.0, atol=1e-9)
        largest = max(largest, *(abs(g - x) for g, x in zip(got, r)))
    assert 1.0 < largest < 100.0          # the correction did work, inside its clamp


def test_a_config_with_a_conditionally_stable_lag_is_refused_naming_the_lag():
    """At K_dp 50 the loader refuses the study's boost 2.56 naming controller.torque_loop.lag_boost_dp (not
    the stiffness, which restores less margin), and an own cutoff that breaks the margin naming it."""
    imp = {"stiffness_dp": 50.0, "stiffness_ie": 25.0}
    with pytest.raises(ConfigError) as err:
        walk_loop_config({"controller": {"type": "impedance", "impedance": imp,
                                                           "torque_loop": dict(LAG_NOTCH, lag_boost_dp=2.56)}})
    assert err.value.key == "controller.torque_loop.lag_boost_dp" and "dB" in err.value.message
    with pytest.raises(ConfigError) as err:
        walk_loop_config({"controller": {"type": "impedance", "torque_loop": {"cutoff_hz_dp": 20.0}}})
    assert err.value.key == "controller.torque_loop.cutoff_hz_dp"


def test_config_check_prints_the_torque_filters_and_lags(tmp_path):
    from ankle_rt.commands.config import describe
    from ankle_rt.paths import CONFIG_DIR

    path = tmp_path / "opt.yaml"
    path.write_text(f"include: [{CONFIG_DIR / 'walk.yaml'}, {CONFIG_DIR / 'torque-loop-lag-notch.yaml'}]\n")
    assert any("torque filter DP 290 / IE 80 Hz; lag DP 2.9 Hz x1.5, IE none" in line for line in describe(load_config(path)))
    assert any("torque filter DP 80 / IE 80 Hz; lag DP none, IE none" in line
               for line in describe(load_config(CONFIG_DIR / "walk.yaml")))


@pytest.mark.parametrize("axis", [0, 1])
def test_the_lag_does_not_wind_up_behind_the_clamp(base, axis):
    """Below its zero the lag integrates: a slow one (0.05 Hz, boost 10: a config the loader accepts) fed
    a one-sided error the clamped correction cannot remove must not hold the correction at the clamp
    once the error reverses (unheld, its state reached 412 N m in 30 s and held the +30 N m clamp 20 s
    more); the correction leaves the clamp as the integral's alone would."""
    name = ("dp", "ie")[axis]
    tl = dict(base["controller"]["torque_loop"], dob_hz=0.0, **{f"lag_hz_{name}": 0.05, f"lag_boost_{name}": 10.0})
    loop = JointTorqueLoop(TorqueLoopGains.from_config(tl, K_NOMINAL), DT)
    lim = tl[f"max_correction_{name}"]

    def correction(error: float) -> float:
        des = [0.0, 0.0]
        des[axis] = error
        return loop.update(des[0], des[1], 0.0, 0.0, 0.0, 0.0, True)[axis] - error

    held = [correction(5.0) for _ in range(30000)]
    assert held[-1] == pytest.approx(lim)                      # the clamp held the correction
    after = [correction(-2.0) for _ in range(100)]
    assert after[0] < lim - 1.0 and max(after) < lim           # off the clamp at once and stays off


def test_a_batch_holds_each_lag_at_its_clamp_as_alone(base):
    """The held lag state is element-wise: a batch of a slow lag, a fast one and none, driven into the clamp
    and back out, gives each device's correction as it runs alone."""
    tl = dict(base["controller"]["torque_loop"], dob_hz=0.0)
    extras = ({"lag_hz_dp": 0.05, "lag_boost_dp": 10.0}, {"lag_hz_ie": 2.9, "lag_boost_ie": 1.5}, {})
    gains = [TorqueLoopGains.from_config(dict(tl, **extra), K_NOMINAL) for extra in extras]
    alone = [JointTorqueLoop(g, DT) for g in gains]
    batch = JointTorqueLoop.stack([JointTorqueLoop(g, DT) for g in gains])
    n = len(gains)
    for k in range(3000):
        des = 5.0 if k < 2000 else -2.0 + math.sin(0.01 * k)
        got = batch.update(np.full(n, des), np.full(n, -des), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), True)
        for i, loop in enumerate(alone):
            want = loop.update(des, -des, 0.0, 0.0, 0.0, 0.0, True)
            assert got[0][i] == pytest.approx(want[0], abs=1e-12) and got[1][i] == pytest.approx(want[1], abs=1e-12)
