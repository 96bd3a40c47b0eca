"""Time sources for the loop: the real monotonic clock, and a simulated one for lockstep runs.

Both count integer nanoseconds. ``sleep_until`` takes an absolute deadline: the loop never sleeps
for a relative period, so errors do not accumulate. With :class:`SimClock` sleeping just moves time
forward, so the same loop runs as fast as the CPU allows and gives the same result on any machine.
"""

from __future__ import annotations

import time
from typing import Protocol


class Clock(Protocol):
    simulated: bool

    def now_ns(self) -> int: ...

    def sleep_until(self, deadline_ns: int) -> None: ...


class MonotonicClock:
    """CLOCK_MONOTONIC. Sleeps until ``spin_ns`` before the deadline, then spins: the kernel's
    wake-up lateness (~100 µs here, half of it timer slack) becomes sub-microsecond for a few % CPU."""

    simulated = False

    def __init__(self, spin_ns: int = 200_000):
        self.spin_ns = spin_ns

    def now_ns(self) -> int:
        return time.monotonic_ns()

    def sleep_until(self, deadline_ns: int) -> None:
        remaining = deadline_ns - time.monotonic_ns() - self.spin_ns
        if remaining > 0:
            time.sleep(remaining * 1e-9)
        while time.monotonic_ns() < deadline_ns:
            pass


class SimClock:
    """Simulated time that advances only when the loop sleeps (lockstep)."""

    simulated = True

    def __init__(self, start_ns: int = 0):
        self._now = start_ns

    def now_ns(self) -> int:
        return self._now

    def sleep_until(self, deadline_ns: int) -> None:
        if deadline_ns > self._now:
            self._now = deadline_ns

    def advance(self, dt_ns: int) -> None:
        """Let simulated time pass, as if a cycle's computation took ``dt_ns``."""
        self._now += dt_ns
