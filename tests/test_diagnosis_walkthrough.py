"""The README's diagnosis walkthrough, command by command: the daemon on the simulator with a hidden
effect ("truth" config) records a run, the run is exported, `diagnose` names the effect, and the
extended config is simulated again and the gain printed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ankle_rt.cli import main
from ankle_rt.interchange import read_csv
from tests.diagnosis_cases import README_RUN_YAML, SIM_CONFIG

pytestmark = pytest.mark.slow   # the README walkthrough, ~60 s on a busy 2-core VM

TRUTH_YAML = """\
include: [run.yaml]
sim:
  effects:
    - {type: delay, delay: 0.006}     # the hidden effect: 6 ms actuation latency
"""


def _position_nrmse(sim_csv, measured) -> float:
    sim = read_csv(sim_csv)
    cols = ("motor_pos_1", "motor_pos_2", "ankle_dp", "ankle_ie")
    return float(np.mean([np.sqrt(np.mean((sim[c] - measured[c]) ** 2)) / np.std(measured[c]) for c in cols]))


def test_readme_walkthrough(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "run.yaml").write_text(README_RUN_YAML)
    (tmp_path / "truth.yaml").write_text(TRUTH_YAML)

    # 1. the "device": the daemon on the simulator with the hidden effect records a run
    assert main(["run", "--fast", "--config", "truth.yaml", "--log", "run.log", "--no-plot"]) == 0
    # 2. export it to the interchange CSV
    assert main(["log", "export", "run.log", "--csv", "run.csv"]) == 0
    # 3. diagnose against the nominal model: names the effect, writes the extended config
    capsys.readouterr()
    assert main(["diagnose", "run.csv", "--config", "run.yaml", "--json", "--write-model", "extended.yaml",
                 "--report", "report"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["cause"] == "delay"
    assert abs(out["parameters"]["delay"]["value"] - 0.006) < 0.0006
    assert out["gain"] > 3.0
    assert out["closed_loop"]["gain"] > 3.0       # free-run positions, re-simulated through run_lockstep
    assert (tmp_path / "report" / "closed_loop.png").exists()
    # the daemon's log is accepted as it is, too
    assert main(["diagnose", "run.log", "--config", "run.yaml", "--json", "--no-closed-loop"]) == 0
    assert json.loads(capsys.readouterr().out)["cause"] == "delay"

    # 4. the extended config simulated again: its positions follow the recorded run far better
    measured = read_csv("run.csv")
    for name in ("run", "extended"):
        assert main(["run", "--fast", "--config", f"{name}.yaml", "--log", f"{name}-sim.log", "--no-plot"]) == 0
        assert main(["log", "export", f"{name}-sim.log", "--csv", f"{name}-sim.csv"]) == 0
    before = _position_nrmse("run-sim.csv", measured)
    after = _position_nrmse("extended-sim.csv", measured)
    print(f"free-run position NRMSE: nominal {before:.4f}, extended {after:.4f}, gain {before / after:.1f}x")
    assert after < before / 3.0


def test_write_model_refuses_an_input_a_directory_or_a_missing_folder_before_diagnosing(tmp_path, capsys):
    import os

    pytest.importorskip("scipy")
    data = tmp_path / "run.arlog"
    data.write_bytes(b"not read: the output is checked first")
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)                       # opening it for writing would wait for a reader
    for out, reason in ((data, "is one of the input files"), (tmp_path, "not a regular file"),
                        (fifo, "not a regular file"), (tmp_path / "no" / "m.yaml", "no such directory")):
        args = ["diagnose", str(data), "--plant", "ankle", "--config", str(SIM_CONFIG), "--write-model", str(out)]
        assert main(args) == 2
        assert reason in capsys.readouterr().err
    assert data.read_bytes() == b"not read: the output is checked first"
    for args in (["diagnose", str(data)], ["diagnose", "--batch", str(tmp_path)]):   # --report on a file
        assert main([*args, "--report", str(data)]) == 2
        assert "is not a directory" in capsys.readouterr().err
