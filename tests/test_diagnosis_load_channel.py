"""The load channel (diag21i): a record without joint angles whose foot rests on a linear load (a bench rig)
still shows a gap between a motor's rotor and its pulley (gear backlash) and a stiffening cable, from the
gauges' spring law of the motor angles (ankle_rt.diagnosis.signals.LoadChannel, candidates.GearBacklash,
candidates.LoadHardening)."""

from __future__ import annotations

import numpy as np
import pytest

from ankle_rt.config import load_config
from ankle_rt.diagnosis import diagnose
from ankle_rt.diagnosis.candidates import GearBacklash, LoadHardening
from ankle_rt.diagnosis.core import Inputs, _add_drift_nuisance, _joint_angles_add_noise, build_channels, geometry_of
from ankle_rt.diagnosis.regression import rss_only
from ankle_rt.diagnosis.signals import LoadChannel, lattice_step
from ankle_rt.interchange import Recording
from benchmarks.diagnosis_cases_c import SIM_CONFIG
from benchmarks.diagnosis_cases_d import R_PULLEY, draw_case_d, make_case_d


def short_case(seed: int, effects: list[str]):
    """8 s + 4 s of generator D's multisine under the motor PD law, no joint encoders (seeds 130 and 131
    draw a bench rig, 132 a free foot)."""
    return make_case_d(seed, effects, motion="multisine", ident_s=8, valid_s=4)


def test_the_load_channel_needs_a_spring_law_of_the_motor_angles():
    """On a bench rig the gauges' torque is a spring law of the motor angles (the spring term explains
    > 98 % of it on both axes); with the free foot it carries no such law and the channel is not used."""
    rig, free = short_case(131, []), short_case(132, [])
    geometry = geometry_of(rig.nominal_cfg)
    assert "ankle_dp" not in rig.ident and "ankle_dp" not in free.ident
    assert LoadChannel.available(rig.ident)
    loaded = LoadChannel(rig.ident, geometry)
    assert loaded.linear and np.all(loaded.spring_share > 0.98) and np.all(loaded.stiffness > 0.0)
    assert not LoadChannel(free.ident, geometry).linear


def test_a_gear_gap_is_named_backlash_per_cable_and_an_effect_free_rig_is_not():
    """Generator D's gear backlash (a true gap between rotor and pulley, the encoder on the rotor) without
    joint encoders read `none` (the cable side needs the joint angles; seeds 130, 135). On a rig the rotor
    crosses the gap with no change of the cable torque: named `backlash` per cable in the load channel, its
    half-width within a factor 2 of the true one (r g / 2). The same device without the gap names none."""
    case = short_case(130, ["backlash"])
    diag = diagnose(case.ident, case.valid, plant="ankle", cfg=case.nominal_cfg)
    assert diag.causes == ["backlash"], (diag.causes, diag.notes)
    effect = diag.effects[0]
    assert effect["channel"] == "load" and effect["effect"]["per"] == "cable"
    true = R_PULLEY * case.effects[0]["gap"] / 2
    assert 0.5 * true < effect["parameters"]["half_width"]["value"] < 2.0 * true
    clean = short_case(130, [])
    assert "backlash" not in diagnose(clean.ident, clean.valid, plant="ankle", cfg=clean.nominal_cfg).causes


def test_the_series_law_gives_the_cables_own_hardening_stretch():
    """A cubic cable law (hardening stretch 4 mm) behind torsion springs of 150 and 60 N m/rad, solved
    exactly for the tension at each motor angle: the load channel's stiffening column, with each axis'
    series factor K' (K' / K)^(p + 1), gives the cable's own hardening stretch within 5 %."""
    geometry = geometry_of(load_config(SIM_CONFIG))
    t = np.arange(0.0, 8.0, 1e-3)
    phi_m = np.column_stack([0.09 * np.sin(2 * np.pi * 0.3 * t) + 0.03 * np.sin(2 * np.pi * 1.1 * t),
                             0.06 * np.sin(2 * np.pi * 0.45 * t + 1.0)])      # motor angles at the axes, rad
    rig, s_h = np.array([150.0, 60.0]), 4e-3

    def tension(phi_c):
        return geometry.K * phi_c * (1.0 + (geometry.levers * np.abs(phi_c) / s_h) ** 2)

    phi_c = phi_m.copy()
    for _ in range(60):       # Newton on phi_c + tension(phi_c) / rig = phi_m (monotone in phi_c)
        slope = 1.0 + geometry.K * (1.0 + 3.0 * (geometry.levers * phi_c / s_h) ** 2) / rig
        phi_c -= (phi_c + tension(phi_c) / rig - phi_m) / slope
    tau = tension(phi_c)
    theta = phi_m @ np.linalg.inv(geometry.R_inv).T
    rec = Recording({"t": t, "motor_pos_1": theta[:, 0], "motor_pos_2": theta[:, 1],
                     "sg_torque_dp": tau[:, 0], "sg_torque_ie": tau[:, 1]}, "rig")
    ch = LoadChannel(rec, geometry)
    hardening = LoadHardening()
    X = np.hstack([ch.baseline_design(), hardening.design(ch, 3.0).X])
    coef = np.linalg.lstsq(X, ch.target(), rcond=None)[0]
    params = hardening.parameters(coef[-1:], np.zeros((1, 1)), 3.0, 0.0, ch, coef[:-1])
    assert params["hardening_stretch"][0] == pytest.approx(s_h, rel=0.05)


def _relaxing_rig(joint_count: float) -> Recording:
    """A linear cable with a relaxing branch (20 % of K, 0.5 s) on torsion springs of 150 / 60 N m/rad, the
    joint angles counted in steps of ``joint_count`` rad (0: exact)."""
    geometry = geometry_of(load_config(SIM_CONFIG))
    dt = 1e-3
    t = np.arange(0.0, 12.0, dt)
    phi_m = np.column_stack([0.09 * np.sin(2 * np.pi * 0.3 * t) + 0.03 * np.sin(2 * np.pi * 1.1 * t),
                             0.06 * np.sin(2 * np.pi * 0.45 * t + 1.0) + 0.02 * np.sin(2 * np.pi * 1.7 * t)])
    rig, share, decay = np.array([150.0, 60.0]), 0.2, 1.0 - np.exp(-dt / 0.5)
    K = geometry.K
    relaxed, phi_c, tau = np.zeros(2), np.empty_like(phi_m), np.empty_like(phi_m)
    for i in range(len(t)):       # the cable's stretch where the cable and its branch balance the springs
        phi_c[i] = (rig * phi_m[i] + share * K * relaxed) / (K * (1.0 + share) + rig)
        tau[i] = K * phi_c[i] + share * K * (phi_c[i] - relaxed)
        relaxed += (phi_c[i] - relaxed) * decay
    return _rig_record(t, phi_m, phi_c, tau, joint_count, "relaxing rig")


def _rig_record(t: np.ndarray, phi_m: np.ndarray, phi_c: np.ndarray, tau: np.ndarray, joint_count: float,
                source: str) -> Recording:
    """The log of a rig whose motors set the stretch ``phi_m`` per axis (rad) of the cable (``phi_c``) and
    the springs in series, the cable's torque ``tau``: the joint angle is what the springs take, counted in
    steps of ``joint_count`` rad (0: exact), and the motors' torques are those that hold the cables."""
    geometry = geometry_of(load_config(SIM_CONFIG))
    theta = phi_m - phi_c
    if joint_count:
        theta = np.round(theta / joint_count) * joint_count
    motors = phi_m @ np.linalg.inv(geometry.R_inv).T
    drive = tau @ geometry.R_inv_T.T
    return Recording({"t": t, "motor_pos_1": motors[:, 0], "motor_pos_2": motors[:, 1],
                      "motor_torque_1": drive[:, 0], "motor_torque_2": drive[:, 1],
                      "sg_torque_dp": tau[:, 0], "sg_torque_ie": tau[:, 1],
                      "ankle_dp": theta[:, 0], "ankle_ie": theta[:, 1]}, source)


def test_the_rig_law_takes_the_cable_side_only_where_the_joint_counts_are_noise():
    """On a rig the load channel replaces the cable channel where the cable law of the stretch fits the
    gauges 10x worse, beside the same linear filters of its angle: 12-bit joint encoders on a few mrad of
    stretch. Exact joint angles keep the cable channel, also with a relaxing cable (the load's filters in
    its baseline alone made them look 7000x worse)."""
    geometry = geometry_of(load_config(SIM_CONFIG))
    for count, coarse in ((0.0, False), (2 * np.pi / 4096, True)):
        rec = _relaxing_rig(count)
        inputs = Inputs(kt=None, v_eps=0.01, geometry=geometry, notes=[],
                        joint_step=max(lattice_step(rec[c]) for c in ("ankle_dp", "ankle_ie")))
        chans = build_channels(rec, inputs)
        assert chans["load"].linear
        ratio = _joint_angles_add_noise(chans)
        assert (ratio is not None and ratio > 10.0) == coarse, (count, ratio)


def _slack_rig(half_width_m: float | tuple[float, float], joint_count: float) -> Recording:
    """A cable with a dead zone of ``half_width_m`` m of cable (half_width_m / lever rad of stretch per
    axis; a pair: DP's and IE's own) on stiff torsion springs (350 / 120 N m/rad), quasi-static, the joint
    angles counted in steps of ``joint_count`` rad: the rig's softer spring in series makes the law of the
    motor angles the closer linear law, though the joint angles resolve the dead zone."""
    geometry = geometry_of(load_config(SIM_CONFIG))
    t = np.arange(0.0, 12.0, 1e-3)
    phi_m = np.column_stack([0.04 * np.sin(2 * np.pi * 0.3 * t) + 0.012 * np.sin(2 * np.pi * 1.1 * t),
                             0.03 * np.sin(2 * np.pi * 0.45 * t + 1.0) + 0.01 * np.sin(2 * np.pi * 1.7 * t)])
    rig, K, b = np.array([350.0, 120.0]), geometry.K, np.asarray(half_width_m) / geometry.levers
    # tau = K (phi_c - b sign phi_c) beyond the dead zone = rig (phi_m - phi_c); inside it the cable is slack
    phi_c = np.where(np.abs(phi_m) > b, (rig * phi_m + K * b * np.sign(phi_m)) / (K + rig), phi_m)
    tau = np.where(np.abs(phi_m) > b, K * (phi_c - b * np.sign(phi_c)), 0.0)
    return _rig_record(t, phi_m, phi_c, tau, joint_count, "slack rig")


def test_a_slack_cable_on_a_stiff_rig_keeps_the_joint_angles():
    """Generator E: a dead zone in the cables on a stiff rig, with 16-bit joint encoders. Its linear cable
    law fits the gauges far worse than the rig's law of the motor angles, which hides the dead zone in
    the rig's softer spring; with its dead zone the cable law fits far better than the load's best form.
    The joint angles carry the dead zone: the cable channel keeps them."""
    geometry = geometry_of(load_config(SIM_CONFIG))
    rec = _slack_rig((1e-4, 1e-4), 2 * np.pi / 65536)
    inputs = Inputs(kt=None, v_eps=0.01, geometry=geometry, notes=[],
                    joint_step=max(lattice_step(rec[c]) for c in ("ankle_dp", "ankle_ie")))
    chans = build_channels(rec, inputs)
    assert chans["load"].linear
    cable, load = chans["cable"], chans["load"]
    linear_cable = rss_only(cable.target(), np.hstack([cable.baseline_design(), cable.history_columns()]))
    assert rss_only(load.target(), load.baseline_design()) < 0.1 * linear_cable      # linear: "noise"
    assert _joint_angles_add_noise(chans) is None


@pytest.mark.parametrize("widths", [(1e-4, 1e-4), (2e-4, 6e-5)])
def test_a_slack_cable_on_a_stiff_rig_is_named_backlash_in_the_cable_channel(widths):
    """On that rig the motor angles follow the joint angles, so the encoder-scale columns can rebuild the
    rig's law of the motor angles (scale ratios of thousands): no calibration takes such values, and it is
    passed over in the selection (noted) instead of being chosen and refused only after it kept the
    dead zone out. The dead zone is named with its width: one length of cable for both axes where it is
    one (refined), each axis' own where they differ (on the grid of widths, 22 % a step), with no
    `unknown` beside it (generator E's dead zones of 4 and 3 mrad)."""
    rec = _slack_rig(widths, 2 * np.pi / 65536)
    rng = np.random.default_rng(1)
    for c in ("sg_torque_dp", "sg_torque_ie"):
        rec.columns[c] = rec.columns[c] + 0.02 * rng.standard_normal(len(rec))
    diag = diagnose(rec, None, plant="ankle", cfg=load_config(SIM_CONFIG))
    assert diag.causes == ["backlash"], (diag.causes, diag.notes)
    effect = diag.effects[0]
    assert effect["channel"] == "cable" and effect["effect"]["per"] == "axis"
    params = effect["parameters"]
    if widths[0] == widths[1]:
        assert "half_width_ie" not in params
        assert params["half_width"]["value"] == pytest.approx(widths[0], rel=0.1)
    else:
        fitted = (params["half_width"]["value"], params["half_width_ie"]["value"])
        assert fitted == pytest.approx(widths, rel=0.25)
        # the candidate table names the widths, not the pair's internal code
        axis_form = [c for c in diag.candidates if "half_width_ie" in c]
        assert axis_form and not any("half_widths" in c for c in diag.candidates)
    assert any("encoder_scale passed over in the selection" in n for n in diag.notes), diag.notes


def test_joint_encoders_coarser_than_every_dead_zone_width_leave_a_verdict():
    """Joint angles counted in 0.04 rad (one count at the longer lever is 2.3 mm of cable, beyond the widest
    dead zone searched): no dead zone nor taut-stretch stiffening applies, and the channels are still
    compared and the record diagnosed (the comparison asked them for their best value on an empty grid)."""
    rec = _slack_rig((1e-4, 1e-4), 0.04)
    diag = diagnose(rec, None, plant="ankle", cfg=load_config(SIM_CONFIG))
    assert diag.causes


def test_a_gauge_drift_keeps_the_loads_own_dynamics_in_its_baseline():
    """A drift's time shapes join the load channel's nuisance columns (the load's inertia, damping and
    relaxation) instead of replacing them, and building them again gives the same columns."""
    geometry = geometry_of(load_config(SIM_CONFIG))
    load = build_channels(_relaxing_rig(0.0), Inputs(kt=None, v_eps=0.01, geometry=geometry, notes=[]))["load"]
    own = load.nuisance.copy()
    _add_drift_nuisance(load)
    _add_drift_nuisance(load)
    assert load.nuisance.shape[1] == own.shape[1] + 6 and np.array_equal(load.nuisance[:, :own.shape[1]], own)


def test_a_stiffening_cable_is_named_through_the_rig():
    """Generator D's cable stiffening (tension ~ e0 sinh(e / e0)) on a rig without joint encoders: the
    spring law of the motor angles stiffens. Named `stiffness_nonlinear` in the load channel, the cable's
    own hardening stretch (the series law's coefficient x (K / K')^(p + 1) per axis) within 40 % of the
    cubic law sinh approaches at small stretch (s_h = sqrt(6) e0); the same device without it names none."""
    case = short_case(131, ["stiffness_nonlinear"])
    diag = diagnose(case.ident, case.valid, plant="ankle", cfg=case.nominal_cfg)
    assert diag.causes == ["stiffness_nonlinear"], (diag.causes, diag.notes)
    effect = diag.effects[0]
    assert effect["channel"] == "load" and effect["effect"]["exponent"] == 3.0
    cubic = np.sqrt(6.0) * case.effects[0]["e0"]
    assert effect["parameters"]["hardening_stretch"]["value"] == pytest.approx(cubic, rel=0.4)
    clean = short_case(131, [])
    assert diagnose(clean.ident, clean.valid, plant="ankle", cfg=clean.nominal_cfg).causes == ["none"]


def test_a_gap_fitted_with_the_load_leading_the_rotor_is_rejected():
    """A negative gap (the fitted column's sign says the pulley leads the rotor) is no gap: rejected."""
    base = np.array([100.0, 0.0, 0.0, 50.0, 0.0, 0.0])
    gap = GearBacklash()
    assert gap.rejection({"half_width": (1e-4, 1e-5)}, np.array([-0.5, -0.2]), base) is None
    assert "not a gap" in gap.rejection({"half_width": (1e-4, 1e-5)}, np.array([-0.5, 0.2]), base)


@pytest.mark.slow
def test_generator_d_seed_130_reads_backlash():
    """The benchmark's own case (16.6 s multisine under the PD law, a bench rig, no joint encoders)."""
    case = make_case_d(**draw_case_d(130))
    diag = diagnose(case.ident, case.valid, plant="ankle", cfg=case.nominal_cfg)
    assert diag.causes == ["backlash"], (diag.causes, diag.notes)
