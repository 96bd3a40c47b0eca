"""Estimation (velocity filter, tare, ankle angle through the cable stretch) and the reference
profiles (step, sine, chirp, gait, CSV, ramps started from the current reference)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ankle_rt.backend import SensorFrame
from ankle_rt.config import ConfigError
from ankle_rt.daemon import run_lockstep
from ankle_rt.estimation import Estimate, Estimator
from ankle_rt.interchange import InterchangeError
from ankle_rt.kinematics import Kinematics
from ankle_rt.params import TransmissionParams
from ankle_rt.references import Gait, Hold, RampTo, ReferenceGenerator, make_profile, reference_from_config
from tests.daemon_helpers import variant


def _estimator(cfg, cutoff=100.0, tare=1):
    kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
    return kin, Estimator(kin, 1e-3, cutoff, tare)


def test_velocity_of_a_quantised_ramp_converges_and_lags_by_the_filter_time_constant(sim_cfg):
    _, est_ = _estimator(sim_cfg, cutoff=50.0)
    frame, est = SensorFrame(), Estimate()
    q = 2 * math.pi / sim_cfg["actuator"]["encoder_counts_per_rev"]
    v = 0.3                                             # rad/s: 5.6 counts per ms
    tau = 1.0 / (2 * math.pi * 50.0)
    vel = []
    for k in range(400):
        frame.t = k * 1e-3
        frame.motor_pos[:] = math.floor(v * frame.t / q) * q if k else 0.0
        est_.update(frame, est)
        vel.append(est.motor_vel[0])
    vel = np.array(vel)
    assert abs(vel[200:].mean() - v) < 0.002 * v          # unbiased on average
    assert np.std(vel[200:]) < 0.1 * v                   # the count staircase is smoothed
    k63 = int(np.argmax(vel > 0.632 * v))                # first-order step response
    assert k63 * 1e-3 == pytest.approx(tau, abs=1.5e-3)


def test_tare_removes_the_strain_gauge_offset_before_activation(sim_cfg):
    cfg = variant(sim_cfg, sim={"strain_gauge_offset": [0.8, -0.5]}, reference={"profile": "hold"})
    res = run_lockstep(cfg, 0.5)
    assert np.abs(res["sg_torque_dp"][200:]).mean() < 0.03
    assert np.abs(res["sg_torque_ie"][200:]).mean() < 0.03
    # without the tare the IE estimate would be off by 0.5 / K_IE = 0.13 deg
    assert np.degrees(np.abs(res["est_ankle_ie"][200:] - res["ankle_ie"][200:]).mean()) < 0.02


def test_ankle_estimate_accounts_for_the_cable_stretch(sim_cfg):
    kin = Kinematics.from_params(TransmissionParams(**sim_cfg["transmission"]))
    cfg = variant(sim_cfg, reference={"profile": "hold"}, sim={"sensor_noise": False, "disturbances": [
        {"start": 0.3, "stop": 10.0, "torque_dp": 2.0, "torque_ie": 1.0}]})
    res = run_lockstep(cfg, 1.5)
    late = slice(1300, 1500)
    true = np.column_stack([res["ankle_dp"], res["ankle_ie"]])[late]
    est = np.column_stack([res["est_ankle_dp"], res["est_ankle_ie"]])[late]
    rigid = (kin.R_inv @ np.vstack([res["motor_pos_1"], res["motor_pos_2"]])).T[late]
    stretch = np.abs(rigid - true).mean(axis=0)
    assert np.all(stretch > [1e-3, 4e-3])                 # 2 / K_DP and 1 / K_IE rad of stretch
    assert np.all(np.abs(est - true).mean(axis=0) < stretch / 20)


def test_profiles_step_sine_chirp_gait():
    step = make_profile("step", {"dp": 0.1, "ie": 0.05, "start_s": 0.5})
    assert step.value(0.499) == (0.0, 0.0) and step.value(0.5) == (0.1, 0.05)
    sine = make_profile("sine", {"amplitude_dp": 0.1, "amplitude_ie": 0.05, "frequency_hz": 2.0, "ie_phase": math.pi / 2})
    assert sine.value(0.125)[0] == pytest.approx(0.1) and sine.value(0.125)[1] == pytest.approx(0.0, abs=1e-12)
    chirp = make_profile("chirp", {"amplitude_dp": 0.1, "f0_hz": 1.0, "f1_hz": 11.0, "duration_s": 10.0})
    t = np.arange(0, 10, 1e-4)
    x = np.array([chirp.value(s)[0] for s in t])
    crossings = np.flatnonzero(np.diff(np.sign(x)) != 0)
    tc = t[crossings]
    f_local, t_mid = 1 / (2 * np.diff(tc)), (tc[1:] + tc[:-1]) / 2     # instantaneous frequency
    assert np.allclose(f_local, 1.0 + t_mid, rtol=0.03)                  # f0 + (f1 - f0) t / duration
    gait = Gait(stride_s=1.0)
    stride = np.degrees(np.array([gait.value(s) for s in np.arange(0, 2, 1e-3)]))
    assert np.allclose(stride[:1000], stride[1000:], atol=1e-9)             # periodic
    assert -17 < stride[:, 0].min() < -12 and 8 < stride[:, 0].max() < 12    # push-off / late stance DP
    assert np.abs(np.diff(stride, axis=0)).max() < 0.5                        # smooth at 1 kHz


def test_relative_profiles_start_from_the_current_reference_and_ramps_are_linear():
    gen = ReferenceGenerator(Hold(0.2, -0.1))
    gen.update(0.0)
    gen.start(make_profile("sine", {"amplitude_dp": 0.05, "frequency_hz": 1.0}))
    gen.update(1.0)
    assert tuple(gen.ref) == pytest.approx((0.2, -0.1))
    gen.update(1.25)
    assert tuple(gen.ref) == pytest.approx((0.25, -0.1))
    gen.start(RampTo(0.0, 0.0, 2.0))
    gen.update(2.0)
    start = tuple(gen.ref)
    gen.update(3.0)
    assert tuple(gen.ref) == pytest.approx((start[0] / 2, start[1] / 2))
    gen.update(5.0)
    assert tuple(gen.ref) == (0.0, 0.0)


def test_csv_profile_interpolates_and_bad_files_name_column_and_row(sim_cfg, tmp_path):
    good = tmp_path / "refs.csv"
    good.write_text("t,ref_dp,ref_ie\n0,0,0\n1,0.2,-0.1\n")
    cfg = variant(sim_cfg, reference={"profile": "csv", "csv": {"path": str(good)}})
    gen = reference_from_config(cfg)
    assert gen.profile.value(0.5) == pytest.approx((0.1, -0.05))
    assert gen.profile.value(3.0) == pytest.approx((0.2, -0.1))
    step = cfg["reference"]["max_rate_rad_s"] / cfg["controller"]["rate_hz"]   # rate limited, as commanded
    for k in range(1, 201):
        gen.update(k * 1e-3)
    assert tuple(gen.ref) == pytest.approx((0.04, -0.02))   # slower than the limit: as written
    gen.update(3.0)                                          # 2.8 s of the file in one update: one step
    assert tuple(gen.ref) == pytest.approx((0.04 + step, -0.02 - step))
    bad = tmp_path / "bad.csv"
    bad.write_text("t,ref_dp,ref_ie\n0,0,0\n1,abc,0\n")
    with pytest.raises(InterchangeError) as err:
        make_profile("csv", {"path": str(bad)})
    assert err.value.column == "ref_dp" and err.value.row == 2
    (tmp_path / "nocol.csv").write_text("t,ref_dp\n0,0\n")
    with pytest.raises(InterchangeError, match="ref_ie"):
        make_profile("csv", {"path": str(tmp_path / "nocol.csv")})
    (tmp_path / "back.csv").write_text("t,ref_dp,ref_ie\n0,0,0\n1,0,0\n0.5,0,0\n")
    with pytest.raises(InterchangeError, match="time does not increase") as err:
        make_profile("csv", {"path": str(tmp_path / "back.csv")})
    assert err.value.column == "t" and err.value.row == 3
    with pytest.raises(ConfigError, match="reference.csv.path"):
        reference_from_config(variant(sim_cfg, reference={"profile": "csv"}))
    with pytest.raises(ConfigError, match=r"reference\.csv\.path.*'ref_dp'.*row 2"):
        reference_from_config(variant(sim_cfg, reference={"profile": "csv", "csv": {"path": str(bad)}}))


def test_a_config_profile_error_keeps_its_whole_message(sim_cfg):
    """Re-keyed to reference.<profile>.<key> without cutting the message at its own ': '."""
    with pytest.raises(ConfigError) as err:
        reference_from_config(variant(sim_cfg, reference={"profile": "sine", "sine": {"bogus": 1.0}}))
    assert err.value.key == "reference.sine.bogus"
    assert err.value.message.startswith("unknown key (expected one of: amplitude_dp")
