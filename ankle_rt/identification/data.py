"""Input data for the offline tools: an interchange CSV, or a daemon run log read directly (the same
columns ``ankle-rt log export --csv`` would write)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ankle_rt.interchange import InterchangeError, Recording, read_csv


def load_recording(path: str | Path, min_rows: int = 2) -> Recording:
    """Read ``path`` as a run log (by its magic bytes) or else as an interchange CSV; either way a file
    with fewer than ``min_rows`` rows is an error naming column 't' and the row count. A run log's
    header metadata is kept in ``extra["log_meta"]``."""
    from ankle_rt.log.header import HEADER_SIZE, is_run_log
    from ankle_rt.log.reader import LogFormatError, interchange_columns, read_log

    path = Path(path)
    try:
        with path.open("rb") as handle:
            is_log = is_run_log(handle.read(HEADER_SIZE))
    except OSError as exc:
        raise InterchangeError(f"cannot read: {exc.strerror}", path) from None
    if not is_log:
        return read_csv(path, min_rows=min_rows)
    try:
        log = read_log(path)
    except LogFormatError as exc:
        raise InterchangeError(str(exc)) from None
    columns = {k: np.asarray(v, dtype=float) for k, v in interchange_columns(log.records).items()}
    n = len(columns["t"])
    if n < min_rows:
        raise InterchangeError(f"too short: {n} records, need at least {min_rows}", path, "t", n)
    return Recording(columns, str(path), extra={"log_meta": log.meta})
