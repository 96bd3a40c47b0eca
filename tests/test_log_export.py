"""`ankle-rt log export`: the CSV holds every field with its unit and exactly the rows it says, and
stays readable as an interchange file; the MCAP reads back with the mcap reader with the same values
at the run's absolute time."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from ankle_rt.cli import main
from ankle_rt.daemon import run_lockstep
from ankle_rt.interchange import read_csv
from ankle_rt.log import export
from ankle_rt.log.export import MCAP_TOPIC
from ankle_rt.log.reader import read_log
from ankle_rt.log.record import FIELDS, UNITS


@pytest.fixture(scope="module")
def run_log(tmp_path_factory, _sim_cfg):
    cfg = _sim_cfg.deep_copy()
    path = tmp_path_factory.mktemp("export") / "run.arlog"
    run_lockstep(cfg, 0.8, log_path=path)
    return path


def test_csv_has_every_field_with_units_and_the_exact_row_count(run_log, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(export, "CHUNK_ROWS", 300)     # 800 rows: three chunks
    out = tmp_path / "all.csv"
    assert main(["log", "export", str(run_log), "--csv", str(out)]) == 0
    printed = capsys.readouterr().out
    log = read_log(run_log)
    with out.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    header, body = rows[0], rows[1:]
    assert len(header) == len(FIELDS) and len(body) == len(log) == 800
    assert f"wrote {len(body)} rows" in printed
    for (name, *_), column in zip(FIELDS, header):
        assert column == name or column == f"{name} [{UNITS[name]}]"
    assert "motor_vel_1 [rad/s]" in header and "period_us [µs]" in header and "state [code]" in header
    assert "t" in header and "current_cmd_1" in header          # the interchange names, plain
    for k, (name, *_) in enumerate(FIELDS):                       # every value, full precision
        values = np.array([float(r[k]) for r in body])
        assert np.array_equal(values, log.records[name].astype(float), equal_nan=True), name
    rec = read_csv(out)                                           # the project's own reader takes it
    assert len(rec) == 800 and rec.input_kind == "current" and "ankle_dp" in rec


def test_csv_of_a_run_without_references_still_reads_as_interchange(sim_cfg, tmp_path, capsys):
    class Zero:                     # an experiment's own controller: the log has no reference (NaN)
        def reset(self, est):
            pass

        def update(self, est, torque):
            torque[0] = torque[1] = 0.0

    path = tmp_path / "noref.arlog"
    run_lockstep(sim_cfg, 0.3, controller=Zero(), log_path=path)
    out = tmp_path / "noref.csv"
    assert main(["log", "export", str(path), "--csv", str(out)]) == 0
    header = out.read_text(encoding="utf-8").splitlines()[0].split(",")
    assert "ref_dp [rad]" in header and "ref_dp" not in header   # all NaN: not an interchange column
    assert len(read_csv(out)) == 300


def test_mcap_reads_back_with_the_same_values_at_absolute_time(run_log, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(export, "CHUNK_ROWS", 300)
    mcap_reader = pytest.importorskip("mcap.reader")
    out = tmp_path / "run.mcap"
    assert main(["log", "export", str(run_log), "--mcap", str(out)]) == 0
    assert "wrote 800 messages" in capsys.readouterr().out
    log = read_log(run_log)
    start_ns = round(log.meta["started_unix_s"] * 1e9)
    with out.open("rb") as handle:
        reader = mcap_reader.make_reader(handle)
        summary = reader.get_summary()
        schema = next(iter(summary.schemas.values()))
        channel = next(iter(summary.channels.values()))
        assert schema.encoding == "jsonschema" and channel.message_encoding == "json" and channel.topic == MCAP_TOPIC
        props = json.loads(schema.data)["properties"]
        assert props["motor_vel_1"]["unit"] == "rad/s"
        messages = [(m.log_time, json.loads(m.data)) for _, _, m in reader.iter_messages()]
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert len(messages) == len(log) == 800
    assert json.loads(meta["ankle_rt.log"]["rate_hz"]) == 1000
    for i, (stamp, msg) in enumerate(messages):
        rec = log.records[i]
        assert stamp == start_ns + round(float(rec["loop_time"]) * 1e9)
        for name, *_ in FIELDS:
            value = rec[name].item()
            if isinstance(value, float) and math.isnan(value):
                assert msg[name] is None, name
            else:
                assert msg[name] == value, name
        assert msg["state_name"] in ("CONFIGURED", "ACTIVE")


def test_export_needs_an_output_and_reports_a_missing_log(run_log, tmp_path, capsys):
    assert main(["log", "export", str(run_log)]) == 2
    assert main(["log", "export", str(tmp_path / "none.arlog"), "--csv", str(tmp_path / "x.csv")]) == 1
    assert "cannot read" in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()
