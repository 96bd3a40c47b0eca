"""Reading a run log back: tolerant of a torn final record (a killed daemon), strict about
everything else (wrong magic, a layout this version does not know)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ankle_rt.log.record import RECORD_DTYPE
from ankle_rt.log.writer import HEADER_SIZE, MAGIC


class LogFormatError(ValueError):
    """The file is not an ankle-rt log, or not one this version can read (the message says why)."""


@dataclass
class RunLog:
    meta: dict[str, Any]
    records: np.ndarray       # structured array, RECORD_DTYPE
    torn_bytes: int           # bytes of an incomplete final record that were ignored
    source: str

    def __len__(self) -> int:
        return len(self.records)


def read_log(path: str | Path) -> RunLog:
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read: {exc.strerror}") from None
    if not data.startswith(MAGIC):
        raise LogFormatError(f"{path}: not an ankle-rt log (magic {data[:8]!r}, expected {MAGIC!r})")
    if len(data) < HEADER_SIZE:
        raise LogFormatError(f"{path}: header truncated ({len(data)} of {HEADER_SIZE} bytes)")
    try:
        meta = json.loads(data[len(MAGIC):HEADER_SIZE].decode().strip())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise LogFormatError(f"{path}: header is not valid JSON: {exc}") from None
    fields = [(name, code) for name, code, _ in meta.get("fields", [])]
    if fields != [(name, RECORD_DTYPE[name].str) for name in RECORD_DTYPE.names]:
        raise LogFormatError(f"{path}: record layout differs from this version's (fields {fields[:3]}...)")
    size = RECORD_DTYPE.itemsize
    body = len(data) - HEADER_SIZE
    n = body // size
    records = np.frombuffer(data, dtype=RECORD_DTYPE, count=n, offset=HEADER_SIZE).copy()
    return RunLog(meta=meta, records=records, torn_bytes=body - n * size, source=str(path))


# The log fields exported to the measured-data interchange CSV (DESIGN.md), in column order.
INTERCHANGE_FIELDS = ("t", "motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2",
                      "sg_torque_dp", "sg_torque_ie", "ankle_dp", "ankle_ie", "ref_dp", "ref_ie")


# Left out when the run has no such data (no joint encoders; an experiment without a reference).
OPTIONAL_FIELDS = ("ankle_dp", "ankle_ie", "ref_dp", "ref_ie")


def interchange_columns(records: np.ndarray) -> dict[str, np.ndarray]:
    """Columns for :func:`ankle_rt.interchange.write_csv`; optional columns only when they hold data.

    A cycle that woke so late that the next one read the same sample again leaves two records with
    the same sample time; the interchange format needs increasing time, so only the later of them
    (whose set value is the one that acted from that time on) is kept."""
    t = np.asarray(records["t"], dtype=float)
    keep = np.ones(len(t), dtype=bool)
    keep[:-1] = np.diff(t) > 0
    cols = {}
    for name in INTERCHANGE_FIELDS:
        col = np.asarray(records[name], dtype=float)[keep]
        if name in OPTIONAL_FIELDS and np.isnan(col).all():
            continue
        cols[name] = col
    return cols
