"""``validate --from`` replays the ankle disturbance a simulated run's log header records (the section 7
pulse of 0.5 N m from 2 s to 3 s), so a known input is not scored as model error."""

from __future__ import annotations

import pytest

from ankle_rt.daemon import run_lockstep
from ankle_rt.identification.data import load_recording
from ankle_rt.identification.validation import recorded_controller, recorded_disturbances, validate_recording

DURATION_S = 3.5   # s: the step at 0.5 s, the disturbance from 2 s to 3 s and 0.5 s after it


@pytest.fixture(scope="module")
def section7(_sim_cfg, tmp_path_factory):
    path = tmp_path_factory.mktemp("s7") / "run.arlog"
    assert run_lockstep(_sim_cfg, DURATION_S, log_path=path).summary["fault"] == "NONE"
    return load_recording(path)


def test_the_header_records_the_simulated_disturbance(section7, _sim_cfg):
    assert recorded_disturbances(section7) == _sim_cfg["sim"]["disturbances"]
    assert _sim_cfg["sim"]["disturbances"][0]["start"] == 2.0


def test_the_replayed_disturbance_is_not_model_error(section7, _sim_cfg):
    with_pulse = validate_recording(section7, _sim_cfg, "reference", controller=recorded_controller(section7))
    ie = {c.name: c.nrmse for c in with_pulse.channels}
    assert with_pulse.worst().nrmse < 0.002 and ie["ankle_ie"] < 0.0005

    meta = section7.extra["log_meta"]
    section7.extra["log_meta"] = {**meta, "sim_disturbances": None}   # a log that does not say
    try:
        without = validate_recording(section7, _sim_cfg, "reference", controller=recorded_controller(section7))
    finally:
        section7.extra["log_meta"] = meta
    assert {c.name: c.nrmse for c in without.channels}["ankle_ie"] > 10 * ie["ankle_ie"]
