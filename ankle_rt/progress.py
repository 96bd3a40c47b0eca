"""Progress of long commands: a bar with the elapsed time and an ETA on a terminal, periodic lines otherwise.

Written to stderr, so ``--json`` output and pipes stay clean. When stderr is not a TTY (CI, a log
file, systemd's journal) it prints one plain line every LINE_S s instead of a bar (from a small
thread, so a long step between two updates still shows), so a command that ends sooner prints
nothing extra and a long one never looks hung. Redraws are limited to a few per
second, so a tight loop can call :meth:`Progress.update` freely. Commands hand
:meth:`Progress.callback` to the library functions that take a ``progress(done, total, what)`` hook.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Callable, TextIO

BAR_WIDTH = 24
REDRAW_S = 0.2
LINE_S = 5.0   # s between the plain progress lines written where stderr is not a terminal

ProgressHook = Callable[[float, float, str], None]


def _clock_text(seconds: float) -> str:
    seconds = max(0, round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class Progress:
    """One progress bar for ``total`` units of work (any unit: runs, simulated s, stages).

    ``stream``: where to draw (default stderr); ``enabled``: None (default) a bar on a terminal and
    a line every LINE_S s elsewhere, True a bar, False nothing; ``clock``: a monotonic time source
    in s (tests pass their own); ``poll``: returns the units done so far, read a few times a second
    by a small thread (for work that cannot report itself).
    """

    def __init__(self, label: str, total: float, *, stream: TextIO | None = None, enabled: bool | None = None,
                 clock: Callable[[], float] = time.monotonic, poll: Callable[[], float] | None = None):
        self.label = label
        self.total = float(total)
        self.stream = stream if stream is not None else sys.stderr
        self.bar = _isatty(self.stream) if enabled is None else enabled
        self.lines = enabled is None and not self.bar
        self.enabled = self.bar or self.lines
        self.clock = clock
        self.poll = poll
        self.start = clock()
        self.done = 0.0
        self.what = ""
        self._last_draw = -float("inf") if self.bar else self.start
        self._width = 0
        self._lock = threading.Lock()
        self._closed = threading.Event()
        ticks = self.lines or (self.bar and poll is not None)
        self._ticker = threading.Thread(target=self._tick, name="progress", daemon=True) if ticks else None
        if self._ticker is not None:
            self._ticker.start()

    def update(self, done: float, what: str = "") -> None:
        """``done`` units finished so far; ``what`` names the current step."""
        self.done = min(max(float(done), 0.0), self.total) if self.total > 0 else 0.0
        self.what = what or self.what
        now = self.clock()
        with self._lock:
            if self.bar and (now - self._last_draw >= REDRAW_S or self.done >= self.total):
                self._last_draw = now
                self._draw(now)
            elif self.lines and now - self._last_draw >= LINE_S:
                self._last_draw = now
                self._write(self.line(now, bar=False) + "\n")

    def _tick(self) -> None:
        """The ticker thread: redraws between updates (``poll`` says how far the work is, for work
        that cannot call :meth:`update` itself, such as a lockstep run)."""
        while not self._closed.wait(REDRAW_S if self.bar else LINE_S / 5):
            self.update(self.poll() if self.poll is not None else self.done)

    def callback(self, done: float, total: float, what: str = "") -> None:
        """The ``progress(done, total, what)`` hook that library functions call."""
        self.total = float(total)
        self.update(done, what)

    def line(self, now: float, bar: bool = True) -> str:
        """The text of the bar (``bar`` False: of a plain line) at time ``now``."""
        frac = self.done / self.total if self.total > 0 else 0.0
        filled = round(frac * BAR_WIDTH)
        elapsed = now - self.start
        eta = _clock_text(elapsed * (1.0 - frac) / frac) if frac > 0 else "?"
        drawn = f" [{'#' * filled}{'.' * (BAR_WIDTH - filled)}]" if bar else ":"
        text = f"{self.label}{drawn} {100 * frac:3.0f}% {_clock_text(elapsed)} elapsed, ETA {eta}"
        return f"{text}  {self.what}" if self.what else text

    def _draw(self, now: float) -> None:
        text = self.line(now)
        pad = " " * max(0, self._width - len(text))
        self._width = len(text)
        self._write(f"\r{text}{pad}")

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):   # the terminal went away: progress is not worth a crash
            self.bar = self.lines = self.enabled = False

    def close(self) -> None:
        """Stop the ticker and clear the bar (the command's own output follows on a clean line)."""
        self._closed.set()
        if self._ticker is not None and self._ticker is not threading.current_thread():
            self._ticker.join()
        with self._lock:
            if self.bar and self._width:
                self._write("\r" + " " * self._width + "\r")
            self.bar = self.lines = self.enabled = False

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _isatty(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False
