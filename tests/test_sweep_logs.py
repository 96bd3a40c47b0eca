"""ankle-rt diagnose --batch: one row per log of a folder, the re-fitted friction follows the device."""

from __future__ import annotations

import json
import re

import pytest
import yaml

from ankle_rt.cli import main
from ankle_rt.daemon import run_lockstep
from tests.conftest import SIM_CONFIG


def _log(sim_cfg, path, coulomb):
    cfg = sim_cfg.deep_copy()
    cfg["actuator"]["coulomb"] = coulomb
    cfg["reference"]["profile"] = "chirp"
    cfg["reference"]["chirp"] = {"amplitude_dp": 0.09, "amplitude_ie": 0.05, "f0_hz": 0.2, "f1_hz": 3.0,
                                 "duration_s": 6.0, "start_s": 0.3}
    path.parent.mkdir(parents=True, exist_ok=True)
    run_lockstep(cfg, 6.0, log_path=path)


def test_diagnose_batch_gives_a_row_per_log_and_tracks_friction_wear(sim_cfg, tmp_path, capsys):
    pytest.importorskip("scipy", reason="diagnose needs the analysis extra")
    logs = tmp_path / "logs"
    _log(sim_cfg, logs / "left" / "day1.arlog", 0.28)
    _log(sim_cfg, logs / "left" / "day2.arlog", 0.36)     # the cables wore: friction up
    (logs / "right").mkdir()
    (logs / "right" / "broken.csv").write_text("not,a,recording\n")
    config = tmp_path / "run.yaml"
    config.write_text(yaml.safe_dump({"include": [str(SIM_CONFIG)]}))
    out = tmp_path / "report"
    assert main(["diagnose", "--batch", str(logs), "--config", str(config), "--report", str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    rows = result["rows"]
    assert [r["device"] for r in rows] == ["left", "left", "right"]
    day1, day2, broken = rows
    assert broken["cause"] == "error" and "broken.csv" in broken["error"]
    for row, kc in ((day1, 0.28), (day2, 0.36)):
        assert row["cause"] != "error"
        for motor in (1, 2):
            assert row[f"motor.coulomb.{motor}"] == pytest.approx(kc, rel=0.05)
    assert (out / "results.parquet").exists() or (out / "results.csv").exists()


def test_diagnose_batch_row_carries_the_data_warnings_of_a_poor_log(sim_cfg, tmp_path, capsys):
    """A short step run cannot pin the baseline down: its row says so instead of only trending numbers."""
    pytest.importorskip("scipy", reason="diagnose needs the analysis extra")
    logs = tmp_path / "logs"
    logs.mkdir()
    run_lockstep(sim_cfg.deep_copy(), 1.5, log_path=logs / "step.arlog")
    assert main(["diagnose", "--batch", str(logs), "--config", str(SIM_CONFIG), "--report", str(tmp_path / "r")]) == 0
    printed = capsys.readouterr().out
    assert "data warnings" in printed
    assert main(["diagnose", "--batch", str(logs), "--config", str(SIM_CONFIG), "--report", str(tmp_path / "r"),
                 "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)["rows"]
    assert row["cause"] != "error" and row["data_warnings"]


def test_diagnose_batch_refuses_a_missing_folder(tmp_path, capsys):
    assert main(["diagnose", "--batch", str(tmp_path / "nope")]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_identify_batch_gives_a_row_per_session(tmp_path, capsys):
    pytest.importorskip("scipy", reason="identification needs the analysis extra")
    sessions = tmp_path / "sessions"
    for name, kc in (("monday", 0.28), ("friday", 0.34)):
        cfg = tmp_path / f"{name}.yaml"
        cfg.write_text(yaml.safe_dump({"include": [str(SIM_CONFIG)], "actuator": {"coulomb": kc}}))
        assert main(["identify", "viscous", "--config", str(cfg), "--out", str(sessions / "unit-a" / name),
                     "--repeats", "1"]) == 0
    (sessions / "unit-b" / "empty").mkdir(parents=True)      # no recordings: not a session
    capsys.readouterr()
    out = tmp_path / "trends"
    assert main(["identify", "viscous", "--batch", str(sessions), "--config", str(SIM_CONFIG), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    lines = [line for line in text.splitlines() if "identified" in line]
    assert len(lines) == 2 and all(line.startswith("unit-a") for line in lines)
    by_session = {line.split()[2].rstrip(":"): line for line in lines}
    for session, kc in (("monday", 0.28), ("friday", 0.34)):
        fitted = float(re.search(r"actuator\.coulomb ([0-9.]+)", by_session[session]).group(1))
        assert fitted == pytest.approx(kc, rel=0.03)
    assert (out / "results.parquet").exists() or (out / "results.csv").exists()
