"""Issue 21, item 4: every valid file gets a verdict. Degenerate but valid records (gauges that read
exactly zero, motors that never move, everything zero) are diagnosed with warnings instead of stopping
on a division by zero or an empty search; a record too short for the filters is refused naming its
length before anything is filtered (a 60-row file stopped inside a Savitzky-Golay filter). Motor angles
logged coarser than the config's encoder (benchmarks/fuzz_diagnose.py, diag23) bound the cogging search by
the counts the file shows."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ankle_rt.diagnosis import diagnose
from ankle_rt.diagnosis.core import logged_counts
from ankle_rt.interchange import InterchangeError, Recording
from tests.diagnosis_cases import make_case
from tests.diagnosis_cases_b import make_case_b


@pytest.fixture(scope="module")
def case():
    return make_case(seed=7, plant="ankle", cause="none", ident_s=6.0, valid_s=3.0)


def _with(rec: Recording, **columns: float) -> Recording:
    """``rec`` with each named column replaced by a constant."""
    cols = dict(rec.columns)
    cols.update({name: np.full(len(rec), value) for name, value in columns.items()})
    return dataclasses.replace(rec, columns=cols)


def _verdict(case, ident: Recording, valid: Recording):
    diag = diagnose(ident, valid, plant=case.plant, cfg=case.nominal_cfg)
    msg = f"{case.describe()} -> {diag.causes} warnings={diag.data_warnings} notes={diag.notes}"
    assert diag.causes, msg
    assert not set(diag.causes) - {"none", "unknown"}, msg     # nothing physical named from no evidence
    return diag, msg


def test_gauges_reading_exactly_zero_get_a_verdict_and_a_warning(case):
    silent = {"sg_torque_dp": 0.0, "sg_torque_ie": 0.0}
    diag, msg = _verdict(case, _with(case.ident, **silent), _with(case.valid, **silent))
    assert any("sg_torque_dp" in w and "reads exactly zero" in w for w in diag.data_warnings), msg
    assert any("fits it exactly" in n for n in diag.notes), msg


def test_motors_that_never_move_get_a_verdict_and_a_warning(case):
    still = {"motor_pos_1": 0.0, "motor_pos_2": 0.0, "ankle_dp": 0.0, "ankle_ie": 0.0,
             "current_cmd_1": 1.0, "current_cmd_2": 1.0}
    diag, msg = _verdict(case, _with(case.ident, **still), _with(case.valid, **still))
    assert any("move in only" in w for w in diag.data_warnings), msg


@pytest.mark.parametrize("rows", [15, 60])
def test_a_record_too_short_for_the_filters_is_refused_naming_its_length(case, rows):
    """The validation record (a 60-row file's held-out quarter is 15 rows) as the identification one."""
    short = dataclasses.replace(case.valid, columns={k: v[:rows] for k, v in case.valid.columns.items()})
    with pytest.raises(InterchangeError, match=f"too short for the diagnosis: {rows} rows"):
        diagnose(case.ident, short, plant=case.plant, cfg=case.nominal_cfg)
    with pytest.raises(InterchangeError, match=f"too short for the diagnosis: {rows} rows"):
        diagnose(short, case.valid, plant=case.plant, cfg=case.nominal_cfg)


def _motors_on_lattice(rec: Recording, step: float) -> Recording:
    """``rec`` with the motor angles rounded to a lattice of ``step`` rad (a coarse encoder)."""
    cols = dict(rec.columns)
    for name in ("motor_pos_1", "motor_pos_2"):
        cols[name] = np.round(cols[name] / step) * step
    return dataclasses.replace(rec, columns=cols)


def test_the_logged_motor_counts_bound_the_configured_ones(case):
    configured = int(case.nominal_cfg["actuator"]["encoder_counts_per_rev"])
    notes: list[str] = []
    assert logged_counts(case.ident, configured, notes) == configured      # logged at the config's counts
    assert not notes
    assert logged_counts(_motors_on_lattice(case.ident, 0.01), configured, notes) == 628    # 2 pi / 0.01
    assert len(notes) == 1 and "628 counts per output revolution" in notes[0]
    analog = _with(case.ident)
    analog.columns["motor_pos_1"] = analog["motor_pos_1"] + 1e-9 * np.sin(np.arange(len(analog)))   # on no lattice
    analog.columns["motor_pos_2"] = analog["motor_pos_1"]
    assert logged_counts(analog, configured, []) == configured


def test_a_coarse_motor_encoder_is_not_read_as_cogging():
    """Generator B's effect-free walking (impedance law, jittered stamps) with its motor angles logged to
    0.01 rad: the lattice's ripple read as cogging at 623 periods per revolution (with load-dependent
    friction and unknown) while the config says 116640 counts; the logged 628 counts now bound the search."""
    case = make_case_b(7, [], "impedance", "walking", jitter=True, ident_s=6.0, valid_s=3.0)
    diag = diagnose(_motors_on_lattice(case.ident, 0.01), _motors_on_lattice(case.valid, 0.01),
                    plant="ankle", cfg=case.nominal_cfg)
    msg = f"{diag.causes} notes={diag.notes}"
    assert "cogging" not in diag.causes, msg
    assert any("lattice of 0.01 rad (628 counts" in n for n in diag.notes), msg
