"""Reading a run log back: tolerant of a torn final record (a killed daemon), strict about
everything else (wrong magic, a layout this version does not know)."""

from __future__ import annotations

import json
import math
import os
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
    records: np.ndarray       # structured array, RECORD_DTYPE (all of them, or the last ``last`` asked for)
    torn_bytes: int           # bytes of an incomplete final record that were ignored
    source: str
    total_records: int = 0    # complete records in the file (> len(records) when only the tail was read)
    first_t: float = math.nan  # s, sample time of the file's first record (NaN when it has none)

    def __len__(self) -> int:
        return len(self.records)

    @property
    def is_tail(self) -> bool:
        """True when only the most recent records were read (a long run, see ``read_log(last=...)``)."""
        return self.total_records > len(self.records)


def read_log(path: str | Path, last: int | None = None) -> RunLog:
    """Read a run log; ``last`` keeps memory and time bounded for long runs: only the most recent
    ``last`` records are read (seek + ``np.fromfile``), never the whole file."""
    path = Path(path)
    try:
        with path.open("rb") as handle:
            head = handle.read(HEADER_SIZE)
            file_size = os.fstat(handle.fileno()).st_size
            if not head.startswith(MAGIC):
                raise LogFormatError(f"{path}: not an ankle-rt log (magic {head[:8]!r}, expected {MAGIC!r})")
            if len(head) < HEADER_SIZE:
                raise LogFormatError(f"{path}: header truncated ({len(head)} of {HEADER_SIZE} bytes)")
            try:
                meta = json.loads(head[len(MAGIC):].decode().strip())
            except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                raise LogFormatError(f"{path}: header is not valid JSON: {exc}") from None
            fields = [(name, code) for name, code, _ in meta.get("fields", [])]
            if fields != [(name, RECORD_DTYPE[name].str) for name in RECORD_DTYPE.names]:
                raise LogFormatError(f"{path}: record layout differs from this version's (fields {fields[:3]}...)")
            size = RECORD_DTYPE.itemsize
            body = file_size - HEADER_SIZE
            total = body // size
            first_t = float(np.fromfile(handle, dtype=RECORD_DTYPE, count=1)["t"][0]) if total else math.nan
            start = 0 if last is None else max(0, total - max(last, 0))
            handle.seek(HEADER_SIZE + start * size)
            records = np.fromfile(handle, dtype=RECORD_DTYPE, count=total - start)
    except OSError as exc:
        raise LogFormatError(f"{path}: cannot read: {exc.strerror}") from None
    return RunLog(meta=meta, records=records, torn_bytes=body - total * size, source=str(path),
                  total_records=total, first_t=first_t)


# The log fields exported to the measured-data interchange CSV (docs/design.md), in column order.
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
