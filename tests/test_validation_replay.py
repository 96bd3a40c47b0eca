"""``validate --from`` replays a recording closed loop through the controller it was made with: a
daemon run with the section 7 step gains (kp 90, kd 5), as a run log (the header records the
controller) and exported as an interchange CSV (the --config names the controller)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from ankle_rt.cli import main
from ankle_rt.daemon import run_lockstep
from ankle_rt.identification.data import load_recording
from ankle_rt.identification.runner import with_overrides
from ankle_rt.identification.validation import DEFAULT_TOLERANCE, recorded_controller, validate_recording
from ankle_rt.interchange import write_csv

ROOT = Path(__file__).resolve().parent.parent
SIM_YAML = ROOT / "config" / "sim.yaml"
DURATION_S = 1.5   # s: tare, soft start, the 10 deg DP / 5 deg IE step at 0.5 s and its settling


@pytest.fixture(scope="module")
def recorded(_sim_cfg, tmp_path_factory):
    """A noisy lockstep daemon run of config/sim.yaml (PD with the step gains, step reference), saved as
    a run log and exported as a CSV."""
    assert _sim_cfg["controller"]["type"] == "pd" and _sim_cfg["controller"]["pd_gains"] == "step"
    assert _sim_cfg["controller"]["step_gains"] != _sim_cfg["controller"]["validation_gains"]
    assert _sim_cfg["sim"]["quantization"] and _sim_cfg["sim"]["sensor_noise"]
    out = tmp_path_factory.mktemp("replay")
    result = run_lockstep(_sim_cfg, DURATION_S, log_path=out / "run.arlog")
    assert result.summary["fault"] == "NONE"
    write_csv(out / "run.csv", result.interchange())
    return out


def _yaml(path: Path, **sections: object) -> Path:
    path.write_text(yaml.safe_dump({"include": [str(SIM_YAML)], **sections}))
    return path


def test_the_log_header_records_the_controller(recorded, _sim_cfg):
    log = load_recording(recorded / "run.arlog")
    assert recorded_controller(log) == _sim_cfg["controller"]
    assert recorded_controller(load_recording(recorded / "run.csv")) is None


@pytest.mark.parametrize("name", ["run.arlog", "run.csv"])
def test_sim_against_itself_under_the_step_gains_is_below_one_percent(recorded, _sim_cfg, name):
    rec = load_recording(recorded / name)
    controller = recorded_controller(rec) or _sim_cfg["controller"]
    comparison = validate_recording(rec, _sim_cfg, None, name, controller)
    assert comparison.drive == "reference"
    assert {c.name for c in comparison.channels} >= {"motor_pos_1", "motor_pos_2", "ankle_dp", "ankle_ie",
                                                       "current_cmd_1"}
    assert comparison.worst().nrmse < 0.01, comparison.lines()
    wrong = with_overrides(_sim_cfg, actuator={"inertia": 1.3 * _sim_cfg["actuator"]["inertia"]})
    again = validate_recording(rec, wrong, None, name, controller)
    assert not again.passed() and again.worst().nrmse > DEFAULT_TOLERANCE
    assert again.worst().nrmse > 20 * comparison.worst().nrmse


def test_cli_replays_the_log_with_its_own_gains_and_the_csv_with_the_configs(recorded, tmp_path, capsys):
    # the user's config says the validation gains: the log's header still wins, the CSV follows the config
    other = _yaml(tmp_path / "validation_gains.yaml", controller={"pd_gains": "validation"})
    assert main(["validate", "--config", str(other), "--from", str(recorded / "run.arlog"),
                 "--out", str(tmp_path / "log")]) == 0
    text = capsys.readouterr().out
    assert "kp 90 N m/rad, kd 5 N m s/rad" in text and "from the run log header" in text
    assert main(["validate", "--config", str(other), "--from", str(recorded / "run.csv"),
                 "--out", str(tmp_path / "csv_other")]) == 1
    text = capsys.readouterr().out
    assert "DISCREPANCY" in text and "kp 80 N m/rad, kd 0.3 N m s/rad" in text and "records no controller" in text
    assert main(["validate", "--config", str(SIM_YAML), "--from", str(recorded / "run.csv"),
                 "--out", str(tmp_path / "csv")]) == 0
    assert "model agrees" in capsys.readouterr().out
    wrong = _yaml(tmp_path / "wrong.yaml", actuator={"inertia": 0.0624})
    assert main(["validate", "--config", str(wrong), "--from", str(recorded / "run.arlog"),
                 "--out", str(tmp_path / "wrong")]) == 1
    assert "DISCREPANCY" in capsys.readouterr().out
