"""Run log integrity: a flipped bit costs at most the record it hits, a damaged header is read from
its copy, impossible values (bad enum bytes, a NaN time) are counted instead of crashing or taking an
intact neighbour along, old format-1 logs still read, and a seeded fuzz of 10^4 mutated logs never
raises anything but LogFormatError."""

from __future__ import annotations

import json
import os
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from ankle_rt.cli import main
from ankle_rt.daemon import run_lockstep
from ankle_rt.interchange import read_csv
from ankle_rt.log.export import csv_columns
from ankle_rt.log.header import BLOCK_SIZE, HEADER_SIZE, MAGIC_V1, V1_HEADER_SIZE, LogFormatError
from ankle_rt.log.reader import read_log
from ankle_rt.log.record import DATA_DTYPE, DATA_STRUCT, FIELDS, RECORD_DTYPE, RECORD_SIZE
from ankle_rt.log.summary import format_summary, summarize_log
from tests.log_fuzz import fuzz_logs, scratch_dir

N_RECORDS = 300


@pytest.fixture(scope="module")
def clean(tmp_path_factory, _sim_cfg) -> tuple[bytes, np.ndarray]:
    """A 0.3 s lockstep run's log bytes and its records' data (DATA_DTYPE)."""
    path = tmp_path_factory.mktemp("integrity") / "run.arlog"
    res = run_lockstep(_sim_cfg, N_RECORDS * 1e-3 - 1e-4, log_path=path)
    assert len(res) == N_RECORDS
    return path.read_bytes(), res.records.astype(DATA_DTYPE)


def _write(tmp_path: Path, data: bytes | bytearray, name: str = "m.arlog") -> Path:
    path = tmp_path / name
    path.write_bytes(bytes(data))
    return path


def _offset(k: int, field: str) -> int:
    """Byte offset of ``field`` of record ``k`` in a format-2 file."""
    return HEADER_SIZE + k * RECORD_SIZE + DATA_DTYPE.fields[field][1]


def _reseal(data: bytearray, k: int) -> None:
    """Recompute record k's CRC: the record as the daemon itself would have written it."""
    start = HEADER_SIZE + k * RECORD_SIZE
    struct.pack_into("<I", data, start + DATA_STRUCT.size, zlib.crc32(data[start:start + DATA_STRUCT.size]))


@pytest.mark.parametrize("field, bit", [("t", 3), ("motor_pos_1", 63), ("current_cmd_2", 20), ("seq", 0),
                                        ("state", 7), ("fault", 1), ("backend_faults", 9)])
def test_one_flipped_bit_loses_exactly_the_record_it_hits(clean, tmp_path, field, bit):
    data, want = bytearray(clean[0]), clean[1]
    pos = _offset(137, field) + bit // 8
    data[pos] ^= 1 << (bit % 8)
    log = read_log(_write(tmp_path, data))
    assert log.damaged == 1 and len(log) == N_RECORDS - 1
    assert log.records.astype(DATA_DTYPE).tobytes() == np.delete(want, 137).tobytes()


def test_a_flipped_crc_bit_also_loses_only_its_record(clean, tmp_path):
    data = bytearray(clean[0])
    data[HEADER_SIZE + 5 * RECORD_SIZE + DATA_STRUCT.size + 2] ^= 0x10
    log = read_log(_write(tmp_path, data))
    assert log.damaged == 1 and len(log) == N_RECORDS - 1


@pytest.mark.parametrize("where", [8 + 20, 6000, BLOCK_SIZE - 2, 3])   # JSON, padding, CRC, magic of copy 1
def test_a_damaged_first_header_copy_is_read_from_the_second(clean, tmp_path, where):
    data = bytearray(clean[0])
    data[where] ^= 0x04
    log = read_log(_write(tmp_path, data))
    assert log.header_note.startswith("first header copy damaged")
    assert log.meta["rate_hz"] == 1000 and len(log) == N_RECORDS and log.damaged == 0


def test_both_header_copies_damaged_still_yields_every_record(clean, tmp_path, capsys):
    data = bytearray(clean[0])
    data[40] ^= 0x01
    data[BLOCK_SIZE + 40] ^= 0x01
    path = _write(tmp_path, data)
    log = read_log(path)
    assert log.meta == {} and "both header copies damaged" in log.header_note and len(log) == N_RECORDS
    assert main(["log", "info", str(path)]) == 0
    assert "both header copies damaged" in capsys.readouterr().out


def test_bad_enum_bytes_and_a_nan_time_are_counted_not_fatal_and_spare_the_neighbours(clean, tmp_path, capsys):
    """The failures of issue 10 item 8, even with a valid CRC (as if the daemon had written them)."""
    data, want = bytearray(clean[0]), clean[1]
    data[_offset(10, "fault")] = 200          # "200 is not a valid Fault"
    data[_offset(20, "state")] = 255          # "255 is not a valid State"
    struct.pack_into("<d", data, _offset(30, "t"), float("nan"))
    for k in (10, 20, 30):
        _reseal(data, k)
    path = _write(tmp_path, data)
    assert main(["log", "info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "3 damaged record(s) left out" in out and f"{N_RECORDS - 3} cycles" in out
    csv = tmp_path / "out.csv"
    assert main(["log", "export", str(path), "--csv", str(csv)]) == 0
    out = capsys.readouterr().out
    rec = read_csv(csv)
    kept = np.delete(want, [10, 20, 30])
    assert len(rec) == N_RECORDS - 3 and f"wrote {N_RECORDS - 3} rows" in out
    assert np.array_equal(rec["t"], kept["t"])              # both neighbours of the NaN time are there
    assert {29 * 1e-3, 31 * 1e-3} <= set(np.round(rec["t"], 9))


def test_a_nan_time_in_a_format1_log_spares_its_neighbours_too(clean, tmp_path):
    _, want = clean
    meta = {"rate_hz": 1000, "fields": [[n, DATA_DTYPE[n].str, ""] for n, *_ in FIELDS]}
    records = want.copy()
    records["t"][30] = np.nan
    records["fault"][40] = 200
    head = (MAGIC_V1 + json.dumps(meta).encode() + b"\n").ljust(V1_HEADER_SIZE, b" ")
    log = read_log(_write(tmp_path, head + records.tobytes()))
    assert log.version == 1 and log.meta["rate_hz"] == 1000 and log.damaged == 2
    assert len(csv_columns(log.records)["t"]) == N_RECORDS - 2
    s = summarize_log(log)
    assert s["cycles"] == N_RECORDS - 2 and "FAULT" not in format_summary(s)


def _older(records: np.ndarray, n_fields: int) -> np.ndarray:
    """``records`` in the packed layout of a log written when the record had ``n_fields`` fields."""
    from ankle_rt.log.record import layout

    out = np.zeros(len(records), dtype=layout(n_fields, False))
    for name in out.dtype.names:
        out[name] = records[name]
    return out


def test_a_format1_log_with_a_damaged_header_still_reads(clean, tmp_path):
    from ankle_rt.log.header import V1_FIELDS

    head = (MAGIC_V1 + b'{"rate_hz": 10\xff00}\n').ljust(V1_HEADER_SIZE, b" ")
    log = read_log(_write(tmp_path, head + _older(clean[1], V1_FIELDS).tobytes()))
    assert log.version == 1 and log.meta == {} and len(log) == N_RECORDS and "format 1" in log.header_note
    assert np.array_equal(log.records["t"], clean[1]["t"]) and not log.records["gait_phase"].any()


def _before_gait_phase(records: np.ndarray) -> bytearray:
    """A format-2 log of ``records`` as written when the record had 25 fields (CRC over its 168 data bytes)."""
    from ankle_rt.log.header import MAGIC, V1_FIELDS

    old = _older(records, V1_FIELDS)
    meta = {"format": 2, "rate_hz": 1000, "fields": [[n, old.dtype[n].str, ""] for n in old.dtype.names]}
    block = (MAGIC + json.dumps(meta).encode() + b"\n").ljust(BLOCK_SIZE - 4, b" ")
    block += struct.pack("<I", zlib.crc32(block))
    body = b"".join(row + struct.pack("<I", zlib.crc32(row)) for row in (old[i:i + 1].tobytes() for i in range(len(old))))
    return bytearray(block + block + body)


def test_a_log_written_before_the_gait_phase_field_reads_with_phase_zero(clean, tmp_path):
    """Fields are only appended: a format-2 log of the older 25-field record reads, its records
    upgraded to this layout with gait_phase 0."""
    log = read_log(_write(tmp_path, _before_gait_phase(clean[1])))
    assert log.version == 2 and log.damaged == 0 and len(log) == N_RECORDS
    assert log.records.dtype == RECORD_DTYPE and not log.records["gait_phase"].any()
    assert np.array_equal(log.records["sg_torque_dp"], clean[1]["sg_torque_dp"])


def test_an_older_log_with_both_header_copies_damaged_reads_by_its_checksums(clean, tmp_path):
    """With the header's layout lost, the records' CRCs tell the 172-byte record from this version's 173."""
    data = _before_gait_phase(clean[1])
    data[40] ^= 0x01
    data[BLOCK_SIZE + 40] ^= 0x01
    log = read_log(_write(tmp_path, data))
    assert log.meta == {} and "25 fields" in log.header_note
    assert log.damaged == 0 and len(log) == N_RECORDS and log.torn_bytes == 0
    assert np.array_equal(log.records["sg_torque_dp"], clean[1]["sg_torque_dp"])


def test_an_unknown_format_version_is_named(tmp_path):
    with pytest.raises(LogFormatError, match="log format 7 is not one this version reads"):
        read_log(_write(tmp_path, b"ANKLOG07" + b" " * 9000))


def test_a_torn_record_is_reported_and_a_truncated_header_refused(clean, tmp_path):
    data = clean[0]
    log = read_log(_write(tmp_path, data[:-5]))
    assert len(log) == N_RECORDS - 1 and log.torn_bytes == RECORD_SIZE - 5 and log.damaged == 0
    with pytest.raises(LogFormatError, match="header truncated"):
        read_log(_write(tmp_path, data[:BLOCK_SIZE + 100]))


# -- fuzz ----------------------------------------------------------------------------------------

def test_fuzz_ten_thousand_mutated_logs_read_or_refuse_cleanly(clean, tmp_path):
    """Seeded: the same 10^4 inputs every run (bit flips, overwritten bytes, truncation, extension,
    inserted and deleted bytes, zeroed blocks, header damage, swapped records)."""
    result = fuzz_logs(clean[0], 10_000, seed=20261123, directory=scratch_dir(tmp_path))
    assert result.inputs == 10_000 and result.crashes == [] and result.violations == []
    assert result.refused < 1000 and result.records_kept > 0 and result.damaged_counted > 0


def test_offline_tools_recognise_an_old_log_and_one_with_a_damaged_first_magic(clean, tmp_path):
    from ankle_rt.identification.data import load_recording

    data = bytearray(clean[0])
    data[2] ^= 0x01                                           # "ANKLOG02" -> "AOKLOG02" in copy 1
    rec = load_recording(_write(tmp_path, data))
    assert len(rec) == N_RECORDS and rec.extra["log_meta"]["rate_hz"] == 1000
    meta = {"rate_hz": 1000, "fields": [[n, DATA_DTYPE[n].str, ""] for n, *_ in FIELDS]}
    head = (MAGIC_V1 + json.dumps(meta).encode() + b"\n").ljust(V1_HEADER_SIZE, b" ")
    assert len(load_recording(_write(tmp_path, head + clean[1].tobytes(), "v1.arlog"))) == N_RECORDS


def test_a_fifo_or_a_directory_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.arlog"
    os.mkfifo(fifo)
    for path in (fifo, tmp_path):
        with pytest.raises(LogFormatError, match="not a regular file"):
            read_log(path)
