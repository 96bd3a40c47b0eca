"""The fixed-rate loop: absolute deadlines on a :class:`~ankle_rt.clock.Clock`, and the overrun policy.

Deadlines lie on a fixed grid ``start + k * period`` (integer ns); the loop never sleeps for a
relative period, so timing errors do not accumulate. The same loop runs on the monotonic clock (real
time) and on a :class:`~ankle_rt.clock.SimClock` (lockstep, as fast as the CPU allows).

Overrun policy. A cycle *overruns* when it ends after the next deadline. Every overrun is counted.
The missed deadlines are skipped, not caught up: the next cycle starts at the first grid point after
the overrun ended (a burst of back-to-back cycles would only make the control worse, and the
backend's sample time tells the estimator how much time passed). After
``max_consecutive_overruns`` overruns in a row, or overruns in a row whose missed deadlines add up to
more than ``max_stall_ns`` (one long stall, or a cycle that takes a little less every time), the loop
reports it (``on_overrun_limit``; the daemon trips the MISSED_DEADLINES fault) and carries on in the
safe state, so the log keeps recording. A short stall (a VM hiccup of a few periods) is one overrun
however many deadlines it covers; a loop that stood still for a second with the motors on must not
just carry on from a stale state.
"""

from __future__ import annotations

from typing import Callable

from ankle_rt.clock import Clock
from ankle_rt.loop_stats import LoopStats


class FixedRateLoop:
    def __init__(self, clock: Clock, period_ns: int, max_consecutive_overruns: int,
                 on_overrun_limit: Callable[[], None] | None = None, max_stall_ns: int | None = None):
        self.clock = clock
        self.max_stall_ns = max_stall_ns
        self.period_ns = period_ns
        self.max_consecutive = max_consecutive_overruns
        self.on_overrun_limit = on_overrun_limit
        self.stats = LoopStats(period_ns)
        self.consecutive_overruns = 0
        self.missed_ns = 0                # ns of deadlines the overruns in a row have missed
        self.last_period_ns = 0
        self.stop_requested = False
        self.start_ns = 0
        self._next_deadline: int | None = None
        self._last_start = -1             # start of the previous cycle (ns), -1 before the first

    def stop(self) -> None:
        """Ask the loop to return after the current cycle (signal-handler safe)."""
        self.stop_requested = True

    def run(self, cycle: Callable[[int], None], duration_ns: int | None = None) -> None:
        """Call ``cycle(start_ns)`` at every deadline until stopped or ``duration_ns`` has passed
        (deadlines at start + k * period for k * period < duration). Calling run again continues
        on the same deadline grid (tests drive a daemon in slices this way)."""
        clock, period, stats = self.clock, self.period_ns, self.stats
        if self._next_deadline is None:        # first run: the grid starts now
            deadline = self.start_ns = clock.now_ns()
        else:                                  # a later run continues the same grid
            deadline = self._next_deadline
        end = deadline + duration_ns if duration_ns is not None else None
        last_start = self._last_start
        while not self.stop_requested and (end is None or deadline < end):
            clock.sleep_until(deadline)
            t_start = clock.now_ns()
            self.last_period_ns = t_start - last_start if last_start >= 0 else 0
            last_start = t_start
            cycle(t_start)
            t_end = clock.now_ns()
            stats.add(self.last_period_ns, t_end - t_start)
            steps = -(-(t_end - deadline) // period)    # grid points up to and including t_end
            if steps > 1:                                # overrun: skip the deadlines already passed
                stats.overruns += 1
                stats.skipped += steps - 1
                deadline += steps * period
                self.consecutive_overruns += 1
                before = self.missed_ns
                self.missed_ns = missed = before + (steps - 1) * period
                stalled = self.max_stall_ns is not None and missed > self.max_stall_ns >= before   # crossed now
                if (self.consecutive_overruns == self.max_consecutive or stalled) and self.on_overrun_limit is not None:
                    self.on_overrun_limit()
            else:
                deadline += period
                self.consecutive_overruns = 0
                self.missed_ns = 0
            self._next_deadline = deadline
            self._last_start = last_start
