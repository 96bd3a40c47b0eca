"""Helpers for the daemon tests: config variants, a fault-injecting backend around the simulator,
and running a Daemon cycle by cycle on a SimClock."""

from __future__ import annotations

import tracemalloc
from typing import Callable

from ankle_rt.backend import Backend, SensorFrame
from ankle_rt.clock import SimClock
from ankle_rt.config import Config
from ankle_rt.daemon import Daemon
from ankle_rt.log.memory import MemoryRecorder
from sim_backend.backend import SimBackend


def traced_memory(run: Callable[[], None]) -> tuple[int, int]:
    """(current, peak) bytes Python allocated while ``run()`` ran (tracemalloc): for the per-cycle
    code that must allocate nothing but float temporaries."""
    import tracemalloc

    tracemalloc.start()
    try:
        run()
        return tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()


def classic_torque_loop() -> dict:
    """controller.torque_loop of config/torque-loop-classic.yaml (the loop shipped before the notched DP
    one): for what the shipped loop's margin does not admit, e.g. the disturbance observer (docs/daemon.md)."""
    import yaml

    from ankle_rt.paths import CONFIG_DIR

    return yaml.safe_load((CONFIG_DIR / "torque-loop-classic.yaml").read_text())["controller"]["torque_loop"]


def variant(cfg: Config, **sections: dict) -> Config:
    """A deep copy of ``cfg`` with the given sections updated key by key."""
    out = cfg.deep_copy()
    for name, values in sections.items():
        out[name].update(values)
    return out


class InjectingBackend(Backend):
    """The simulator, with ``mutate(frame, cycle)`` applied to every sample from cycle ``at`` on.
    Records the cycles in which deactivate() was called."""

    name = "inject"
    simulated_plant = True   # the simulator behind it

    def __init__(self, cfg: Config, clock: SimClock, at: int = 10**9,
                 mutate: Callable[[SensorFrame, int], None] | None = None):
        super().__init__(cfg, clock)
        self.sim = SimBackend(cfg, clock)
        self.at, self.mutate = at, mutate
        self.cycle = -1
        self.deactivated_at: list[int] = []
        self.writes: list[tuple[int, float, float]] = []   # (cycle, i1, i2) of every write

    @property
    def active(self) -> bool:
        return self.sim.active

    def activate(self) -> None:
        self.sim.activate()

    def deactivate(self) -> None:
        self.deactivated_at.append(self.cycle)
        self.sim.deactivate()

    def write(self, current_1: float, current_2: float) -> None:
        self.writes.append((self.cycle, current_1, current_2))
        self.sim.write(current_1, current_2)

    def read(self, frame: SensorFrame) -> None:
        self.cycle += 1
        self.sim.read(frame)
        if self.mutate is not None and self.cycle >= self.at:
            self.mutate(frame, self.cycle)


def lockstep_daemon(cfg: Config, *, backend: Backend | None = None, capacity: int = 20000, **kw) -> Daemon:
    """A Daemon on a SimClock with an in-memory recorder (run it with run_cycles)."""
    clock = backend.clock if backend is not None else SimClock()
    return Daemon(cfg, clock, backend=backend, recorder=MemoryRecorder(capacity), **kw)


def run_cycles(daemon: Daemon, n: int) -> None:
    """Run ``n`` more cycles of the daemon's loop on its SimClock."""
    daemon.loop.run(daemon.cycle, n * daemon.period_ns)


def reply(result, guard_s: float = 30.0):
    """A Daemon.handle result as its reply data: a Pending reply (a CSV profile loading in the
    background thread) is polled until ready (``guard_s`` only stops a hung test)."""
    import time

    from ankle_rt.service.protocol import Pending

    if not isinstance(result, Pending):
        return result
    end = time.monotonic() + guard_s
    while time.monotonic() < end:
        data = result.poll()
        if data is not None:
            return data
        time.sleep(0.001)
    raise AssertionError("the pending reply never became ready")


def mutated_run(cfg: Config, duration_s: float, mutate: Callable[[SensorFrame, int], None],
                push: Callable[[float], tuple[float, float]] = lambda t: (0.0, 0.0)):
    """``run_lockstep`` of ``cfg`` on the simulator under the ankle torque ``push(t)`` (N m [DP, IE]), every
    sample then changed by ``mutate(frame, cycle)`` (a sensor going bad)."""
    from ankle_rt.backend import open_backend
    from ankle_rt.bench.impedance import TorqueProgramBackend
    from ankle_rt.daemon import run_lockstep

    class Mutated(TorqueProgramBackend):
        cycle = -1

        def read(self, frame: SensorFrame) -> None:
            super().read(frame)
            self.cycle += 1
            mutate(frame, self.cycle)

    return run_lockstep(cfg, duration_s, backend=Mutated(open_backend(cfg, SimClock()), lambda t, x: push(t)))
