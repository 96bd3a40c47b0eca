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


def load_recording(path: str | Path, min_rows: int = 2, cfg: Mapping[str, Any] | None = None, *,
                   gaps_masked: bool = False) -> Recording:
    """Read ``path`` as a run log (by its magic bytes) or else as an interchange CSV; either way a file
    with fewer than ``min_rows`` rows is an error naming column 't' and the row count. The sampling
    and units are checked against ``cfg`` (when given; see :func:`ankle_rt.sampling.check_sampling`):
    refusals raise InterchangeError, warnings are kept in ``extra["warnings"]``; ``gaps_masked`` for a
    caller that masks the samples around a time gap instead of refusing it. A run log's header metadata is
    kept in ``extra["log_meta"]``."""
    rec = _read(Path(path), min_rows)
    rebased = _from_first_sample(rec)
    rec.extra["warnings"] = rebased + check_sampling(rec, cfg, gaps_masked=gaps_masked)
    return rec


ABSOLUTE_TIME_S = 1e7
"""s (115 days): a first time stamp beyond this is a clock's absolute time (UNIX seconds), not a run's."""


def _from_first_sample(rec: Recording) -> list[str]:
    """Count ``rec``'s time from its first sample when it is a clock's absolute time (the tools replay and
    simulate from t = 0; the format asks only for seconds that increase); the warning says so."""
    t = rec["t"]
    if abs(t[0]) <= ABSOLUTE_TIME_S:
        return []
    rec.columns["t"] = t - t[0]
    return [f"{rec.source}: column 't': time stamps start at {t[0]:.10g} s (a clock's absolute time): counted "
            "from the first sample"]


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
