"""Parse a reference-profile CSV in a child process, so the control loop's process never spends
interpreter time on it.

Parsing a 12 MB CSV takes about a second of interpreter time. In a thread of the daemon it would
compete with the loop thread for the interpreter lock and cost it missed cycles; in a child process
(at the lowest CPU priority) it competes for nothing the loop needs. The child checks the file
exactly as :class:`~ankle_rt.references.CsvProfile` does and writes either an error or the three
columns as float64 arrays to its stdout; the parent (the daemon's background loader thread) reads
them in slices (no interpreter lock held while waiting) straight into ``array('d')`` tables, pausing
between slices: no per-value Python objects are made, so the parent holds the lock only for short copies.

Protocol on the child's stdout: one JSON line ``{"rows": N, "bounds": [[dp_min, dp_max], [ie_min,
ie_max]]}`` followed by 3 x N little-endian float64 (t, ref_dp, ref_ie), or one JSON line
``{"error": MESSAGE}``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from array import array
from typing import Callable

import numpy as np

from ankle_rt.interchange import InterchangeError

SLICE_BYTES = 1 << 17
"""Bytes the parent reads and copies per step (16384 values, a few µs of interpreter time)."""


def load_csv_profile(path: str, pause: Callable[[], None]) -> "CsvProfile":  # noqa: F821
    """The CsvProfile of ``path``, parsed in a child process; InterchangeError for a bad file."""
    from ankle_rt.references import CsvProfile

    proc = subprocess.Popen([sys.executable, "-m", "ankle_rt.service.profile_process", path],
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    try:
        head = json.loads(proc.stdout.readline() or b'{"error": "the profile reader exited without a result"}')
        if "error" in head:
            raise InterchangeError(head["error"])
        rows = int(head["rows"])
        columns = []
        for _ in range(3):
            column, need = array("d"), 8 * rows
            while need:
                chunk = proc.stdout.read(min(need, SLICE_BYTES))   # waits without the interpreter lock
                if not chunk:
                    raise InterchangeError(f"{path}: the profile reader stopped early")
                column.frombytes(chunk)                          # one short copy: no per-value objects
                need -= len(chunk)
                pause()
            if sys.byteorder != "little":
                column.byteswap()
            columns.append(column)
        bounds = tuple(tuple(b) for b in head["bounds"])
        return CsvProfile.from_columns(columns[0], columns[1], columns[2], bounds)
    finally:
        proc.kill()
        proc.wait()
        proc.stdout.close()


def main(path: str) -> int:
    from ankle_rt.references import CsvProfile
    from ankle_rt.service.loader import normal_scheduling

    normal_scheduling()   # not the real-time policy a SCHED_FIFO daemon's threads pass on
    os.nice(19)           # and the lowest priority: the control loop's CPU time comes first

    out = sys.stdout.buffer
    try:
        profile = CsvProfile(path)
    except InterchangeError as exc:
        out.write(json.dumps({"error": str(exc)}).encode() + b"\n")
        return 0
    out.write(json.dumps({"rows": len(profile.t), "bounds": profile.bounds()}).encode() + b"\n")
    for column in (profile.t, profile.dp, profile.ie):
        out.write(np.asarray(column, dtype="<f8").tobytes())
    out.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
