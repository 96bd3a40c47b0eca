"""Generator D's findings (benchmarks/diagnosis_cases_d.py, diagD): what the diagnosis got wrong on a device
whose motors truly stick, and the rules that fixed it."""

from __future__ import annotations

import numpy as np
import pytest

from ankle_rt.diagnosis import diagnose
from ankle_rt.diagnosis.candidates import COUNTS_PER_PERIOD, Cogging
from ankle_rt.diagnosis.signals import MotorChannel, resting
from benchmarks.diagnosis_cases_d import COUNTS, draw_case_d, make_case_d


def test_resting_marks_runs_of_an_unchanged_count():
    pos = np.array([0, 0, 0, 0, 1, 1, 2, 2, 2, 2, 2, 3], dtype=float)[:, None]
    assert resting(pos, 4)[:, 0].tolist() == [True] * 4 + [False] * 2 + [True] * 5 + [False]


def test_cogging_counts_stay_within_what_the_encoder_resolves():
    """A stuck motor makes the slowest tenth of the motion zero speed, so the pass-band bound on the count
    is unbounded; the encoder's counts bound it (8 counts a period)."""
    case = make_case_d(113, ["torque_offset"], motion="steps", controller="impedance", ident_s=4, valid_s=2)
    free = MotorChannel(case.ident, 1.66, None, 0.01)
    bounded = MotorChannel(case.ident, 1.66, None, 0.01, counts_per_rev=COUNTS)
    assert free.resting.any()
    assert Cogging().count_range(free)[1] > COUNTS // COUNTS_PER_PERIOD
    assert Cogging().count_range(bounded)[1] == COUNTS // COUNTS_PER_PERIOD


@pytest.mark.slow
@pytest.mark.parametrize("seed, truth", [(113, ["torque_offset"]), (103, ["stribeck"]), (101, ["none"])])
def test_a_sticking_motor_is_not_cogging(seed, truth):
    """Generator D's motors stick (Coulomb friction solved implicitly): the holding torques of the rests
    sit at a few angles and fitted cogging at 516 077 periods per turn (113: a period below one encoder
    count), 1879 (103) and 19 085 (101). Counts bounded by the encoder and rests left out of the cogging
    regressor: no cogging."""
    case = make_case_d(**draw_case_d(seed))
    diag = diagnose(case.ident, case.valid, plant="ankle", cfg=case.nominal_cfg)
    assert diag.causes == truth, (seed, diag.causes, diag.notes)
