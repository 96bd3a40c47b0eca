"""Preallocated log ring and its writer thread.

The loop packs each cycle's record into the next slot of a ``bytearray`` ring with one
``struct.pack_into`` call (no allocation, no I/O). A writer thread wakes every
``logging.flush_interval_s`` and hands whole ring slices to ``os.write`` (which releases the GIL), so
it does almost no Python work per record and never competes with the loop for long. Records reach
the kernel within one flush interval and survive a kill -9 of the daemon; ``close()`` writes the
rest and fsyncs. If the disk stalls for longer than the ring holds, or a write fails (disk full), the
records are dropped and counted (``dropped``, ``error``), never the loop delayed.
"""

from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path
from typing import Any

from ankle_rt.log.record import FIELDS, RECORD_DTYPE, RECORD_STRUCT

MAGIC = b"ANKLOG01"
HEADER_SIZE = 4096   # fixed: records start here, so a reader finds them without parsing


def encode_header(meta: dict[str, Any]) -> bytes:
    """MAGIC + JSON (record layout and run metadata), padded with spaces to HEADER_SIZE."""
    body = dict(meta)
    body["record_size"] = RECORD_DTYPE.itemsize
    body["fields"] = [[name, RECORD_DTYPE[name].str, doc] for name, _, doc in FIELDS]
    text = json.dumps(body, sort_keys=True).encode()
    if len(MAGIC) + len(text) + 1 > HEADER_SIZE:
        raise ValueError("log header metadata too large")
    return (MAGIC + text + b"\n").ljust(HEADER_SIZE, b" ")


class LogWriter:
    """Ring of ``capacity`` records plus the thread that appends them to ``path``."""

    def __init__(self, path: str | Path, meta: dict[str, Any], capacity: int = 16384,
                 flush_interval_s: float = 0.05):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.size = RECORD_STRUCT.size
        self.capacity = capacity
        self.buffer = bytearray(capacity * self.size)
        self.view = memoryview(self.buffer)
        self.pack_into = RECORD_STRUCT.pack_into
        self.written = 0     # records packed by the loop (only the loop writes this)
        self.flushed = 0     # records handed to the kernel (only the writer thread writes this)
        self.dropped = 0
        self.error = ""      # the latest write error (the records it cost are counted in dropped)
        self.interval = flush_interval_s
        self.fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.write(self.fd, encode_header(meta))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ankle-rt-log", daemon=True)
        self._thread.start()

    def append(self, *values: Any) -> None:
        """Pack one record into the ring (the loop's only logging work). Values in FIELDS order."""
        n = self.written
        self.pack_into(self.buffer, (n % self.capacity) * self.size, *values)
        self.written = n + 1

    def _flush(self) -> None:
        end = self.written
        start = self.flushed
        # keep a margin: the loop may be packing slot `end` right now
        if end - start > self.capacity - 1:
            self.dropped += end - start - (self.capacity - 1)
            start = end - (self.capacity - 1)
        cap, size, view = self.capacity, self.size, self.view
        try:
            while start < end:
                i = start % cap
                j = min(cap, i + (end - start))
                chunk = view[i * size:j * size]
                while chunk:                        # os.write may write less than asked
                    chunk = chunk[os.write(self.fd, chunk):]
                start += j - i
        except OSError as exc:                      # disk full, I/O error: count, keep the loop going
            self.dropped += end - start
            self.error = f"{self.path}: {exc.strerror or exc}"
        self.flushed = end

    def _run(self) -> None:
        # A thread inherits its creator's scheduling policy; the writer must never run SCHED_FIFO
        # beside the loop (it would hold the GIL and the CPU at the loop's priority while it writes).
        if os.sched_getscheduler(0) != os.SCHED_OTHER:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        while not self._stop.wait(self.interval):
            self._flush()

    def close(self) -> None:
        """Stop the thread, write every remaining record and fsync. Idempotent."""
        if self.fd < 0:
            return
        self._stop.set()
        self._thread.join()
        self._flush()
        try:
            os.fsync(self.fd)
        except OSError as exc:
            self.error = self.error or f"{self.path}: fsync: {exc.strerror or exc}"
        os.close(self.fd)
        self.fd = -1


def log_metadata(**extra: Any) -> dict[str, Any]:
    """The header's run metadata: wall-clock start (UTC, ISO 8601) plus ``extra``."""
    return {"started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), **extra}
