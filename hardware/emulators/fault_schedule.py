"""Scheduled fault injection for the hardware emulators: ``NAME@START[:STOP]`` in s of plant time.

Both emulators (serial bridge, CANopen node) take the same ``--inject`` syntax; each checks the
names against its own fault list, since the faults a transport can have differ.
"""

from __future__ import annotations

import math
from typing import Sequence

ScheduledFault = tuple[str, float, float]
"""(fault name, start s, stop s) in plant time; the fault is on for start <= t < stop."""


def parse_schedule(spec: str, faults: Sequence[str]) -> ScheduledFault:
    """``NAME@START[:STOP]`` (s of plant time; no STOP: until the end) -> (name, start, stop).

    A ValueError names the spec and the problem: bad times, a name not in ``faults``, STOP <= START."""
    name, _, times = spec.partition("@")
    try:
        start_s, _, stop_s = times.partition(":")
        start, stop = float(start_s), float(stop_s) if stop_s else math.inf
    except ValueError:
        raise ValueError(f"--inject {spec!r}: expected NAME@START[:STOP] in seconds") from None
    if name not in faults:
        raise ValueError(f"--inject {spec!r}: unknown fault {name!r} (expected one of: {', '.join(faults)})")
    if stop <= start:
        raise ValueError(f"--inject {spec!r}: STOP must be after START")
    return name, start, stop
