"""Period and compute-time statistics of the fixed-rate loop, in preallocated histograms.

Each cycle adds one count to a 1-µs-bin histogram (up to ``MAX_US``, plus an overflow bin) and
updates an exact maximum: O(1) work, no allocation, and percentiles over the whole run at any time
(p50/p99/p99.9 to 1 µs resolution), cheap enough to answer a status request from inside the loop.
"""

from __future__ import annotations

from array import array

import numpy as np

MAX_US = 100_000   # histogram range; slower values land in the overflow bin (their max is exact)


class Histogram:
    """Counts of integer microsecond values."""

    def __init__(self, max_us: int = MAX_US):
        # array('q') increments cost a fraction of a numpy element update; numpy reads the same
        # memory (no copy) when percentiles are asked for.
        self.bins = array("q", bytes(8 * (max_us + 2)))
        self.counts = np.frombuffer(self.bins, dtype=np.int64)
        self.top = max_us + 1
        self.n = 0
        self.max_ns = 0

    def add_ns(self, value_ns: int) -> None:
        if value_ns > self.max_ns:
            self.max_ns = value_ns
        us = value_ns // 1000
        self.bins[us if us < self.top else self.top] += 1
        self.n += 1

    def percentile_us(self, q: float, cumulative: np.ndarray | None = None) -> float:
        """The q-th percentile (0-100) in µs (bin upper edge), NaN when empty. ``cumulative``:
        :meth:`cumulative` computed once for several percentiles."""
        if self.n == 0:
            return float("nan")
        rank = q / 100.0 * self.n
        cum = self.cumulative() if cumulative is None else cumulative
        idx = int(np.searchsorted(cum, max(rank, 1), side="left"))
        if idx >= self.top:
            return self.max_ns / 1000.0
        return min(float(idx + 1), self.max_ns / 1000.0)

    def cumulative(self) -> np.ndarray:
        """Cumulative counts up to the bin of the maximum (the bins above it are empty): a status
        request costs microseconds, not the milliseconds of a cumsum over all 100 001 bins."""
        return np.cumsum(self.counts[:min(self.max_ns // 1000, self.top) + 1])

    def summary(self) -> dict[str, float]:
        cum = self.cumulative()
        return {"p50_us": self.percentile_us(50, cum), "p99_us": self.percentile_us(99, cum),
                "p99.9_us": self.percentile_us(99.9, cum), "max_us": self.max_ns / 1000.0, "n": self.n}


class LoopStats:
    """Timing of the loop: period error |period - nominal|, compute time, overruns and skips."""

    def __init__(self, period_ns: int):
        self.period_ns = period_ns
        self.period_error = Histogram()
        self.compute = Histogram()
        self.overruns = 0          # cycles that ended after the next deadline
        self.skipped = 0           # deadlines skipped because of overruns
        self.late = 0              # cycles that started more than 2 periods after the previous one
        self.cycles = 0

    def add(self, period_ns: int, compute_ns: int) -> None:
        """One cycle: its start-to-start period (0 for the first cycle) and its compute time."""
        self.cycles += 1
        if period_ns > 0:
            err = period_ns - self.period_ns
            self.period_error.add_ns(err if err >= 0 else -err)
            if period_ns > 2 * self.period_ns:
                self.late += 1
        self.compute.add_ns(compute_ns)

    def summary(self) -> dict[str, object]:
        return {"cycles": self.cycles, "overruns": self.overruns, "skipped_cycles": self.skipped,
                "late_cycles": self.late, "period_error": self.period_error.summary(),
                "compute": self.compute.summary()}
