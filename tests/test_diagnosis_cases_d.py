"""Generator D itself (benchmarks/diagnosis_cases_d.py): deterministic per seed, valid interchange files the
tools accept, truth in the cause vocabulary, and the physics it claims (a true stuck state). Not the diagnosis'
score: that is benchmarks/bench_diagnose.py --generator d."""

from __future__ import annotations

import numpy as np
import pytest

from ankle_rt.interchange import read_csv
from ankle_rt.sampling import check_sampling
from benchmarks.diagnosis_cases_d import (FLAGGED, H, OUTSIDE, QUIET, VOCAB, draw_case_d, make_case_d, stick_or_slip,
                                          write_case_d)

SHORT = {"ident_s": 2.0, "valid_s": 1.0}


def short_case(seed: int):
    return make_case_d(**{**draw_case_d(seed), **SHORT})


def test_same_seed_same_case_and_other_seed_other_case():
    a, b, c = short_case(5), short_case(5), short_case(6)
    assert a.causes == b.causes and a.describe() == b.describe()
    for part in ("ident", "valid"):
        ra, rb = getattr(a, part), getattr(b, part)
        assert ra.columns.keys() == rb.columns.keys()
        for k in ra.columns:
            np.testing.assert_array_equal(ra[k], rb[k])
    assert not np.array_equal(a.ident["motor_pos_1"][:1000], c.ident["motor_pos_1"][:1000])


@pytest.mark.parametrize("seed", [0, 3, 11])
def test_cases_write_valid_interchange_files(tmp_path, seed):
    case = short_case(seed)
    paths = write_case_d(case, tmp_path)
    assert [p.name for p in paths] == [f"d{seed}_ident.csv", f"d{seed}_valid.csv"]
    for path in paths:
        rec = read_csv(path)
        check_sampling(rec, case.nominal_cfg)          # raises on what the tools refuse
        assert np.all(np.diff(rec["t"]) > 0)
        assert all(np.all(np.isfinite(v)) for v in rec.columns.values())
        assert {"t", "motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2", "sg_torque_dp",
                "sg_torque_ie"} <= set(rec.columns)


def test_truth_uses_the_vocabulary_and_the_mix_covers_every_kind():
    """Over 300 drawn specs: truth words from the vocabulary, `unknown` exactly when an effect is outside it,
    `none` exactly when no effect is, a flag expected exactly for the calibration / sensor conditions; every
    effect and condition kind is drawn, walking and both controllers too."""
    words = VOCAB | {"none", "unknown"}
    kinds, motions, controllers = set(), set(), set()
    for seed in range(300):
        spec = draw_case_d(seed)
        kinds |= set(spec["effects"]) | set(spec["conditions"])
        motions.add(spec["motion"])
        controllers.add(spec["controller"])
        assert set(spec["effects"]) <= VOCAB | OUTSIDE
        assert set(spec["conditions"]) <= FLAGGED | QUIET
    assert kinds == VOCAB | OUTSIDE | FLAGGED | QUIET
    assert motions == {"multisine", "chirp", "steps", "walking"} and controllers == {"pd", "impedance"}
    for seed in range(40, 52):
        spec = draw_case_d(seed)
        case = make_case_d(**{**spec, **SHORT})
        assert set(case.causes) <= words
        assert ("unknown" in case.causes) == any(e in OUTSIDE for e in spec["effects"])
        assert (case.causes == ("none",)) == (not spec["effects"])
        assert case.expect_flag == any(c in FLAGGED for c in spec["conditions"])


def test_coulomb_friction_has_a_true_stuck_state():
    """A motor at rest under a torque below its static level stays exactly at rest (no creep, as a tanh
    friction would give); above it, and when sliding, friction takes exactly its level's impulse."""
    inertia, level = 0.048, 0.28
    for torque in (0.0, 0.1, -0.27, 0.28):
        assert stick_or_slip(0.0 + H * torque / inertia, level, inertia) == 0.0
    assert stick_or_slip(H * 0.5 / inertia, level, inertia) == pytest.approx(H * 0.22 / inertia)
    assert stick_or_slip(-1.0, level, inertia) == pytest.approx(-1.0 + H * level / inertia)
