"""Exporting a run log for other tools: a CSV with every field and its unit, and MCAP (Foxglove,
PlotJuggler; needs the optional ``mcap`` package, extra ``logs``)."""

from __future__ import annotations

import calendar
import json
import math
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

from ankle_rt.log.reader import INTERCHANGE_FIELDS, OPTIONAL_FIELDS, RunLog, increasing_time
from ankle_rt.log.record import FIELDS, RECORD_DTYPE, UNITS, field_doc
from ankle_rt.safety import Fault, State

MCAP_TOPIC = "/ankle_rt/cycle"
MCAP_SCHEMA = "ankle_rt.Cycle"
MCAP_MISSING = "MCAP export needs the mcap package: pip install 'ankle-rt[logs]'"
CHUNK_ROWS = 65536   # records formatted at a time (Python objects per chunk, not per log)


def csv_name(name: str, plain: bool) -> str:
    """A CSV column's header: the interchange name as-is (its unit is the format's, SI), else ``name [unit]``."""
    return name if plain else f"{name} [{UNITS[name]}]"


def exported_records(records: np.ndarray) -> np.ndarray:
    """The records both exports write: one per sample time (:func:`increasing_time`), so the CSV's
    rows and the MCAP's messages are the same cycles."""
    return records[increasing_time(records)]


def csv_columns(records: np.ndarray) -> dict[str, np.ndarray]:
    """Every field as a CSV column, in record order, one row per sample time (:func:`increasing_time`).

    The docs/design.md interchange columns keep their plain names, so ``diagnose``, ``identify`` and
    ``validate`` read the file as it is; an optional one (joint encoders, references) goes under
    ``name [unit]`` instead when it holds a value that is not finite (the interchange format allows
    none), where the interchange reader ignores it. Every other field is ``name [unit]``."""
    records = exported_records(records)
    out = {}
    for name, *_ in FIELDS:
        col = records[name]
        plain = name in INTERCHANGE_FIELDS and not (name in OPTIONAL_FIELDS and not np.isfinite(col).all())
        out[csv_name(name, plain)] = col
    return out


def shortest_text(values: np.ndarray) -> list[str]:
    """Each number as the shortest decimal text that reads back to exactly the same value
    (``0.003``, not ``0.0030000000000000001``): Python's float repr for float64, numpy's for float32."""
    if values.dtype.kind == "f" and values.dtype.itemsize == 4:
        return [str(v) for v in values]
    return list(map(repr, values.tolist()))


def write_csv(path: str | Path, columns: dict[str, np.ndarray]) -> int:
    """Write ``columns`` (from :func:`csv_columns`) exactly, each value as its shortest text
    (:func:`shortest_text`); returns the rows written. The file appears complete or not at all
    (written beside it, then renamed)."""
    path = Path(path)
    names = list(columns)
    rows = len(columns[names[0]]) if names else 0
    tmp = path.with_name(f".{path.name}.part")
    try:
        with tmp.open("w", newline="", encoding="utf-8") as handle:
            handle.write(",".join(names) + "\n")
            for start in range(0, rows, CHUNK_ROWS):      # bounded memory for logs of hours
                stop = min(rows, start + CHUNK_ROWS)
                cells = [shortest_text(columns[n][start:stop]) for n in names]
                handle.writelines(",".join(row) + "\n" for row in zip(*cells))
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return rows


def start_unix_ns(meta: dict[str, Any]) -> int | None:
    """The run's wall-clock start in ns since 1970 from the header (``started_unix_s``, or the
    second-resolution ``started_utc`` of older logs); None when the header does not say."""
    value = meta.get("started_unix_s")
    if isinstance(value, (int, float)) and math.isfinite(value) and value >= 0:
        return round(value * 1e9)
    try:
        return calendar.timegm(time.strptime(str(meta["started_utc"]), "%Y-%m-%dT%H:%M:%SZ")) * 10**9
    except (KeyError, ValueError, OverflowError):
        return None


def _schema() -> dict[str, Any]:
    props: dict[str, Any] = {}
    for name, *_ in FIELDS:
        kind = "integer" if RECORD_DTYPE[name].kind in "iu" else "number"
        props[name] = {"type": kind if kind == "integer" else ["number", "null"], "unit": UNITS[name],
                       "description": field_doc(name) + (" (null: not available)" if kind == "number" else "")}
    props["state_name"] = {"type": "string", "description": "safety.State name of `state`"}
    props["fault_name"] = {"type": "string", "description": "safety.Fault name of `fault`"}
    props["gait_phase_name"] = {"type": "string", "description": "gait phase of `gait_phase` (none: another controller)"}
    return {"type": "object", "title": MCAP_SCHEMA, "properties": props}


def _json_columns(records: np.ndarray) -> dict[str, list]:
    """Every field as a list of Python numbers, NaN/inf as None (JSON has no NaN)."""
    columns = {}
    for name, *_ in FIELDS:
        values = records[name].tolist()
        columns[name] = values if RECORD_DTYPE[name].kind in "iu" else [v if math.isfinite(v) else None for v in values]
    return columns


def write_mcap(path: str | Path, log: RunLog) -> dict[str, Any]:
    """Write every intact record of ``log`` (:func:`exported_records`, as the CSV) as one JSON message
    on :data:`MCAP_TOPIC` (JSON schema, so Foxglove and PlotJuggler plot every field); log time = the
    run's start (UTC) + the record's ``loop_time``. Returns ``{"messages", "start_ns", "note"}``.
    Raises ImportError without ``mcap``."""
    from mcap.writer import CompressionType, Writer

    start = start_unix_ns(log.meta)
    note = "" if start is not None else "the header does not say when the run started: times count from 1970-01-01"
    start = start or 0
    records = exported_records(log.records)
    loop_time = records["loop_time"].astype(float)
    rel = np.where(np.isfinite(loop_time) & (loop_time >= 0), loop_time, 0.0)
    times = start + np.round(rel * 1e9).astype(np.int64)
    state_names = {int(s): s.name for s in State}
    fault_names = {int(f): f.name for f in Fault}
    from ankle_rt.control.gait_phase import PHASE_NAMES
    names = [name for name, *_ in FIELDS]
    path = Path(path)
    tmp = path.with_name(f".{path.name}.part")
    try:
        with tmp.open("wb") as handle:
            writer = Writer(handle, compression=CompressionType.ZSTD)
            writer.start(profile="", library="ankle-rt")
            schema = writer.register_schema(MCAP_SCHEMA, "jsonschema", json.dumps(_schema()).encode())
            channel = writer.register_channel(MCAP_TOPIC, "json", schema)
            writer.add_metadata("ankle_rt.log", {k: json.dumps(v) for k, v in log.meta.items() if k != "fields"})
            dumps = json.dumps
            for start in range(0, len(records), CHUNK_ROWS):
                columns = _json_columns(records[start:start + CHUNK_ROWS])
                for j in range(len(columns["t"])):
                    message = {name: columns[name][j] for name in names}
                    message["state_name"] = state_names[message["state"]]
                    message["fault_name"] = fault_names[message["fault"]]
                    code = message["gait_phase"]
                    message["gait_phase_name"] = PHASE_NAMES[code] if code < len(PHASE_NAMES) else str(code)
                    i = start + j
                    stamp = int(times[i])
                    writer.add_message(channel, log_time=stamp, publish_time=stamp, sequence=i,
                                       data=dumps(message, allow_nan=False).encode())
            writer.finish()
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return {"messages": len(records), "start_ns": start, "note": note}
