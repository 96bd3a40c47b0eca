"""The run log: round trip, torn final records, kill -9 and SIGTERM of a real daemon process, and
the `ankle-rt log` / `ankle-rt run --fast` commands."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from ankle_rt.cli import main
from ankle_rt.daemon import run_lockstep
from ankle_rt.interchange import read_csv
from ankle_rt.log.reader import LogFormatError, read_log
from ankle_rt.log.record import DATA_DTYPE, RECORD_DTYPE
from ankle_rt.log.writer import HEADER_SIZE, LogWriter
from ankle_rt.safety import State
from tests.conftest import ROOT, SIM_CONFIG


def test_lockstep_log_reads_back_identically_and_ignores_a_torn_record(sim_cfg, tmp_path):
    path = tmp_path / "run.arlog"
    res = run_lockstep(sim_cfg, 0.5, log_path=path)
    log = read_log(path)
    assert log.torn_bytes == 0 and log.meta["rate_hz"] == 1000
    assert log.records.astype(DATA_DTYPE).tobytes() == res.records.astype(DATA_DTYPE).tobytes()
    with path.open("ab") as handle:          # a writer killed in the middle of a record
        handle.write(b"\x01" * (RECORD_DTYPE.itemsize - 3))
    log = read_log(path)
    assert len(log) == len(res) and log.torn_bytes == RECORD_DTYPE.itemsize - 3


def test_not_a_log_is_refused_with_the_reason(tmp_path):
    bad = tmp_path / "x.arlog"
    bad.write_bytes(b"hello world")
    with pytest.raises(LogFormatError, match="not an ankle-rt log"):
        read_log(bad)


def test_writer_thread_writes_everything_and_counts_drops(tmp_path):
    w = LogWriter(tmp_path / "w.arlog", {"rate_hz": 1000}, capacity=256, flush_interval_s=0.01)
    for k in range(1000):     # 18 float64 fields, seq, period, latency, overruns, state, fault, bits, gait phase
        w.append(*([float(k)] * 18 + [k, 0.0, 0.0, 0, 1, 0, 0, 0]))
        if k % 100 == 0:
            time.sleep(0.03)                 # let the writer catch up now and then
    w.close()
    log = read_log(tmp_path / "w.arlog")
    assert len(log) + w.dropped == 1000
    assert np.all(np.diff(log.records["seq"]) > 0)
    assert log.records["seq"][-1] == 999     # close() writes the rest


def _daemon_config(tmp_path: Path) -> Path:
    cfg = tmp_path / "daemon.yaml"
    cfg.write_text(yaml.safe_dump({"include": [str(SIM_CONFIG)], "loop": {"duration_s": 0.0},
                                   "service": {"socket_path": str(tmp_path / "ctl.sock")}}))
    return cfg


def _start_daemon(tmp_path: Path, log: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen([sys.executable, "-m", "ankle_rt.cli", "run", "--config", str(_daemon_config(tmp_path)),
                             "--log", str(log), "--no-plot"], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _wait_for_records(proc: subprocess.Popen, log: Path, n: int, timeout_s: float = 60.0) -> None:
    size = HEADER_SIZE + n * RECORD_DTYPE.itemsize
    deadline = time.monotonic() + timeout_s
    while not (log.exists() and log.stat().st_size >= size):
        if proc.poll() is not None:
            pytest.fail(f"daemon exited early: {proc.stdout.read()}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail("daemon wrote no log in time")
        time.sleep(0.05)


def test_kill_9_mid_run_leaves_a_readable_log(tmp_path):
    log = tmp_path / "killed.arlog"
    proc = _start_daemon(tmp_path, log)
    _wait_for_records(proc, log, 400)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    run = read_log(log)
    assert len(run) >= 400
    rec = run.records
    assert np.all(np.diff(rec["loop_time"]) > 0)
    # a cycle that woke late may see the next one read the same sample again (never an older one)
    assert np.all(np.diff(rec["t"]) >= 0) and np.all(np.diff(rec["seq"]) >= 0)
    assert np.mean(np.diff(rec["seq"]) > 0) > 0.9
    assert set(np.unique(run.records["state"])) <= {State.CONFIGURED, State.ACTIVE}
    assert main(["log", "info", str(log)]) == 0


def test_sigterm_stops_safe_and_flushes(tmp_path):
    log = tmp_path / "stopped.arlog"
    proc = _start_daemon(tmp_path, log)
    _wait_for_records(proc, log, 300)
    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 0, out
    run = read_log(log)
    assert run.torn_bytes == 0
    assert run.records["state"][-1] == State.SAFE
    assert run.records["current_cmd_1"][-1] == 0.0
    assert "final state SAFE" in out and str(log) in out


def test_run_fast_then_log_info_and_export(tmp_path, capsys):
    log = tmp_path / "fast.arlog"
    assert main(["run", "--fast", "--duration", "1", "--log", str(log), "--no-plot"]) == 0
    out = capsys.readouterr().out
    assert "tracking error" in out and "\n  DP " in out and "\n  IE " in out and str(log) in out
    assert main(["log", "info", str(log)]) == 0
    assert "1000 cycles" in capsys.readouterr().out
    csv = tmp_path / "out.csv"
    assert main(["log", "export", str(log), "--csv", str(csv)]) == 0
    rec = read_csv(csv)
    assert len(rec) == 1000 and rec.input_kind == "current" and "ref_dp" in rec and "ankle_dp" in rec
    assert main(["log", "info", str(tmp_path / "missing.arlog")]) == 1


def test_export_keeps_the_later_of_two_records_with_the_same_sample_time(sim_cfg):
    from ankle_rt.log.reader import interchange_columns

    rec = run_lockstep(sim_cfg, 0.2).records.copy()
    rec["t"][51] = rec["t"][50]                   # cycle 50 woke late; 51 read the same sample
    cols = interchange_columns(rec)
    assert len(cols["t"]) == len(rec) - 1
    assert np.all(np.diff(cols["t"]) > 0)
    assert cols["current_cmd_1"][50] == rec["current_cmd_1"][51]


def test_bench_loop_json_has_the_figures(capsys):
    """Smoke test of the benchmark's output format (no timing asserted)."""
    import json

    assert main(["bench", "loop", "--duration", "0.2", "--lockstep", "0.2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("period_error_p99_us", "compute_p99_us", "late_cycles", "lockstep_realtime_factor"):
        assert key in out
    assert out["cycles"] > 0 and out["lockstep_realtime_factor"] > 0


def test_bench_loop_prints_the_readme_goals(capsys):
    """The printed goals are the README's (p99 period error 100 us, compute 250 us, lockstep 30x)."""
    assert main(["bench", "loop", "--duration", "0.1", "--lockstep", "0.1"]) == 0
    out = capsys.readouterr().out
    for goal in ("goal p99 <= 100 us", "goal p99 <= 250 us", "goal >= 30x"):
        assert goal in out


def test_a_failing_disk_costs_records_not_the_loop(tmp_path):
    w = LogWriter(tmp_path / "full.arlog", {"rate_hz": 1000}, capacity=256, flush_interval_s=0.01)
    with open("/dev/full", "wb") as full:
        os.dup2(full.fileno(), w.fd)                 # every later write fails with ENOSPC
    for k in range(100):
        w.append(*([float(k)] * 18 + [k, 0.0, 0.0, 0, 1, 0, 0, 0]))
    w.close()
    assert w.dropped == 100 and "No space left" in w.error
