"""Generator C's findings (benchmarks/diagnosis_cases_c.py, issue 21): a friction transition sharper than
the config's assumed smoothing, and the named set measured jointly against the catch-all."""

from __future__ import annotations

import numpy as np
import pytest

from ankle_rt.diagnosis import diagnose
from ankle_rt.diagnosis.core import folded_coulomb
from benchmarks.diagnosis_cases_c import PlantC, make_case_c


def test_folded_coulomb_keeps_level_and_slope_at_rest():
    """Two Coulomb columns folded into the simulator's one tanh: the same level and the same slope at rest,
    the width bounded to the two columns'; a zero sharp part leaves the config's smoothing."""
    v_eps = 0.01
    level, width = folded_coulomb(0.2, 0.08, v_eps)
    assert level == pytest.approx(0.28)
    assert level / width == pytest.approx(0.2 / v_eps + 4.0 * 0.08 / v_eps)
    assert folded_coulomb(0.28, 0.0, v_eps) == (pytest.approx(0.28), pytest.approx(v_eps))
    assert v_eps / 4 <= folded_coulomb(0.01, 0.5, v_eps)[1] < v_eps


@pytest.mark.slow
@pytest.mark.parametrize("seed, effects", [(113, ["delay"]), (119, [])])
def test_sharper_coulomb_transition_is_not_a_stribeck_effect(seed, effects):
    """A device whose Coulomb friction turns sharper (v_eps 0.0057 / 0.0045 rad/s) than the config's assumed
    0.01: the baseline's second Coulomb column takes it, so no Stribeck term at its grid edge is named
    (before: delay + stribeck, stribeck), and the written smoothing velocity is the sharper one."""
    true_veps = PlantC(np.random.default_rng([seed, 7]), []).veps
    case = make_case_c(seed, effects, motion="multisine", ident_s=12, valid_s=6)
    diag = diagnose(case.ident, case.valid, plant="ankle", cfg=case.nominal_cfg)
    assert diag.causes == (effects or ["none"]), (seed, diag.causes, diag.notes)
    refit = diag.actuator_refit
    assert 0.4 * true_veps < refit["friction_smoothing_velocity"] < 0.01
    assert refit["coulomb"] == pytest.approx(np.mean(PlantC(np.random.default_rng([seed, 7]), []).kc), rel=0.1)
    assert all(v > 0.0 for v in diag.baseline["motor"]["coulomb_sharp"]["value"])     # sharper than configured
