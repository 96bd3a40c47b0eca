"""Generator B (tests/diagnosis_cases_b.py): its independent plant agrees with the nominal model, and each
condition leaves the trace it is meant to leave in the data."""

import numpy as np
import pytest

from ankle_rt.diagnosis import diagnose
from tests.diagnosis_cases_b import CALIBRATIONS, WORDS, draw_case_b, make_case_b


def test_effect_free_data_of_the_independent_plant_fit_the_nominal_model():
    # B's own integrator and equations, no condition: the diagnosis' baseline must be adequate
    case = make_case_b(5, [], "pd", "multisine", ident_s=8.0, valid_s=4.0)
    assert case.causes == ("none",) and not case.expect_flag
    assert diagnose(case.ident, case.valid, plant="ankle", cfg=case.nominal_cfg).causes == ["none"]


@pytest.mark.parametrize("controller,motion", [("pd", "walking"), ("impedance", "multisine")])
def test_controllers_and_motions_move_both_motors_within_the_clamp(controller, motion):
    rec = make_case_b(6, [], controller, motion, ident_s=3.0, valid_s=1.0).ident
    for i in (1, 2):
        assert np.std(rec[f"motor_pos_{i}"]) > 0.05
        assert np.max(np.abs(rec[f"current_cmd_{i}"])) <= 5.0
    assert np.std(rec["sg_torque_dp"]) > 0.5


def test_conditions_leave_their_trace():
    base = make_case_b(7, [], ident_s=2.0, valid_s=1.0).ident
    offset = make_case_b(7, ["sg_offset"], ident_s=2.0, valid_s=1.0)
    shift = offset.ident["sg_torque_dp"].mean() - base["sg_torque_dp"].mean()
    assert abs(shift - offset.conditions[0]["offset"][0]) < 0.05
    clip = make_case_b(7, ["sg_clip"], ident_s=2.0, valid_s=1.0)
    sg = clip.ident["sg_torque_dp"]
    assert np.sum(np.abs(sg) == np.max(np.abs(sg))) > 10          # flat at the clip level
    jit = make_case_b(7, [], jitter=True, ident_s=2.0, valid_s=1.0).ident
    steps = np.diff(jit["t"])
    assert steps.min() < 0.00095 and steps.max() > 0.00105 and np.all(steps > 0)
    delayed = make_case_b(7, ["delay"], ident_s=2.0, valid_s=1.0)
    assert not np.allclose(delayed.ident["motor_pos_1"], base["motor_pos_1"])


def test_truth_words_and_flags():
    assert make_case_b(8, ["stiffening", "kt_error"], ident_s=1.0, valid_s=0.5).causes == ("stiffness_nonlinear",)
    case = make_case_b(8, ["kt_error"], ident_s=1.0, valid_s=0.5)
    assert case.causes == ("none",) and case.expect_flag
    specs = [draw_case_b(s) for s in range(200)]
    kinds = {k for s in specs for k in s["kinds"]}
    assert kinds == set(WORDS) | set(CALIBRATIONS)
    assert sum(len([k for k in s["kinds"] if k in WORDS]) >= 2 for s in specs) > 40
    assert not any(s["jitter"] and set(s["kinds"]) & set(CALIBRATIONS) for s in specs)


def test_cases_are_written_as_interchange_files(tmp_path):
    from ankle_rt.interchange import read_csv
    from tests.diagnosis_cases_b import write_case_b

    case = make_case_b(9, ["delay"], jitter=True, ident_s=1.0, valid_s=0.5)
    ident, valid = write_case_b(case, tmp_path)
    back = read_csv(ident)
    assert np.allclose(back["t"], case.ident["t"]) and np.allclose(back["sg_torque_ie"], case.ident["sg_torque_ie"])
    assert len(read_csv(valid)) == len(case.valid)
