"""Model validation (issue 5, the paper's section 4): the checks on the simulator against the
noise-free model, a deliberately wrong inertia, recorded files, and bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from ankle_rt.cli import main
from ankle_rt.identification.runner import with_overrides
from ankle_rt.identification.signals import IdentificationError
from ankle_rt.identification.validation import DEFAULT_TOLERANCE, run_checks, validate_recording
from ankle_rt.interchange import Recording, write_csv

ROOT = Path(__file__).resolve().parent.parent
SIM_YAML = ROOT / "config" / "sim.yaml"


@pytest.fixture(scope="module")
def checks(_sim_cfg):
    assert _sim_cfg["sim"]["quantization"] and _sim_cfg["sim"]["sensor_noise"]   # the "device" is noisy
    return run_checks(_sim_cfg, _sim_cfg, ("step", "sine"), frequencies=(1.0,))


def test_sim_against_itself_is_below_one_percent(checks):
    step, sine = checks
    assert step.drive == "input" and sine.drive == "reference"
    assert {c.name for c in step.channels} >= {"motor_pos_1", "motor_speed_1"}
    assert {c.name for c in sine.channels} >= {"motor_pos_1", "motor_pos_2", "ankle_ie", "current_cmd_1"}
    for comparison in checks:
        assert comparison.passed()
        assert all(c.nrmse < 0.01 for c in comparison.channels), comparison.lines()
    # the sine really tracked: the IE joint angle swings by about the commanded +-10 deg
    assert np.ptp(sine.measured["ankle_ie"]) == pytest.approx(np.radians(20.0), rel=0.1)


def test_wrong_inertia_is_a_clear_discrepancy(checks, _sim_cfg):
    wrong = with_overrides(_sim_cfg, actuator={"inertia": 1.3 * _sim_cfg["actuator"]["inertia"]})
    step_model = with_overrides(wrong, sim={"cables": False})
    for comparison, model in zip(checks, (step_model, wrong)):
        again = validate_recording(comparison.measured, model, comparison.drive)
        assert not again.passed()
        assert again.worst().nrmse > 2 * DEFAULT_TOLERANCE
        assert again.worst().nrmse > 20 * comparison.worst().nrmse


def test_cli_validates_a_recorded_file_and_exits_1_on_discrepancy(checks, tmp_path, capsys):
    data = tmp_path / "sine.csv"
    write_csv(data, checks[1].measured.columns)
    # a CSV carries no controller: the config names the one the Fig. 7 run used (the validation gains)
    ran = {"controller": {"pd_gains": "validation"}}
    config = tmp_path / "validation_gains.yaml"
    config.write_text(yaml.safe_dump({"include": [str(SIM_YAML)], **ran}))
    assert main(["validate", "--config", str(config), "--from", str(data), "--out", str(tmp_path / "ok")]) == 0
    assert "model agrees" in capsys.readouterr().out
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text(yaml.safe_dump({"include": [str(SIM_YAML)], "actuator": {"inertia": 0.0624}, **ran}))
    assert main(["validate", "--config", str(wrong), "--from", str(data), "--out", str(tmp_path / "bad")]) == 1
    text = capsys.readouterr().out
    assert "DISCREPANCY" in text and "current_cmd_1" in text
    assert (tmp_path / "bad" / "validate_1.png").exists()


def test_reference_drive_needs_the_reference_columns(checks, _sim_cfg):
    cols = {k: v for k, v in checks[0].measured.columns.items() if not k.startswith("ref_")}
    with pytest.raises(IdentificationError, match="ref_dp"):
        validate_recording(Recording(cols, "steps.csv"), _sim_cfg, "reference")


def test_sample_period_must_match_the_config(checks, _sim_cfg):
    rec = checks[0].measured
    slow = Recording({**rec.columns, "t": 2.0 * rec["t"]}, "slow.csv")
    with pytest.raises(IdentificationError, match="column 't'"):
        validate_recording(slow, _sim_cfg, "input")


def test_cli_bad_recording_names_the_column(checks, tmp_path, capsys):
    cols = {k: v for k, v in checks[1].measured.columns.items() if k != "t"}
    data = tmp_path / "no_time.csv"
    write_csv(data, cols)
    assert main(["validate", "--config", str(SIM_YAML), "--from", str(data), "--out", str(tmp_path)]) == 2
    assert "column 't'" in capsys.readouterr().err
