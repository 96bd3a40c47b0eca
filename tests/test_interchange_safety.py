"""Issue 10 item 6: bad interchange files get an InterchangeError naming the problem (never a
traceback), and diagnose / validate check sampling and units against the config before fitting."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ankle_rt.cli import main
from ankle_rt.daemon import run_lockstep
from ankle_rt.identification.data import load_recording
from ankle_rt.interchange import InterchangeError, read_csv, write_csv
from tests.conftest import SIM_CONFIG


@pytest.fixture(scope="module")
def columns(_sim_cfg):
    """One second of the shipped sim experiment as interchange columns."""
    return {k: np.asarray(v, dtype=float) for k, v in run_lockstep(_sim_cfg, 1.0).interchange().items()}


def csv_of(tmp_path, columns, name="rec.csv", **changes):
    cols = {**columns, **changes}
    path = tmp_path / name
    write_csv(path, cols)
    return path


def refused(capsys, *argv) -> str:
    assert main(list(argv)) == 2
    return capsys.readouterr().err


def test_good_recording_loads_against_the_config(tmp_path, columns, _sim_cfg):
    rec = load_recording(csv_of(tmp_path, columns), cfg=_sim_cfg)
    assert len(rec) == len(columns["t"]) and rec.extra["warnings"] == []


def test_binary_file_is_refused_by_name(tmp_path, capsys):
    path = tmp_path / "rec.csv"
    path.write_bytes(b"t,motor_pos_1\n\x00\x01\x02\xff\xfe" * 100)
    assert "binary data, not text" in refused(capsys, "validate", "--config", str(SIM_CONFIG), "--from", str(path))
    path.write_bytes(b"t,motor_pos_1,current_cmd_1\n0,0,\xff\xfe\n")
    with pytest.raises(InterchangeError, match="not UTF-8 text"):
        read_csv(path)


def test_a_utf8_bom_is_accepted(tmp_path, columns):
    path = csv_of(tmp_path, columns)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    assert len(read_csv(path)) == len(columns["t"])


@pytest.mark.parametrize("header,says", [
    ("t;motor_pos_1;current_cmd_1", "separated by commas"),
    ("# logged on the bench\nt,motor_pos_1,current_cmd_1", "the header must be the first line"),
    ("t [s],motor_pos_1 [rad],current_cmd_1 [A]", "a name carries no unit"),
    ("tick,pos,i", "the header is 'tick', 'pos', 'i'"),
    ("Time,motor_pos_1,current_cmd_1", "the time column is named 't'"),
])
def test_a_header_without_the_time_column_says_what_was_read(tmp_path, header, says):
    sep = ";" if ";" in header else ","
    path = tmp_path / "odd.csv"
    path.write_text(header + "\n" + "\n".join(sep.join(["0.00" + str(i), "0", "0"]) for i in range(1, 4)) + "\n")
    with pytest.raises(InterchangeError, match="required column missing") as err:
        read_csv(path)
    assert says in str(err.value)
    assert ("carries no unit" in str(err.value)) == ("[" in header)


def test_a_clock_stamp_written_with_too_few_digits_is_named(tmp_path):
    path = tmp_path / "epoch.csv"
    rows = [f"{1.7e9 + 1e-3 * i:.9g},0,0" for i in range(5)]
    path.write_text("t,motor_pos_1,current_cmd_1\n" + "\n".join(rows) + "\n")
    with pytest.raises(InterchangeError, match="time does not increase.*too few digits"):
        read_csv(path)


def test_rows_with_extra_cells_are_refused(tmp_path, columns):
    path = csv_of(tmp_path, columns)
    lines = path.read_text().splitlines()
    lines[5] += ",7"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InterchangeError, match=r"row 5 \(line 6\): row has \d+ cells, header has"):
        read_csv(path)


@pytest.mark.parametrize("factor", [1e300, 1.7e308, -1.7e308])
def test_absurd_magnitudes_are_refused_before_any_fit(tmp_path, columns, capsys, factor):
    path = csv_of(tmp_path, columns, motor_pos_1=np.clip(columns["motor_pos_1"] * factor, -1.7e308, 1.7e308))
    err = refused(capsys, "validate", "--config", str(SIM_CONFIG), "--from", str(path))
    assert "column 'motor_pos_1'" in err and "implausible value" in err and "Traceback" not in err


def test_time_in_ms_is_refused_naming_the_period(tmp_path, columns, capsys, _sim_cfg):
    path = csv_of(tmp_path, columns, t=columns["t"] * 1000.0)
    with pytest.raises(InterchangeError, match=r"column 't'.*time in ms rather than s"):
        load_recording(path, cfg=_sim_cfg)
    with pytest.raises(InterchangeError, match=r"column 't'.*time in ms rather than s"):
        load_recording(path)                           # even without a config: slower than 10 Hz
    assert "time in ms" in refused(capsys, "diagnose", str(path), "--config", str(SIM_CONFIG))


def test_angles_in_degrees_are_refused_against_the_config(tmp_path, columns, capsys, _sim_cfg):
    deg = {k: np.degrees(columns[k]) for k in ("motor_pos_1", "motor_pos_2", "ankle_dp", "ankle_ie", "ref_dp", "ref_ie")
           if k in columns}
    path = csv_of(tmp_path, columns, **deg)
    with pytest.raises(InterchangeError, match=r"degrees .*rather than rad"):
        load_recording(path, cfg=_sim_cfg)
    assert "rather than rad" in refused(capsys, "diagnose", str(path), "--config", str(SIM_CONFIG))


def test_currents_in_ma_are_refused_against_the_config(tmp_path, columns, _sim_cfg):
    path = csv_of(tmp_path, columns, current_cmd_1=columns["current_cmd_1"] * 1000.0)
    with pytest.raises(InterchangeError, match=r"current_cmd_1.*mA rather than A"):
        load_recording(path, cfg=_sim_cfg)


def test_a_time_gap_is_refused(tmp_path, columns, capsys):
    t = columns["t"].copy()
    t[500:] += 0.4                                     # the logger stalled 400 ms
    path = csv_of(tmp_path, columns, t=t)
    err = refused(capsys, "validate", "--config", str(SIM_CONFIG), "--from", str(path))
    assert "column 't'" in err and "time gap of 0.401 s" in err and "row 501 (line 502)" in err   # t[500] is data row 501


def test_cycles_an_overrunning_loop_dropped_are_masked_by_diagnose_not_refused(tmp_path, capsys, _sim_cfg):
    """A loop on a busy computer skips cycles: its log has gaps of a few periods, here 6 ms ones in the step's fastest
    motion and after it. `diagnose` masks around them (its screening) and gives a verdict naming the gaps; the
    speed check divides by each step's own time, so the motion across a gap is not "angles in degrees"; `validate`
    (which replays the record cycle by cycle) still refuses a gap."""
    columns = {k: np.asarray(v, dtype=float) for k, v in run_lockstep(_sim_cfg, 4.0).interchange().items()}
    speed = np.abs(np.diff(columns["motor_pos_1"])) / np.diff(columns["t"])
    fast = int(np.argmax(speed))
    keep = np.ones(len(columns["t"]), dtype=bool)
    for start in (fast - 2, fast + 150, fast + 300):
        keep[start:start + 5] = False
    assert speed[fast] * 6 > 1.5 * _sim_cfg["safety"]["max_motor_speed_rad_s"]   # over the bound at the median period
    path = csv_of(tmp_path, {k: v[keep] for k, v in columns.items()})
    assert main(["diagnose", str(path), "--config", str(SIM_CONFIG), "--json", "--no-closed-loop"]) == 0
    out = capsys.readouterr()
    assert json.loads(out.out)["cause"] and "3 time gap(s) (dropped samples), the longest 6 ms" in out.out + out.err
    err = refused(capsys, "validate", "--config", str(SIM_CONFIG), "--from", str(path))
    assert "column 't'" in err and "samples are missing" in err


def test_a_clocks_absolute_seconds_are_counted_from_the_first_sample(tmp_path, columns, _sim_cfg):
    """UNIX seconds in `t` (a logger stamping with the wall clock) are seconds that increase, as the format asks:
    read, counted from the first sample with a warning saying so, and checked as any record; the same clock's
    milliseconds are still refused."""
    path = tmp_path / "epoch.csv"
    write_csv(path, columns)
    lines = path.read_text().splitlines()
    col = lines[0].split(",").index("t")
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:
        row[col] = f"{1764425000.0 + float(row[col]):.6f}"
    path.write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    rec = load_recording(path, cfg=_sim_cfg)
    assert rec["t"][0] == 0.0 and np.max(np.abs(rec["t"] - columns["t"])) < 1e-6
    assert len(rec.extra["warnings"]) == 1 and "start at 1764425000 s" in rec.extra["warnings"][0]
    for row in rows:
        row[col] = f"{1e3 * float(row[col]):.3f}"
    path.write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    with pytest.raises(InterchangeError, match=r"column 't'.*implausible value .*time in ms rather than s"):
        load_recording(path, cfg=_sim_cfg)


def test_time_stamps_in_pairs_are_refused_as_bunched_not_as_a_gap(tmp_path, columns, capsys):
    """Every second stamp 1 us after the one before (a logger writing each sample's time twice): the median step
    is 1 us, so every other step looked like a gap of ~1000 periods ("samples are missing"); it is named."""
    t = columns["t"].copy()
    t[1::2] = t[0:-1:2] + 1e-6
    path = csv_of(tmp_path, columns, t=t)
    err = refused(capsys, "diagnose", str(path), "--config", str(SIM_CONFIG))
    assert "column 't'" in err and "bunches: 50 % of the steps" in err and "missing" not in err


def test_an_irregular_time_base_is_a_warning(tmp_path, columns, _sim_cfg):
    t = columns["t"].copy()
    rng = np.random.default_rng(1)
    t += rng.uniform(-0.0003, 0.0003, len(t)) * (np.arange(len(t)) % 3 == 0)
    path = csv_of(tmp_path, columns, t=np.maximum.accumulate(t + np.arange(len(t)) * 1e-9))
    rec = load_recording(path, cfg=_sim_cfg)
    assert any("irregular time base" in w for w in rec.extra["warnings"])


def test_a_fifo_or_device_is_refused_without_blocking(tmp_path):
    import os
    fifo = tmp_path / "rec.csv"
    os.mkfifo(fifo)
    with pytest.raises(InterchangeError, match=r"not a regular file \(a FIFO\)"):
        load_recording(fifo)
    with pytest.raises(InterchangeError, match=r"not a regular file \(a character device\)"):
        read_csv("/dev/zero")


def test_non_finite_cells_name_column_and_row(tmp_path, columns):
    for bad in ("nan", "inf", "-1e999"):
        path = tmp_path / "rec.csv"
        path.write_text(f"t,motor_pos_1,current_cmd_1\n0,0,0\n0.001,{bad},0\n")
        with pytest.raises(InterchangeError, match=r"column 'motor_pos_1', row 2.*not a finite number"):
            read_csv(path)
    assert math.isfinite(columns["t"][-1])
