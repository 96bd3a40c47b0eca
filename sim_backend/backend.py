"""The simulated backend: the daemon's view of :class:`~sim_backend.plant.SimulatedPlant`.

``read`` first advances the plant to the clock's time in whole control ticks, with the last set
values held, then samples its sensors. Under a :class:`~ankle_rt.clock.SimClock` that is exactly one
tick per cycle (lockstep); under the real clock, cycles the loop skipped still pass for the plant.
The tick grid is anchored half a period before the first read, so a loop on the same period never
sees its wake-up jitter as a repeated or skipped sample.
"""

from __future__ import annotations

from ankle_rt.backend import Backend, BackendFault, SensorFrame
from ankle_rt.clock import Clock
from ankle_rt.config import Config
from sim_backend.plant import SimulatedPlant

MAX_CATCH_UP_TICKS = 1000


class SimBackend(Backend):
    name = "sim"
    simulated_plant = True

    def __init__(self, cfg: Config, clock: Clock):
        super().__init__(cfg, clock)
        self.plant = SimulatedPlant(cfg, getattr(cfg, "source", "config"))
        self.period_ns = round(1e9 / cfg["controller"]["rate_hz"])
        self.start_ns: int | None = None  # ns, the tick grid's origin, set at the first read
        self.active = False
        self.set_values = [0.0, 0.0]
        self.injected = BackendFault.NONE  # faults a test or tool injects into the samples

    def activate(self) -> None:
        self.set_values[0] = self.set_values[1] = 0.0
        self.active = True

    def deactivate(self) -> None:
        self.set_values[0] = self.set_values[1] = 0.0
        self.active = False

    def write(self, current_1: float, current_2: float) -> None:
        if self.active:
            self.set_values[0] = current_1
            self.set_values[1] = current_2

    def read(self, frame: SensorFrame) -> None:
        plant = self.plant
        now = self.clock.now_ns()
        if self.start_ns is None:
            # Put the tick grid half a period before the first read: a loop reading on its own
            # period then always lands mid-tick, so wake-up jitter (< period / 2) never repeats or
            # skips a sample. The plant's time starts at this first read.
            self.start_ns = now - self.period_ns // 2
        due = (now - self.start_ns) // self.period_ns
        todo = due - plant.ticks
        if todo > MAX_CATCH_UP_TICKS:
            todo = MAX_CATCH_UP_TICKS
        while todo > 0:       # usually once (lockstep): no range object or min() call per cycle
            plant.step(self.set_values[0], self.set_values[1])
            todo -= 1
        frame.t = plant.t
        frame.seq = plant.ticks
        v = frame.values   # [motor 1, motor 2, sg DP, sg IE, ankle DP, ankle IE], set as plain floats
        v[0], v[1] = plant.motor_positions()
        v[2], v[3] = plant.strain_gauge_torques()
        v[4], v[5] = plant.ankle_positions()
        injected = self.injected   # usually NONE: skip the flag arithmetic (~0.5 us per IntFlag "&")
        ready = not (injected and injected & BackendFault.AMP_NOT_READY)
        frame.amp_ready[0] = frame.amp_ready[1] = ready
        frame.faults = self.injected
