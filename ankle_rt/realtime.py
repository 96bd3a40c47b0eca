"""Operating-system settings for the real-time loop, each requested only when the config asks, and
each reported plainly when the OS refuses (no privileges, no RLIMIT_RTPRIO, a container).

- ``loop.realtime.priority`` > 0: SCHED_FIFO at that priority (``os.sched_setscheduler``).
- ``loop.realtime.cpus``: CPU affinity (``os.sched_setaffinity``).
- ``loop.realtime.lock_memory``: ``mlockall(MCL_CURRENT | MCL_FUTURE)`` via libc.
- ``loop.realtime.timer_slack_ns``: ``prctl(PR_SET_TIMERSLACK)``; the kernel's default 50 µs slack
  is half of the median wake-up lateness of ``clock_nanosleep`` here.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
from typing import Any, Mapping

MCL_CURRENT = 1
MCL_FUTURE = 2
PR_SET_TIMERSLACK = 29


def _libc() -> ctypes.CDLL:
    return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)


def set_timer_slack(ns: int) -> str:
    """Set this thread's timer slack (ns). Returns a one-line report."""
    try:
        if _libc().prctl(PR_SET_TIMERSLACK, ctypes.c_ulong(ns), 0, 0, 0) != 0:
            return f"timer slack {ns} ns: refused ({os.strerror(ctypes.get_errno())})"
    except (OSError, AttributeError) as exc:
        return f"timer slack {ns} ns: not available ({exc})"
    return f"timer slack {ns} ns: set"


def apply_realtime(rt: Mapping[str, Any]) -> list[str]:
    """Apply the ``loop.realtime`` settings to the calling process/thread; one report line each."""
    report = []
    if rt["timer_slack_ns"] > 0:
        report.append(set_timer_slack(rt["timer_slack_ns"]))
    if rt["cpus"]:
        cpus = set(rt["cpus"])
        try:
            os.sched_setaffinity(0, cpus)
            report.append(f"CPU affinity {sorted(cpus)}: set")
        except OSError as exc:
            report.append(f"CPU affinity {sorted(cpus)}: refused ({exc.strerror})")
    if rt["lock_memory"]:
        try:
            if _libc().mlockall(MCL_CURRENT | MCL_FUTURE) != 0:
                err = ctypes.get_errno()
                report.append(f"mlockall: refused ({os.strerror(err)}; raise LimitMEMLOCK or run with CAP_IPC_LOCK)")
            else:
                report.append("mlockall: memory locked")
        except (OSError, AttributeError) as exc:
            report.append(f"mlockall: not available ({exc})")
    if rt["priority"] > 0:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(rt["priority"]))
            report.append(f"SCHED_FIFO priority {rt['priority']}: set")
        except (OSError, AttributeError) as exc:
            why = getattr(exc, "strerror", None) or str(exc)
            report.append(f"SCHED_FIFO priority {rt['priority']}: refused ({why}; needs CAP_SYS_NICE or "
                          f"LimitRTPRIO), running with normal scheduling")
    return report
