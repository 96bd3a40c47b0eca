"""Log rotation and retention in the writer thread: each part is a complete log, no record falls
between two parts, the configured number of files is kept, and a failed write stops logging with a
status (a fault only when logging.fault_on_error is set)."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pytest

from ankle_rt.cli import main
from ankle_rt.daemon import Daemon
from ankle_rt.log.header import HEADER_SIZE
from ankle_rt.log.reader import read_log
from ankle_rt.log.record import RECORD_SIZE
from ankle_rt.log.writer import LogWriter, Rotation, part_path
from ankle_rt.safety import Fault, State
from tests.conftest import SIM_CONFIG
from tests.daemon_helpers import run_cycles


def _values(k: int) -> tuple:
    """Record k: distinct, physically plausible values in every float field (the interchange reader
    refuses angles beyond a turn), seq = k."""
    return tuple([k * 1e-3] + [k * 1e-2] * 17 + [k, 1000.0, 10.0, 0, 1, 0, 0, 0])


def _rotated_run(first: Path, records: int) -> list[str]:
    """Write ``records`` records (``_values``) as a run rotated every 30 records; the parts' paths."""
    w = LogWriter(first, {"rate_hz": 1000}, capacity=1024, rotation=Rotation(size_bytes=HEADER_SIZE + 30 * RECORD_SIZE))
    for k in range(records):
        w.append(*_values(k))
    w.close()
    return [str(part_path(first, i)) for i in range(w.part + 1)]


def _wait_flushed(w: LogWriter, timeout_s: float = 30.0) -> None:
    """Until the writer thread has taken every record packed so far (no fixed sleep)."""
    deadline = time.monotonic() + timeout_s
    while w.flushed < w.written:
        assert time.monotonic() < deadline, "writer thread did not flush"
        time.sleep(0.002)


def _parts(first: Path) -> list[Path]:
    return sorted(p for p in first.parent.glob(f"{first.stem}*{first.suffix}"))


def test_size_rotation_keeps_every_record_and_a_header_in_each_part(tmp_path):
    first = tmp_path / "run.arlog"
    size = HEADER_SIZE + 100 * RECORD_SIZE           # 100 records per part
    w = LogWriter(first, {"rate_hz": 1000}, capacity=4096, flush_interval_s=0.005,
                  rotation=Rotation(size_bytes=size))
    for k in range(1050):
        w.append(*_values(k))
        if k % 300 == 299:
            _wait_flushed(w)                         # rotations happen inside a flush, and at its edges
    w.close()
    parts = [part_path(first, i) for i in range(w.part + 1)]
    assert w.part == 10 and _parts(first) == sorted(parts) and w.status()["state"] == "closed"
    seqs = []
    for i, p in enumerate(parts):
        log = read_log(p)
        assert p.stat().st_size <= size and log.damaged == 0 and log.torn_bytes == 0
        assert log.meta["part"] == i and log.meta["first_record"] == len(seqs) and log.meta["rate_hz"] == 1000
        seqs.extend(log.records["seq"].tolist())
    assert seqs == list(range(1050)) and w.dropped == 0


def test_age_rotation_starts_a_new_part_at_the_next_write(tmp_path):
    first = tmp_path / "aged.arlog"
    w = LogWriter(first, {}, capacity=1024, flush_interval_s=0.005, rotation=Rotation(interval_s=1e-6))
    for k in range(10):
        w.append(*_values(k))
    _wait_flushed(w)
    for k in range(10, 20):
        w.append(*_values(k))
    w.close()
    assert w.part >= 1
    seqs = [s for i in range(w.part + 1) for s in read_log(part_path(first, i)).records["seq"].tolist()]
    assert seqs == list(range(20))


def test_retention_keeps_the_newest_files_of_the_pattern_and_never_the_current(tmp_path):
    old = []
    for i in range(5):                               # earlier runs, oldest first
        p = tmp_path / f"run-2026010{i}-000000.arlog"
        p.write_bytes(b"x")
        os.utime(p, ns=(10**18 + i * 10**9, 10**18 + i * 10**9))
        old.append(p)
    other = tmp_path / "keep-me.arlog"
    other.write_bytes(b"y")
    first = tmp_path / "run-20260201-000000.arlog"
    w = LogWriter(first, {}, capacity=1024, flush_interval_s=0.005,
                  rotation=Rotation(size_bytes=HEADER_SIZE + 10 * RECORD_SIZE, keep_files=3, pattern="run-*.arlog"))
    assert [p.exists() for p in old] == [False, False, False, True, True]     # at open: 2 old + the new one
    for k in range(35):
        w.append(*_values(k))
    w.close()
    left = sorted(p.name for p in tmp_path.glob("run-*.arlog"))
    assert w.part == 3 and len(left) == 3 and part_path(first, 3).name in left and other.exists()
    assert w.status()["deleted_files"] == 6        # the 5 earlier runs and part 0


def test_retention_by_age_deletes_only_old_files(tmp_path):
    stale, fresh = tmp_path / "x.0001.arlog", tmp_path / "x.0002.arlog"
    stale.write_bytes(b"s")
    fresh.write_bytes(b"f")
    week_ago = time.time_ns() - 7 * 86400 * 10**9
    os.utime(stale, ns=(week_ago, week_ago))
    w = LogWriter(tmp_path / "x.arlog", {}, capacity=256, rotation=Rotation(keep_days=2.0))
    w.close()
    assert not stale.exists() and fresh.exists()


def test_a_full_disk_stops_logging_with_a_status(tmp_path):
    w = LogWriter(tmp_path / "full.arlog", {"rate_hz": 1000}, capacity=256, flush_interval_s=0.01)
    with open("/dev/full", "wb") as full:
        os.dup2(full.fileno(), w.fd)                 # every later write fails with ENOSPC
    for k in range(100):
        w.append(*_values(k))
    _wait_flushed(w)
    for k in range(100, 150):
        w.append(*_values(k))
    w.close()
    status = w.status()
    assert w.failed and status["state"] == "failed" and "No space left" in status["error"]
    assert w.dropped == 150 and status["records"] == 0


@pytest.mark.parametrize("fault_on_error", [False, True])
def test_daemon_status_shows_a_failed_log_and_faults_only_when_configured(sim_cfg, tmp_path, fault_on_error):
    sim_cfg["logging"]["fault_on_error"] = fault_on_error
    from ankle_rt.clock import SimClock

    d = Daemon(sim_cfg, SimClock())
    d.open_log(tmp_path / "d.arlog")
    run_cycles(d, 800)                               # active after the tare
    assert d.safety.state == State.ACTIVE and d.status()["log"]["state"] == "writing"
    with open("/dev/full", "wb") as full:
        os.dup2(full.fileno(), d.recorder.fd)
    run_cycles(d, 10)
    _wait_flushed(d.recorder)
    run_cycles(d, 10)
    status = d.status()
    d.close()
    assert status["log"]["state"] == "failed" and "No space left" in status["log"]["error"]
    if fault_on_error:
        assert status["state"] == "fault" and status["fault"] == Fault.LOG_FAILED.name.lower()
    else:
        assert status["state"] == "active"


def test_run_with_rotation_summarises_the_last_records_across_parts(tmp_path, capsys):
    cfg = tmp_path / "rot.yaml"
    cfg.write_text(f"include: [{SIM_CONFIG}]\nlogging: {{rotate_size_mb: 0.05, keep_files: 3}}\n")
    first = tmp_path / "r.arlog"
    assert main(["run", "--fast", "--config", str(cfg), "--duration", "2", "--log", str(first),
                 "--no-plot", "--json"]) == 0
    out = capsys.readouterr().out
    summary = json.loads(out[out.index("\n{") + 1:])     # after the start-up line
    parts = _parts(first)
    assert len(parts) == 3 and summary["log"] == str(parts[-1]) and summary["log_status"]["dropped"] == 0
    last, before = read_log(parts[-1]), read_log(parts[-2])
    per_part = (50_000 - HEADER_SIZE) // RECORD_SIZE                 # records per 50 kB part (194)
    assert len(last) < per_part == len(before)
    window = summary["window"]                            # the last part + the one before, of the whole run
    assert window["records"] == summary["cycles"] == len(last) + len(before) and window["total_records"] == 2000
    assert window["run_s"] == pytest.approx(1.999)
    logs = [read_log(p) for p in parts]
    total = sum(len(log) for log in logs)
    assert logs[-1].meta["first_record"] + len(logs[-1]) == 2000 and total < 2000   # the oldest were deleted
    seq = np.concatenate([log.records["seq"] for log in logs])
    assert np.all(np.diff(seq) == 1)                 # the kept parts join without a gap


def test_export_joins_the_parts_of_a_rotated_run_and_names_a_gap(tmp_path, capsys):
    parts = _rotated_run(tmp_path / "j.arlog", 100)
    out = tmp_path / "j.csv"
    assert main(["log", "export", *reversed(parts), "--csv", str(out)]) == 0     # any order
    assert "wrote 100 rows" in capsys.readouterr().out
    from ankle_rt.interchange import read_csv
    assert np.array_equal(read_csv(out)["t"], np.arange(100) * 1e-3)
    assert main(["log", "export", parts[0], parts[2], "--csv", str(out)]) == 0
    assert "30 records missing between" in capsys.readouterr().err
    other = tmp_path / "other.arlog"
    LogWriter(other, {"rate_hz": 1000}).close()
    assert main(["log", "export", parts[0], str(other), "--csv", str(out)]) == 1
    assert "parts of different runs" in capsys.readouterr().err


def test_read_tail_takes_the_rest_from_the_part_before(tmp_path):
    from ankle_rt.log.reader import read_tail

    first = tmp_path / "t.arlog"
    newest = Path(_rotated_run(first, 100)[3])         # parts of 30, 30, 30 and 10 records
    tail = read_tail(newest, 25)
    assert tail.records["seq"].tolist() == list(range(75, 100)) and tail.total_records == 100 and tail.is_tail
    assert len(read_tail(newest, 500)) == 40            # this part and the one before, no further
    part_path(first, 2).unlink()
    assert read_tail(newest, 25).records["seq"].tolist() == list(range(90, 100))


def test_export_refuses_overlapping_parts_and_an_output_that_is_an_input(tmp_path, capsys):
    parts = _rotated_run(tmp_path / "o.arlog", 60)
    out = tmp_path / "o.csv"
    assert main(["log", "export", parts[0], parts[1], parts[0], "--csv", str(out)]) == 1   # a part given twice
    assert "overlap" in capsys.readouterr().err and not out.exists()
    before = Path(parts[1]).read_bytes()
    assert main(["log", "export", *parts, "--csv", parts[1]]) == 2        # would overwrite the run log
    assert "is one of the logs" in capsys.readouterr().err
    assert Path(parts[1]).read_bytes() == before
    assert main(["log", "export", *parts, "--mcap", str(tmp_path)]) == 2
    assert f"{tmp_path} is a directory" in capsys.readouterr().err
