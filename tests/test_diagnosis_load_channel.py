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
from ankle_rt.diagnosis.core import geometry_of
from ankle_rt.diagnosis.signals import LoadChannel
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
