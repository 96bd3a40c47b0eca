"""Input data for the offline tools: an interchange CSV, or a daemon run log read directly (the same
columns ``ankle-rt log export --csv`` would write), with its sampling and units checked
(:mod:`ankle_rt.sampling`) before any tool fits it."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ankle_rt.interchange import InterchangeError, Recording, read_csv
from ankle_rt.sampling import check_sampling
from ankle_rt.textfile import TextFileError, read_head


def load_recording(path: str | Path, min_rows: int = 2, cfg: Mapping[str, Any] | None = None) -> Recording:
    """Read ``path`` as a run log (by its magic bytes) or else as an interchange CSV; either way a file
    with fewer than ``min_rows`` rows is an error naming column 't' and the row count. The sampling
    and units are checked against ``cfg`` (when given; see :func:`ankle_rt.sampling.check_sampling`):
    refusals raise InterchangeError, warnings are kept in ``extra["warnings"]``. A run log's header
    metadata is kept in ``extra["log_meta"]``."""
    rec = _read(Path(path), min_rows)
    rec.extra["warnings"] = check_sampling(rec, cfg)
    return rec


def _read(path: Path, min_rows: int) -> Recording:
    from ankle_rt.log.header import HEADER_SIZE, is_run_log
    from ankle_rt.log.reader import LogFormatError, interchange_columns, read_log

    try:
        is_log = is_run_log(read_head(path, HEADER_SIZE))
    except TextFileError as exc:
        raise InterchangeError(str(exc), path) from None
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
