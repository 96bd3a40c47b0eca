"""The load channel (diag21i): a record without joint angles whose foot rests on a linear load (a bench rig)
still shows a gap between a motor's rotor and its pulley (gear backlash), from the gauges' spring law of
the motor angles (ankle_rt.diagnosis.signals.LoadChannel, candidates.GearBacklash)."""

from __future__ import annotations

import numpy as np
import pytest

from ankle_rt.diagnosis import diagnose
from ankle_rt.diagnosis.candidates import GearBacklash
from ankle_rt.diagnosis.core import geometry_of
from ankle_rt.diagnosis.signals import LoadChannel
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
