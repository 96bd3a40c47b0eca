"""Reading a run log back: every intact record is kept, every damaged one counted and left out.

A record is damaged when its CRC does not match (format 2) or it holds a value the daemon never
writes (a time that is not finite, an unknown state or fault code). A torn final record (a killed
daemon) is ignored and reported. A damaged header is read from its copy. Anything that is not a
readable log raises :class:`LogFormatError` with the reason.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ankle_rt.log.header import HEADER_SIZE, Header, LogFormatError, decode_header
from ankle_rt.log.record import crc_ok, upgrade
from ankle_rt.safety import Fault, State
from ankle_rt.textfile import TextFileError, open_regular

__all__ = ["LogFormatError", "RunLog", "read_log", "read_tail", "read_parts", "interchange_columns"]

_KNOWN_STATE = np.isin(np.arange(256), [int(s) for s in State])   # by u1 code: a table lookup per record
_KNOWN_FAULT = np.isin(np.arange(256), [int(f) for f in Fault])
_FIRST_SCAN = 1024   # records searched for the first intact one (first_t of a tail read)


@dataclass
class RunLog:
    meta: dict[str, Any]
    records: np.ndarray       # the intact records (RECORD_DTYPE): all of them, or of the last ``last`` asked for
    torn_bytes: int           # bytes of an incomplete final record that were ignored
    source: str
    total_records: int = 0    # complete records in the file (> len(records) when only the tail was read)
    first_t: float = math.nan  # s, sample time of the file's first intact record (NaN when it has none)
    damaged: int = 0          # records of the part read that were left out (checksum or impossible values)
    header_note: str = ""     # damage found in the header ("" when intact)
    version: int = 2          # the file's format version

    def __len__(self) -> int:
        return len(self.records)

    @property
    def is_tail(self) -> bool:
        """True when only the most recent records were read (a long run, see ``read_log(last=...)``)."""
        return self.total_records > len(self.records) + self.damaged


def _intact(raw: bytes, dtype: np.dtype, checksummed: bool) -> tuple[np.ndarray, int]:
    """The intact records of ``raw`` (whole records only) and how many were damaged."""
    n = len(raw) // dtype.itemsize
    rows = np.frombuffer(raw, dtype=np.uint8, count=n * dtype.itemsize).reshape(n, dtype.itemsize)
    records = rows.view(dtype).reshape(n)
    ok = np.isfinite(records["t"]) & _KNOWN_STATE[records["state"]] & _KNOWN_FAULT[records["fault"]]
    if checksummed:
        ok &= crc_ok(rows)
    if ok.all():
        return records, 0
    return rows[ok].view(dtype).reshape(-1), int(n - ok.sum())   # whole rows: the CRC bytes stay


def _by_checksums(sample: bytes, header: Header) -> Header:
    """``header`` with the layout of ``header.layouts`` under which most records of ``sample`` (the
    file's first records) have intact checksums: a log whose header was lost may predate a field."""
    def intact(dtype: np.dtype) -> int:
        n = len(sample) // dtype.itemsize
        return int(crc_ok(np.frombuffer(sample, np.uint8, n * dtype.itemsize).reshape(n, dtype.itemsize)).sum())

    best = max(header.layouts, key=intact)   # the first (newest) on a tie
    if best is header.dtype:
        return header
    fields = len(best.names)
    return Header({}, header.records_offset, best, header.version,
                  f"{header.note} of {fields} fields (an older record, told by its checksums)")


def read_log(path: str | Path, last: int | None = None) -> RunLog:
    """Read a run log; ``last`` keeps memory and time bounded for long runs: only the most recent
    ``last`` records are read (a seek, then one read), never the whole file."""
    path = Path(path)
    try:                       # a regular file only: a FIFO would block the read, a directory fail it
        handle = os.fdopen(open_regular(path, None), "rb")
    except TextFileError as exc:
        raise LogFormatError(f"{path}: {exc}") from None
    try:
        with handle:
            file_size = os.fstat(handle.fileno()).st_size
            header = decode_header(handle.read(HEADER_SIZE), str(path))
            if header.layouts:
                header = _by_checksums(handle.read(_FIRST_SCAN * max(d.itemsize for d in header.layouts)), header)
                handle.seek(header.records_offset)
            size = header.dtype.itemsize
            checksummed = header.version >= 2
            body = max(0, file_size - header.records_offset)
            total = body // size
            first, _ = _intact(handle.read(min(total, _FIRST_SCAN) * size), header.dtype, checksummed)
            start = 0 if last is None else max(0, total - max(last, 0))
            handle.seek(header.records_offset + start * size)
            raw = handle.read((total - start) * size)
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read: {exc.strerror}") from None
    records, damaged = _intact(raw, header.dtype, checksummed)
    return RunLog(meta=header.meta, records=upgrade(records), torn_bytes=body - total * size, source=str(path),
                  total_records=total, first_t=float(first["t"][0]) if len(first) else math.nan,
                  damaged=damaged, header_note=header.note, version=header.version)


def read_tail(path: str | Path, last: int) -> RunLog:
    """The most recent ``last`` records of the run whose newest part is ``path`` (bounded like
    ``read_log(last=...)``). A part just begun by a rotation holds few records, so the rest come
    from the part before it when that is still there; ``total_records`` and ``first_t`` then
    describe the whole run (from the header's ``first_record``, and the run's start from the last
    record's ``loop_time``), so the summary says which part of the run it covers."""
    from ankle_rt.log.writer import part_path

    log = read_log(path, last)
    part, first = log.meta.get("part"), log.meta.get("first_record")
    if not (isinstance(part, int) and isinstance(first, int)) or part <= 0:
        return log
    records, damaged = log.records, log.damaged
    wanted = last - len(records) - damaged
    previous = part_path(Path(path).with_name(str(log.meta.get("first_part", ""))), part - 1)
    if wanted > 0 and previous.is_file():
        try:
            before = read_log(previous, wanted)
        except LogFormatError:
            before = None
        if before is not None and before.meta.get("first_record", -1) + before.total_records == first:
            records, damaged = np.concatenate([before.records, records]), damaged + before.damaged
    run_start = float(records["t"][-1] - records["loop_time"][-1]) if len(records) else math.nan
    return RunLog(meta=log.meta, records=records, torn_bytes=log.torn_bytes, source=log.source,
                  total_records=first + log.total_records, first_t=run_start, damaged=damaged,
                  header_note=log.header_note, version=log.version)


def read_parts(paths: list[str | Path]) -> tuple[RunLog, list[str]]:
    """Parts of one rotated run read as one log, in record order (each part's ``first_record``), and
    notes on any records missing between two of them (a deleted part, records dropped). Raises
    :class:`LogFormatError` for parts of different runs or a part whose header was lost."""
    logs = [read_log(p) for p in paths]
    if len(logs) == 1:
        return logs[0], []
    for log in logs:
        if "first_record" not in log.meta:
            raise LogFormatError(f"{log.source}: no part number in its header (damaged, or an older log): "
                                 "export it on its own")
    runs = {(log.meta.get("first_part"), log.meta.get("started_utc")) for log in logs}
    if len(runs) > 1:
        raise LogFormatError(f"{', '.join(log.source for log in logs)}: parts of different runs")
    logs.sort(key=lambda log: log.meta["first_record"])
    notes = []
    for a, b in zip(logs, logs[1:]):
        missing = b.meta["first_record"] - (a.meta["first_record"] + a.total_records)
        if missing < 0:
            raise LogFormatError(f"{a.source}, {b.source}: parts overlap ({-missing} records in both; "
                                 "the same part given twice?)")
        if missing:
            notes.append(f"{missing} records missing between {a.source} and {b.source}")
    joined = RunLog(meta=logs[0].meta, records=np.concatenate([log.records for log in logs]),
                    torn_bytes=sum(log.torn_bytes for log in logs), source=" + ".join(log.source for log in logs),
                    total_records=sum(log.total_records for log in logs), first_t=logs[0].first_t,
                    damaged=sum(log.damaged for log in logs),
                    header_note="; ".join(f"{log.source}: {log.header_note}" for log in logs if log.header_note),
                    version=min(log.version for log in logs))
    return joined, notes


# The log fields exported to the measured-data interchange CSV (docs/design.md), in column order.
INTERCHANGE_FIELDS = ("t", "motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2",
                      "sg_torque_dp", "sg_torque_ie", "ankle_dp", "ankle_ie", "ref_dp", "ref_ie")


# Left out when the run has no such data (no joint encoders; an experiment without a reference).
OPTIONAL_FIELDS = ("ankle_dp", "ankle_ie", "ref_dp", "ref_ie")


def increasing_time(records: np.ndarray) -> np.ndarray:
    """Mask of the records the CSV export keeps: where a cycle woke so late that the next one read
    the same sample again, two records share a sample time; the interchange format needs increasing
    time, so only the later of them (whose set value acted from that time on) is kept."""
    t = np.asarray(records["t"], dtype=float)
    keep = np.ones(len(t), dtype=bool)
    keep[:-1] = np.diff(t) > 0
    return keep


def interchange_columns(records: np.ndarray) -> dict[str, np.ndarray]:
    """Columns for :func:`ankle_rt.interchange.write_csv`; optional columns only when they hold data.
    Rows as :func:`increasing_time` keeps them."""
    keep = increasing_time(records)
    cols = {}
    for name in INTERCHANGE_FIELDS:
        col = np.asarray(records[name], dtype=float)[keep]
        if name in OPTIONAL_FIELDS and np.isnan(col).all():
            continue
        cols[name] = col
    return cols
