"""Read the diagnosis' input: an interchange CSV or a daemon run log (told apart by the log's magic)."""

from __future__ import annotations

from pathlib import Path

from ankle_rt.interchange import InterchangeError, Recording, read_csv


def load_recording(path: str | Path) -> Recording:
    """A :class:`Recording` from an interchange CSV or an ``ankle-rt run`` log.

    Raises InterchangeError (naming column and row) for a bad CSV, or for a log that cannot be read."""
    from ankle_rt.log.reader import LogFormatError, interchange_columns, read_log
    from ankle_rt.log.writer import MAGIC

    path = Path(path)
    try:
        with path.open("rb") as handle:
            head = handle.read(len(MAGIC))
    except OSError as exc:
        raise InterchangeError(f"cannot read: {exc.strerror}", path) from None
    if head != MAGIC:
        return read_csv(path)
    try:
        log = read_log(path)
    except LogFormatError as exc:
        raise InterchangeError(str(exc)) from None
    if len(log) < 2:
        raise InterchangeError("run log holds fewer than 2 records", path, "t", len(log))
    return Recording(interchange_columns(log.records), str(path), extra={"meta": log.meta})
