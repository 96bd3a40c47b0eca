"""Progress of long commands: a bar with the elapsed time and an ETA on a terminal, nothing otherwise.

Written to stderr, so ``--json`` output and pipes stay clean; when stderr is not a TTY (CI, a log
file, systemd's journal) it prints nothing at all. Redraws are limited to a few per second, so a
tight loop can call :meth:`Progress.update` freely. Commands hand :meth:`Progress.callback` to the
library functions that take a ``progress(done, total, what)`` hook.
"""

from __future__ import annotations

import sys
import time
from typing import Callable, TextIO

BAR_WIDTH = 24
REDRAW_S = 0.2

ProgressHook = Callable[[float, float, str], None]


def _clock_text(seconds: float) -> str:
    seconds = max(0, round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class Progress:
    """One progress bar for ``total`` units of work (any unit: runs, simulated s, stages).

    ``stream``: where to draw (default stderr); ``enabled``: default ``stream.isatty()``;
    ``clock``: a monotonic time source in s (tests pass their own).
    """

    def __init__(self, label: str, total: float, *, stream: TextIO | None = None, enabled: bool | None = None,
                 clock: Callable[[], float] = time.monotonic):
        self.label = label
        self.total = float(total)
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = _isatty(self.stream) if enabled is None else enabled
        self.clock = clock
        self.start = clock()
        self.done = 0.0
        self.what = ""
        self._last_draw = -float("inf")
        self._width = 0

    def update(self, done: float, what: str = "") -> None:
        """``done`` units finished so far; ``what`` names the current step."""
        self.done = min(max(float(done), 0.0), self.total) if self.total > 0 else 0.0
        self.what = what or self.what
        now = self.clock()
        if self.enabled and (now - self._last_draw >= REDRAW_S or self.done >= self.total):
            self._last_draw = now
            self._draw(now)

    def callback(self, done: float, total: float, what: str = "") -> None:
        """The ``progress(done, total, what)`` hook that library functions call."""
        self.total = float(total)
        self.update(done, what)

    def line(self, now: float) -> str:
        """The text of the bar at time ``now``."""
        frac = self.done / self.total if self.total > 0 else 0.0
        filled = round(frac * BAR_WIDTH)
        elapsed = now - self.start
        eta = _clock_text(elapsed * (1.0 - frac) / frac) if frac > 0 else "?"
        text = (f"{self.label} [{'#' * filled}{'.' * (BAR_WIDTH - filled)}] {100 * frac:3.0f}% "
                f"{_clock_text(elapsed)} elapsed, ETA {eta}")
        return f"{text}  {self.what}" if self.what else text

    def _draw(self, now: float) -> None:
        text = self.line(now)
        pad = " " * max(0, self._width - len(text))
        self._width = len(text)
        try:
            self.stream.write(f"\r{text}{pad}")
            self.stream.flush()
        except (OSError, ValueError):   # the terminal went away: progress is not worth a crash
            self.enabled = False

    def close(self) -> None:
        """Clear the bar (the command's own output follows on a clean line)."""
        if self.enabled and self._width:
            try:
                self.stream.write("\r" + " " * self._width + "\r")
                self.stream.flush()
            except (OSError, ValueError):
                pass
        self.enabled = False

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _isatty(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False
