"""Round-trip timing of a hardware backend over its in-process lockstep emulator, shared by
bench_serial.py and bench_canopen.py (imported as a sibling module: run them as scripts).

One cycle is what the daemon does with the backend: ``read`` then ``write`` (a 0.5 A square wave on
motor 1, 0.3 A on motor 2), with the SimClock advanced by a period. The time spent inside the
emulator is measured by wrapping the emulator method the link calls into (so the rest is the
backend's side plus the link). Timing is noisy on shared cores: percentiles over all cycles, best
and median of the repeats.
"""

from __future__ import annotations

import statistics
import time
from typing import Callable

from ankle_rt.backend import Backend, SensorFrame
from ankle_rt.clock import SimClock

Row = tuple[float, float, float, float]   # s: p50, p99, max round trip; emulator time per cycle


def round_trips(backend: Backend, clock: SimClock, emulator_entry: str, cycles: int) -> tuple[list[float], float]:
    """Per-cycle round trips (s) and the total time spent inside the emulator's ``emulator_entry``
    method (s); closes the backend."""
    emulator = backend.emulator
    inside = [0.0]
    entry = getattr(emulator, emulator_entry)

    def timed(*args: object) -> None:
        t0 = time.perf_counter()
        entry(*args)
        inside[0] += time.perf_counter() - t0

    setattr(emulator, emulator_entry, timed)
    frame = SensorFrame()
    backend.activate()
    rtt = []
    for k in range(cycles):
        t0 = time.perf_counter()
        backend.read(frame)
        backend.write(0.5 if (k // 200) % 2 else -0.5, 0.3)
        rtt.append(time.perf_counter() - t0)
        clock.advance(backend.period_ns)
    backend.close()
    return rtt, inside[0]


def pct(values: list[float], q: float) -> float:
    """The ``q`` quantile (0..1) of ``values``, nearest rank."""
    s = sorted(values)
    return s[min(len(s) - 1, int(q * len(s)))]


def timed_repeats(open_lockstep: Callable[[int, SimClock], Backend], emulator_entry: str, cycles: int,
                  repeats: int) -> list[Row]:
    """One :data:`Row` per repeat; ``open_lockstep(repeat, clock)`` opens a fresh backend."""
    rows = []
    for r in range(repeats):
        clock = SimClock()
        rtt, inside = round_trips(open_lockstep(r, clock), clock, emulator_entry, cycles)
        rows.append((statistics.median(rtt), pct(rtt, 0.99), max(rtt), inside / cycles))
    return rows


def print_table(rows: list[Row], rest: str) -> None:
    """µs per cycle, best and median over the repeats; ``rest`` labels round trip minus emulator."""
    width = max(9, len(rest) + 2)
    print(f"{'':>8}{'p50':>9}{'p99':>9}{'max':>9}{'emulator':>10}{rest:>{width}}")
    for name, pick in (("best", min), ("median", statistics.median)):
        p50, p99, mx, emu = (pick(r[i] for r in rows) for i in range(4))
        print(f"{name:>8}{p50 * 1e6:>9.0f}{p99 * 1e6:>9.0f}{mx * 1e6:>9.0f}{emu * 1e6:>10.0f}{(p50 - emu) * 1e6:>{width}.0f}")
