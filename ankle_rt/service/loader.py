"""Work that may block (reading a profile file) done off the control loop's thread.

The loop thread must never open, read or wait on a file: a 12 MB CSV or a FIFO named by a command
would stall it with the motors on. :class:`BackgroundLoader` runs such jobs one at a time in a
daemon thread; the loop submits a job (a non-blocking queue put) and looks at ``Job.done`` on later
cycles (an attribute read), taking the ready result when it is there. While a job runs the
interpreter's switch interval is lowered to :data:`SWITCH_INTERVAL_S`, and a job that reads a big
file calls :func:`pause` between chunks, so that the loop thread gets the interpreter lock promptly.
"""

from __future__ import annotations

import os
import queue
import sys
import threading
import time
from typing import Any, Callable


SWITCH_INTERVAL_S = 1e-4
"""While a job runs, the interpreter switches threads at least this often (default 5 ms): the loop
thread, waking for its next cycle, never waits longer than this for the interpreter lock."""


def pause() -> None:
    """Give the interpreter lock away briefly (between chunks of a long job)."""
    time.sleep(0.0002)


def normal_scheduling() -> None:
    """Put the calling thread (or process) under normal scheduling: a thread started by a SCHED_FIFO
    loop thread inherits its real-time policy, and must not compete with the loop at its priority."""
    try:
        if os.sched_getscheduler(0) != os.SCHED_OTHER:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (OSError, AttributeError):   # not Linux, or not permitted: nothing to undo then
        pass


class Job:
    """One submitted job: ``done`` turns True once ``result`` (or ``error``, the exception) is set."""

    __slots__ = ("fn", "done", "result", "error", "what")

    def __init__(self, fn: Callable[[], Any], what: str):
        self.fn = fn
        self.what = what
        self.done = False
        self.result: Any = None
        self.error: BaseException | None = None


class BackgroundLoader:
    """A single worker thread, started on first use, running submitted jobs in order."""

    def __init__(self, name: str = "ankle-rt-loader"):
        self.name = name
        self._queue: "queue.SimpleQueue[Job | None]" = queue.SimpleQueue()
        self._thread: threading.Thread | None = None
        self.busy: Job | None = None
        """The job submitted last while it is not done yet (one at a time: the caller checks this)."""

    def submit(self, fn: Callable[[], Any], what: str) -> Job:
        """Queue ``fn`` (never blocks); returns its Job."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._work, name=self.name, daemon=True)
            self._thread.start()
        job = Job(fn, what)
        self.busy = job
        self._queue.put(job)
        return job

    def pending(self) -> Job | None:
        """The job still running, if any."""
        job = self.busy
        if job is not None and job.done:
            self.busy = job = None
        return job

    def _work(self) -> None:
        normal_scheduling()
        while True:
            job = self._queue.get()
            if job is None:
                return
            switch = sys.getswitchinterval()
            sys.setswitchinterval(min(switch, SWITCH_INTERVAL_S))
            try:
                job.result = job.fn()
            except BaseException as exc:   # reported to whoever waits for the job, never lost
                job.error = exc
            finally:
                sys.setswitchinterval(switch)
            job.done = True

    def close(self, timeout_s: float = 1.0) -> None:
        """Stop the worker after its current job (waits at most ``timeout_s``; it is a daemon thread)."""
        if self._thread is not None:
            self._queue.put(None)
            self._thread.join(timeout_s)
            self._thread = None
