"""``ankle-rt log``: inspect and export the daemon's run logs (format: docs/log-format.md)."""

from __future__ import annotations

import argparse
import sys


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("log", help="summarise or export a run log",
                              description="Read a run log written by `ankle-rt run` (a log cut short by a crash "
                                          "is read up to its last complete record).")
    sub = p.add_subparsers(dest="log_command", required=True, metavar="CMD")
    info = sub.add_parser("info", help="summary of a run: tracking errors, currents, loop timing, faults")
    info.add_argument("path")
    info.add_argument("--json", action="store_true", help="print the summary as JSON")
    info.set_defaults(handler=info_cmd)
    export = sub.add_parser("export", help="write the measured-data interchange CSV (docs/design.md), one row per cycle")
    export.add_argument("path")
    export.add_argument("--csv", required=True, metavar="OUT", help="CSV file to write")
    export.set_defaults(handler=export_cmd)


def _read(path: str, last: int | None = None):
    from ankle_rt.log.reader import LogFormatError, read_log

    try:
        return read_log(path, last)
    except LogFormatError as exc:
        print(f"ankle-rt log: {exc}", file=sys.stderr)
        return None


def info_cmd(args: argparse.Namespace) -> int:
    import json

    from ankle_rt.log.summary import SUMMARY_MAX_RECORDS, format_summary, summarize_log

    log = _read(args.path, SUMMARY_MAX_RECORDS)
    if log is None:
        return 1
    summary = summarize_log(log)
    summary["log"] = log.source
    summary["meta"] = {key: value for key, value in log.meta.items() if key != "fields"}  # minus the record layout
    summary["torn_bytes"] = log.torn_bytes
    if args.json:
        print(json.dumps(summary, indent=2, default=float))
        return 0
    m = log.meta
    print(f"{log.source}: started {m.get('started_utc', '?')}, config {m.get('config', '?')}, backend "
          f"{m.get('backend', '?')}, {m.get('rate_hz', '?')} Hz, controller {m.get('controller', '?')}")
    if log.torn_bytes:
        print(f"(ignored an incomplete final record of {log.torn_bytes} bytes: the writer was cut off)")
    print(format_summary(summary))
    return 0


def export_cmd(args: argparse.Namespace) -> int:
    from ankle_rt.interchange import write_csv
    from ankle_rt.log.reader import interchange_columns

    log = _read(args.path)
    if log is None:
        return 1
    if len(log) == 0:
        print(f"ankle-rt log: {args.path}: no records to export", file=sys.stderr)
        return 1
    cols = interchange_columns(log.records)
    write_csv(args.csv, cols)
    print(f"wrote {len(log)} rows, columns {', '.join(cols)} to {args.csv}")
    return 0
