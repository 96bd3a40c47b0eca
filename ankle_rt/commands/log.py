"""``ankle-rt log``: inspect and export the daemon's run logs (format: docs/log-format.md)."""

from __future__ import annotations

import argparse
import sys

from ankle_rt.commands.outputs import output_problem


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("log", help="summarise or export a run log",
                              description="Read a run log written by `ankle-rt run`. Every intact record is "
                                          "kept; damaged ones (checksum) are left out and counted; a log cut "
                                          "short by a crash is read up to its last complete record.")
    sub = p.add_subparsers(dest="log_command", required=True, metavar="CMD")
    info = sub.add_parser("info", help="summary of a run: tracking errors, currents, loop timing, faults, damage")
    info.add_argument("path")
    info.add_argument("--json", action="store_true", help="print the summary as JSON")
    info.set_defaults(handler=info_cmd)
    export = sub.add_parser("export", help="write every field as CSV (units in the header) and/or MCAP",
                            description="CSV: one row per sample time, every field; the interchange columns "
                                        "(docs/design.md) under their plain names, the others as `name [unit]`. "
                                        "MCAP: one JSON message per record on /ankle_rt/cycle at the run's "
                                        "absolute time (Foxglove, PlotJuggler; needs the `logs` extra).")
    export.add_argument("path", nargs="+", help="a run log, or several parts of one rotated run (joined in order)")
    export.add_argument("--csv", metavar="OUT", help="CSV file to write")
    export.add_argument("--mcap", metavar="OUT", help="MCAP file to write")
    export.set_defaults(handler=export_cmd)


def _read(path: str, last: int):
    from ankle_rt.log.reader import LogFormatError, read_tail

    try:
        return read_tail(path, last)
    except LogFormatError as exc:
        print(f"ankle-rt log: {exc}", file=sys.stderr)
        return None


def _damage_lines(log) -> list[str]:
    """What was left out of ``log`` and why, one line each ([] for an intact log)."""
    lines = []
    if log.header_note:
        lines.append(f"header: {log.header_note}")
    if log.damaged:
        lines.append(f"{log.damaged} damaged record(s) left out (checksum or impossible values); "
                     f"{len(log)} intact kept")
    if log.torn_bytes:
        lines.append(f"ignored an incomplete final record of {log.torn_bytes} bytes: the writer was cut off")
    if log.version < 2:
        lines.append(f"format {log.version} log: records carry no checksum, damage cannot be detected")
    return lines


def info_cmd(args: argparse.Namespace) -> int:
    from ankle_rt import jsonout
    from ankle_rt.log.summary import SUMMARY_MAX_RECORDS, format_summary, summarize_log

    log = _read(args.path, SUMMARY_MAX_RECORDS)
    if log is None:
        return 1
    summary = summarize_log(log)
    summary["log"] = log.source
    summary["meta"] = {key: value for key, value in log.meta.items() if key != "fields"}  # minus the record layout
    summary["torn_bytes"] = log.torn_bytes
    summary["damaged_records"] = log.damaged
    summary["header_note"] = log.header_note
    summary["format"] = log.version
    if args.json:
        print(jsonout.dumps(summary, indent=2))
        return 0
    m = log.meta
    print(f"{log.source}: started {m.get('started_utc', '?')}, config {m.get('config', '?')}, backend "
          f"{m.get('backend', '?')}, {m.get('rate_hz', '?')} Hz, controller {m.get('controller', '?')}"
          + (f", part {m['part']} (from record {m.get('first_record', '?')})" if m.get("part") else ""))
    for line in _damage_lines(log):
        print(f"({line})")
    print(format_summary(summary))
    return 0


def export_cmd(args: argparse.Namespace) -> int:
    from ankle_rt.log.export import MCAP_MISSING, csv_columns, write_csv, write_mcap

    if not (args.csv or args.mcap):
        print("ankle-rt log export: give --csv OUT and/or --mcap OUT", file=sys.stderr)
        return 2
    from ankle_rt.log.reader import LogFormatError, increasing_time, read_parts

    for out in (args.csv, args.mcap):      # the export replaces its output: never a run log it reads
        problem = out and output_problem(out, args.path, "logs being exported")
        if problem:
            print(f"ankle-rt log export: {out} {problem}", file=sys.stderr)
            return 2
    try:
        log, notes = read_parts(args.path)
    except LogFormatError as exc:
        print(f"ankle-rt log: {exc}", file=sys.stderr)
        return 1
    for line in _damage_lines(log) + notes:
        print(f"{log.source}: {line}", file=sys.stderr)
    if len(log) == 0:
        print(f"ankle-rt log: {log.source}: no intact records to export", file=sys.stderr)
        return 1
    try:
        repeats = len(log) - int(increasing_time(log.records).sum())   # a count: no copy of the records
        merged = (f"; {repeats} record(s) repeating an earlier sample time merged into the later one"
                  if repeats else "")
        if args.csv:
            cols = csv_columns(log.records)
            rows = write_csv(args.csv, cols)
            print(f"wrote {rows} rows ({len(cols)} columns) to {args.csv}{merged}")
        if args.mcap:
            try:
                done = write_mcap(args.mcap, log)
            except ImportError:
                print(f"ankle-rt log: {MCAP_MISSING}", file=sys.stderr)
                return 1
            print(f"wrote {done['messages']} messages on /ankle_rt/cycle to {args.mcap}{merged}")
            if done["note"]:
                print(f"note: {done['note']}", file=sys.stderr)
    except OSError as exc:
        print(f"ankle-rt log: cannot write {exc.filename}: {exc.strerror}", file=sys.stderr)
        return 1
    return 0
