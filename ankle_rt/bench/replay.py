"""The daemon's own compute per cycle, without the simulated plant: what the prosthesis computer
pays (``ankle-rt bench loop``'s ``daemon_cycle_*``).

Sensor frames are first recorded from a lockstep run of the configured daemon on its simulated
backend (:class:`RecordingBackend`), then the same daemon (estimator, controller, safety layer,
loop bookkeeping, the in-memory log record) runs on a SimClock against :class:`ReplayBackend`,
whose read copies the next recorded frame and whose write does nothing. So the timed cycle does
everything the real one does but the transport's I/O and the plant.
"""

from __future__ import annotations

import gc
import statistics
import time
from typing import TYPE_CHECKING, Callable

from ankle_rt.backend import Backend, ForwardingBackend, SensorFrame, open_backend
from ankle_rt.clock import SimClock
from ankle_rt.daemon import Daemon, run_lockstep
from ankle_rt.log.memory import MemoryRecorder

if TYPE_CHECKING:
    from ankle_rt.config import Config

CHUNK = 50         # cycles per timed slice

Row = tuple[float, int, float, float, float, float, float, float]   # t, seq, motor 1/2, sg DP/IE, joint DP/IE


class RecordingBackend(ForwardingBackend):
    """Passes everything to ``inner`` and keeps each frame it reads (not for the real-time loop)."""

    def __init__(self, inner: Backend):
        super().__init__(inner)
        self.rows: list[Row] = []

    def read(self, frame: SensorFrame) -> None:
        self.inner.read(frame)
        self.rows.append((frame.t, frame.seq, *frame.values))


class ReplayBackend(Backend):
    """Reads the recorded ``rows`` in turn (the last one again once they run out: a stale sample);
    writes nothing anywhere."""

    def __init__(self, cfg: "Config", clock: SimClock, rows: list[Row]):
        super().__init__(cfg, clock)
        self.rows = rows
        self.next = 0

    def activate(self) -> None:
        pass

    def deactivate(self) -> None:
        pass

    def write(self, current_1: float, current_2: float) -> None:
        pass

    def read(self, frame: SensorFrame) -> None:
        k = self.next
        if k < len(self.rows) - 1:
            self.next = k + 1
        v = frame.values
        frame.t, frame.seq, v[0], v[1], v[2], v[3], v[4], v[5] = self.rows[k]


def record_frames(cfg: "Config", seconds: float) -> list[Row]:
    """The sensor frames of a lockstep run of ``cfg`` (its simulated backend) for ``seconds``."""
    clock = SimClock()
    recorder = RecordingBackend(open_backend(cfg, clock))
    try:
        run_lockstep(cfg, seconds, backend=recorder)
    finally:
        recorder.close()
    return recorder.rows


def daemon_cycle_s(cfg: "Config", seconds: float, repeats: int = 3) -> float:
    """Wall seconds per cycle of the daemon alone: the median of ``repeats`` runs of ``seconds``
    simulated s each on the frames of one recorded run."""
    rows = record_frames(cfg, seconds)
    return _median_cycle_s(lambda clock: ReplayBackend(cfg, clock, rows), cfg, seconds, repeats)


def lockstep_cycle_s(cfg: "Config", seconds: float, repeats: int = 3) -> float:
    """Wall seconds per cycle of the daemon with its simulated plant in lockstep, timed as
    :func:`daemon_cycle_s` times the daemon alone."""
    return _median_cycle_s(lambda clock: open_backend(cfg, clock), cfg, seconds, repeats)


def _median_cycle_s(backend: Callable[[SimClock], Backend], cfg: "Config", seconds: float, repeats: int) -> float:
    """Each repeat: a fresh daemon on a SimClock with ``backend(clock)``, recording into memory as in
    lockstep, its loop run for ``seconds`` in slices of CHUNK cycles (with the GC off, as
    :meth:`Daemon.run` runs it); the median slice over all repeats, per cycle (a slice is short
    enough that most miss the other processes of a busy machine). Not timed: building the daemon
    and the collection before the run."""
    times = []
    for _ in range(repeats):
        clock = SimClock()
        daemon = Daemon(cfg, clock, backend=backend(clock))
        daemon.recorder = MemoryRecorder(round(seconds * cfg["controller"]["rate_hz"]) + 1)
        slice_ns = CHUNK * daemon.period_ns
        gc.collect()
        gc.disable()
        try:
            for _ in range(max(1, round(seconds * 1e9) // slice_ns)):
                t0 = time.perf_counter()
                daemon.loop.run(daemon.cycle, slice_ns)
                times.append((time.perf_counter() - t0) / CHUNK)
        finally:
            gc.enable()
            daemon.close()
    return statistics.median(times)
