"""Whether a daemon is talking to a standalone emulator (``ankle-rt emulate``): one line when one
starts and one when it has gone quiet, so the person at the bench sees each daemon come and go."""

from __future__ import annotations

import math
import sys
import time
from typing import Callable, TextIO

GONE_S = 1.0   # s without a message from the daemon before it counts as gone (a run's end, a crash)


class Presence:
    """Follows the emulator's running count of the daemon's messages (``what``: commands, SYNCs)."""

    def __init__(self, what: str, *, gone_s: float = GONE_S, stream: TextIO | None = None,
                 clock: Callable[[], float] = time.monotonic):
        self.what, self.gone_s, self.clock = what, gone_s, clock
        self.stream = stream if stream is not None else sys.stdout
        self.start = clock()
        self.count = 0
        self.last = -math.inf
        self.connected = False
        self.sessions = 0

    def update(self, count: int, now: float) -> None:
        """Call in the serving loop with the current count and monotonic time (s)."""
        if count != self.count:
            self.count, self.last = count, now
            if not self.connected:
                self.connected = True
                self.sessions += 1
                self._say(f"daemon connected ({self.what} arriving)", now)
        elif self.connected and now - self.last > self.gone_s:
            self.connected = False
            self._say(f"daemon gone (no {self.what} for {self.gone_s:g} s)", now)

    def _say(self, text: str, now: float) -> None:
        print(f"emulator: {text} at {now - self.start:.1f} s", file=self.stream, flush=True)


def until_text(duration_s: float) -> str:
    """How the standalone emulator ends, for its start-up line."""
    return f"stops after {duration_s:g} s or on Ctrl-C" if duration_s else "Ctrl-C stops"
