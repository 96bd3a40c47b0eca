"""Preallocated log ring and its writer thread, which also rotates the log and keeps it in bounds.

The loop packs each cycle's record (with its CRC) into the next slot of a ``bytearray`` ring (no
allocation, no I/O). A writer thread wakes every ``logging.flush_interval_s`` and hands whole ring
slices to ``os.write`` (which releases the GIL), so it does almost no Python work per record and
never competes with the loop for long. Records reach the kernel within one flush interval and
survive a kill -9 of the daemon; ``close()`` writes the rest and fsyncs.

Rotation and retention run in the same thread, between two writes: when the file would grow past
``rotate_size_bytes`` or has been open ``rotate_interval_s``, it is fsynced and closed, the next part
is opened with its own header (each part is a complete log), and the oldest logs beyond
``keep_files`` are deleted. No record falls between two parts. If the disk stalls for longer than
the ring holds, records are dropped and counted; if a write fails (disk full, I/O error), logging
stops for the rest of the run with the reason in :meth:`LogWriter.status` (``failed``), and every
later record is counted as dropped. The loop is never delayed.

A ``tap`` (the Lab Streaming Layer publisher, :mod:`ankle_rt.log.lsl`) is opened in the same thread
and handed each flush's records, whether or not the file still takes them; a tap that raises is
dropped with its reason in its ``error``, and logging goes on.
"""

from __future__ import annotations

import glob
import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from ankle_rt.log.header import HEADER_SIZE, encode_header
from ankle_rt.log.record import RECORD_SIZE, RecordRing


class RecordTap(Protocol):
    """Something else the writer thread hands the records to (e.g. the LSL publisher)."""

    error: str

    def open(self) -> None:
        """Called once in the writer thread before the first records."""

    def publish(self, chunk: memoryview) -> None:
        """Whole records of one flush as ring bytes (RECORD_SIZE each, oldest first), valid only during
        the call (the loop reuses the slots)."""

    def close(self) -> None:
        """Called once at the end (or when it failed)."""


@dataclass(frozen=True)
class Rotation:
    """When to start a new log file and how many to keep (0 = no limit)."""

    size_bytes: int = 0          # rotate before the file would grow past this (header included)
    interval_s: float = 0.0      # rotate after the file has been open this long
    keep_files: int = 0          # logs kept (the current one counted); the oldest are deleted
    keep_days: float = 0.0       # logs last written longer ago than this are deleted
    pattern: str = ""            # which files of the directory count (glob); "": this log's parts

    @classmethod
    def from_config(cls, logging: dict[str, Any], pattern: str = "") -> "Rotation":
        """From the config's ``logging`` section (``rotate_size_mb``, ``rotate_interval_s``,
        ``keep_files``, ``keep_days``)."""
        return cls(size_bytes=int(logging["rotate_size_mb"] * 1e6), interval_s=float(logging["rotate_interval_s"]),
                   keep_files=int(logging["keep_files"]), keep_days=float(logging["keep_days"]), pattern=pattern)


def part_path(first: Path, part: int) -> Path:
    """Part ``part`` of the log that started as ``first``: the first itself, then STEM.0001.arlog, ..."""
    return first if part == 0 else first.with_name(f"{first.stem}.{part:04d}{first.suffix}")


class LogWriter:
    """Ring of ``capacity`` records plus the thread that appends them to ``path`` (and its next parts)."""

    def __init__(self, path: str | Path, meta: dict[str, Any], capacity: int = 16384,
                 flush_interval_s: float = 0.05, rotation: Rotation | None = None, tap: RecordTap | None = None):
        self.first_path = self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.meta = dict(meta)
        self.rotation = rotation or Rotation()
        self.ring = RecordRing(capacity)
        self.capacity = capacity
        self.pack = self.ring.pack
        self.tap = tap
        self.written = 0     # records packed by the loop (only the loop writes this)
        self.flushed = 0     # records handed to the kernel or dropped (only the writer thread writes this)
        self.dropped = 0
        self.error = ""      # why logging failed ("" while it works)
        self.failed = False  # a write failed: logging stopped for the rest of the run
        self.part = 0
        self.deleted: list[str] = []    # logs removed by retention, oldest first
        self.interval = flush_interval_s
        self.fd = -1
        self._closed = False
        self._open_part(0)   # raises OSError here, before the run, when the log cannot be created
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="ankle-rt-log", daemon=True)
        self._thread.start()

    def append(self, *values: Any) -> None:
        """Pack one record into the ring (the loop's only logging work). Values in FIELDS order."""
        n = self.written
        self.pack(n % self.capacity, values)
        self.written = n + 1

    # -- the writer thread --------------------------------------------------------------------------
    def _open_part(self, first_record: int) -> None:
        path = part_path(self.first_path, self.part)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            header = encode_header({**self.meta, "part": self.part, "first_record": first_record,
                                    "first_part": self.first_path.name,
                                    "part_started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())})
            _write_all(fd, memoryview(header))
        except OSError:
            os.close(fd)
            path.unlink(missing_ok=True)    # a header cut short (disk full) would be a file no reader takes
            raise
        self.fd, self.path = fd, path
        self.file_bytes = HEADER_SIZE
        self.opened = time.monotonic()
        self._retain()

    def _rotation_due(self) -> bool:
        rot = self.rotation
        return ((rot.size_bytes > 0 and self.file_bytes + RECORD_SIZE > rot.size_bytes
                 and self.file_bytes > HEADER_SIZE)
                or (rot.interval_s > 0 and time.monotonic() - self.opened >= rot.interval_s))

    def _rotate(self, next_record: int) -> None:
        os.fsync(self.fd)
        os.close(self.fd)
        self.fd = -1
        self.part += 1
        self._open_part(next_record)

    def _retain(self) -> None:
        """Delete the oldest logs beyond ``keep_files`` and those older than ``keep_days`` (never the
        current one). Which files count: ``rotation.pattern`` in the log's directory, else this log's parts."""
        keep, days = self.rotation.keep_files, self.rotation.keep_days
        if keep <= 0 and days <= 0:
            return
        first = self.first_path
        patterns = ([self.rotation.pattern] if self.rotation.pattern else
                    [glob.escape(first.name), f"{glob.escape(first.stem)}.[0-9][0-9][0-9][0-9]{glob.escape(first.suffix)}"])
        found = {}
        for pattern in patterns:
            for p in first.parent.glob(pattern):
                try:
                    found[p] = p.stat().st_mtime_ns
                except OSError:     # deleted meanwhile
                    continue
        old = sorted((mtime, p.name, p) for p, mtime in found.items() if p != self.path)
        excess = max(0, len(old) - (keep - 1)) if keep > 0 else 0
        cutoff = time.time_ns() - int(days * 86400e9) if days > 0 else 0
        for k, (mtime, _, p) in enumerate(old):
            if k >= excess and mtime >= cutoff:
                continue
            try:
                p.unlink()
                self.deleted.append(p.name)
            except OSError:
                pass                # not ours to delete (permissions) or gone: keep logging

    def _room(self) -> int:
        """Records that still fit into the current part (at least 1: a part holds one record or more)."""
        size = self.rotation.size_bytes
        if size <= 0:
            return 1 << 62
        return max(1, (size - self.file_bytes) // RECORD_SIZE)

    def _flush(self) -> None:
        end = self.written
        start = self.flushed
        cap = self.capacity
        # keep a margin: the loop may be packing slot `end` right now
        if end - start > cap - 1:
            self.dropped += end - start - (cap - 1)
            start = end - (cap - 1)
        if self.tap is not None and start < end:
            self._publish(start, end)
        if self.failed:
            self.dropped += end - start
            self.flushed = end
            return
        view = self.ring.view
        try:
            while start < end:
                if self._rotation_due():
                    self._rotate(start)
                i = start % cap
                n = min(end - start, cap - i, self._room())
                _write_all(self.fd, view[i * RECORD_SIZE:(i + n) * RECORD_SIZE])
                self.file_bytes += n * RECORD_SIZE
                start += n
        except (OSError, ValueError) as exc:        # disk full, I/O error: stop logging, keep the loop going
            self.dropped += end - start
            self.failed = True
            self.error = f"{self.path}: {getattr(exc, 'strerror', None) or exc}"
        self.flushed = end

    def _publish(self, start: int, end: int) -> None:
        """Hand records [start, end) to the tap as ring bytes: one slice, or two where the ring wraps."""
        cap, view = self.capacity, self.ring.view
        i = start % cap
        n = min(end - start, cap - i)
        self._tap_call(self.tap.publish, view[i * RECORD_SIZE:(i + n) * RECORD_SIZE])
        if n < end - start and self.tap is not None:
            self._tap_call(self.tap.publish, view[:(end - start - n) * RECORD_SIZE])

    def _tap_call(self, method, *args: Any) -> None:
        """Call a tap method; one that raises is closed and dropped, its reason in its ``error``."""
        tap = self.tap
        try:
            method(*args)
        except Exception as exc:   # a tap's library may raise anything: it must not stop the log
            tap.error = f"{type(exc).__name__}: {exc}"
            self.tap = None
            try:
                tap.close()
            except Exception:
                pass

    def _run(self) -> None:
        # A thread inherits its creator's scheduling policy; the writer must never run SCHED_FIFO
        # beside the loop (it would hold the GIL and the CPU at the loop's priority while it writes).
        if os.sched_getscheduler(0) != os.SCHED_OTHER:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        if self.tap is not None:   # here, so that threads the tap starts get normal scheduling too
            self._tap_call(self.tap.open)
        while not self._stop.wait(self.interval):
            self._flush()

    def status(self) -> dict[str, Any]:
        """For ``ctl status`` and the run summary: where the log goes and whether it still does."""
        return {"state": "failed" if self.failed else ("closed" if self._closed else "writing"),
                "error": self.error, "path": str(self.path), "part": self.part,
                "records": self.flushed - self.dropped, "dropped": self.dropped, "deleted_files": len(self.deleted)}

    def close(self) -> None:
        """Stop the thread, write every remaining record and fsync. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self._thread.join()
        self._flush()
        if self.tap is not None:
            self._tap_call(self.tap.close)
        if self.fd < 0:          # a rotation failed half-way: nothing open
            return
        try:
            os.fsync(self.fd)
        except OSError as exc:
            self.failed = True
            self.error = self.error or f"{self.path}: fsync: {exc.strerror or exc}"
        os.close(self.fd)
        self.fd = -1


def _write_all(fd: int, chunk: memoryview) -> None:
    while chunk:                        # os.write may write less than asked
        chunk = chunk[os.write(fd, chunk):]


def log_metadata(**extra: Any) -> dict[str, Any]:
    """The header's run metadata: wall-clock start (UTC, ISO 8601 and Unix time in s) plus ``extra``."""
    now = time.time()
    return {"started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(now)), "started_unix_s": now, **extra}
