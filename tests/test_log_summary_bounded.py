"""The end-of-run and `ankle-rt log info` summaries read only the most recent records of a long run
(bounded memory and time at stop), say so, and are unchanged for a run shorter than the bound."""

from __future__ import annotations

import json

import numpy as np
import pytest

import ankle_rt.log.summary as log_summary
from ankle_rt.cli import main
from ankle_rt.daemon import run_lockstep
from ankle_rt.log.reader import read_log
from ankle_rt.log.record import RECORD_DTYPE
from ankle_rt.log.summary import summarize, summarize_log


@pytest.fixture(scope="module")
def long_log(tmp_path_factory, _sim_cfg):
    """A 1.5 s lockstep run (1500 records) with a torn final record: "long" once the bound is 700."""
    path = tmp_path_factory.mktemp("bounded") / "run.arlog"
    run_lockstep(_sim_cfg, 1.5, log_path=path)
    with path.open("ab") as handle:
        handle.write(b"\x01" * (RECORD_DTYPE.itemsize - 5))
    return path


def test_read_log_last_reads_only_the_tail(long_log):
    whole = read_log(long_log)
    tail = read_log(long_log, last=300)
    assert whole.total_records == len(whole) and not whole.is_tail
    assert len(tail) == 300 and tail.total_records == len(whole) and tail.is_tail
    assert tail.records.tobytes() == whole.records[-300:].tobytes()
    assert tail.torn_bytes == whole.torn_bytes == RECORD_DTYPE.itemsize - 5
    assert tail.first_t == whole.records["t"][0]
    assert read_log(long_log, last=10 * len(whole)).records.tobytes() == whole.records.tobytes()


def test_log_info_summarises_the_tail_of_a_long_run_and_says_so(long_log, monkeypatch, capsys):
    whole = read_log(long_log)
    monkeypatch.setattr(log_summary, "SUMMARY_MAX_RECORDS", 700)   # > SETTLE_S: settled errors exist
    assert main(["log", "info", "--json", str(long_log)]) == 0
    s = json.loads(capsys.readouterr().out)
    expected = summarize(whole.records[-700:], whole.meta)
    assert s["cycles"] == 700 and not np.isnan(s["tracking_error"]["DP"]["settled_mean_abs_deg"])
    for key in ("duration_s", "tracking_error", "peak_current_a", "rms_current_a", "loop"):
        np.testing.assert_equal(s[key], expected[key])
    run_s = float(whole.records["t"][-1] - whole.records["t"][0])
    assert s["window"] == {"records": 700, "total_records": len(whole), "run_s": run_s}
    assert main(["log", "info", str(long_log)]) == 0
    text = capsys.readouterr().out
    assert f"the last 700 of {len(whole)} records" in text and f"of a {run_s:.1f} s run" in text


def test_short_log_summary_is_the_whole_run_summary(long_log, capsys):
    whole = read_log(long_log)
    assert len(whole) < log_summary.SUMMARY_MAX_RECORDS
    s = summarize_log(read_log(long_log, last=log_summary.SUMMARY_MAX_RECORDS))
    np.testing.assert_equal(s, summarize(whole.records, whole.meta))
    assert "window" not in s
    assert main(["log", "info", str(long_log)]) == 0
    assert "summary of the last" not in capsys.readouterr().out


def test_run_prints_the_bounded_summary_when_the_run_is_longer(tmp_path, monkeypatch, capsys):
    log = tmp_path / "fast.arlog"
    monkeypatch.setattr(log_summary, "SUMMARY_MAX_RECORDS", 200)
    assert main(["run", "--fast", "--duration", "0.6", "--log", str(log), "--no-plot", "--json"]) == 0
    out = capsys.readouterr().out
    s = json.loads(out[out.index("\n{") + 1:])      # after the start line
    whole = read_log(log)
    assert s["window"]["records"] == 200 and s["window"]["total_records"] == len(whole) == 600
    assert s["cycles"] == 200 and s["loop_stats"]["cycles"] == 600   # whole run: the live statistics
    assert np.isclose(s["duration_s"], whole.records["t"][-1] - whole.records["t"][-200])
