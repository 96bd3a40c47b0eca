"""Helpers for the hardware tests (serial bridge and CANopen node, each with its in-process emulator):
bench configs as private copies, the same config on the direct simulator, the simulator with the
set-value quantisation of the I/O hardware, read-only cycles of a backend, and the daemon stepped
cycle by cycle over a backend with the steps of a fault-injection scenario."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Callable, Sequence

from ankle_rt.backend import Backend, SensorFrame, open_backend
from ankle_rt.clock import SimClock
from ankle_rt.config import Config, load_config
from ankle_rt.daemon import Daemon
from ankle_rt.safety import Fault, State
from hardware.escon import EsconAmplifier
from sim_backend.backend import SimBackend


def config_copy(cfg: Config) -> Config:
    """A deep copy of ``cfg`` that a test may edit, naming the same source file in its errors."""
    return cfg.deep_copy()


@functools.cache
def _loaded(path: Path) -> Config:
    return load_config(path)


def bench_config(path: Path) -> Config:
    """A private copy of the config at ``path``, which is loaded and validated once per test session."""
    return config_copy(_loaded(Path(path)))


def sim_copy(cfg: Config) -> Config:
    """The same config on the direct simulated backend."""
    out = config_copy(cfg)
    out["backend"] = "sim"
    return out


def read_cycles(backend: Backend, frame: SensorFrame, n: int) -> None:
    """``n`` cycles of ``read`` alone (no set values sent), the backend's SimClock advanced by a
    period after each."""
    for _ in range(n):
        backend.read(frame)
        backend.clock.advance(backend.period_ns)


class QuantisedSimBackend(SimBackend):
    """The direct simulated backend with the I/O hardware's set-value quantisation (``amps``: the
    hardware backend's two ESCON maps), so that it differs from a transport by nothing else."""

    def __init__(self, cfg: Config, clock: SimClock, amps: Sequence[EsconAmplifier]):
        super().__init__(cfg, clock)
        self.amps = amps

    def write(self, current_1: float, current_2: float) -> None:
        a1, a2 = self.amps
        super().write(a1.current(a1.code(current_1)), a2.current(a2.code(current_2)))


class Bench:
    """The daemon and the config's hardware backend with its in-process emulator in lockstep,
    stepped cycle by cycle."""

    def __init__(self, cfg: Config, open_: Callable[[Config, SimClock], Backend] = open_backend):
        """``open_``: how to open the backend (default: as the config says)."""
        self.clock = SimClock()
        self.backend = open_(cfg, self.clock)
        self.emu = self.backend.emulator
        self.daemon = Daemon(cfg, self.clock, backend=self.backend)
        self.period = self.backend.period_ns

    def cycles(self, n: int, until: Callable[[], bool] | None = None) -> int:
        """Run up to ``n`` cycles (stop early once ``until()`` is true); return how many ran."""
        for k in range(1, n + 1):
            t = self.clock.now_ns()
            self.daemon.cycle(t)
            self.clock.sleep_until(t + self.period)
            if until is not None and until():
                return k
        return n

    @property
    def state(self) -> State:
        return State(self.daemon.safety.state)

    def run_into_the_step(self) -> None:
        """Tare, activate and run 0.5 s into the section 7 step, until the motors work."""
        self.cycles(505)
        assert self.state == State.ACTIVE
        assert max(abs(c) for c in self.emu.plant.current) > 1.0

    def cycles_until_safe(self, limit: int) -> int:
        """Run until the daemon leaves ACTIVE, at most ``limit`` cycles; return how many ran.
        It must then be in FAULT or SAFE."""
        took = self.cycles(limit, until=lambda: self.state != State.ACTIVE)
        assert self.state in (State.FAULT, State.SAFE)
        return took

    def assert_latched(self, fault: Fault) -> None:
        """20 more cycles: still not ACTIVE, still reporting ``fault``."""
        self.cycles(20)
        assert self.state in (State.FAULT, State.SAFE) and self.daemon.safety.fault == fault

    def reset_and_resume(self) -> None:
        """Reset the fault, activate and run 200 cycles: ACTIVE again, no fault."""
        self.daemon.reset_fault()
        self.daemon.activate()
        self.cycles(200)
        assert self.state == State.ACTIVE and self.daemon.safety.fault == Fault.NONE

    def close(self) -> None:
        self.daemon.close()
        self.backend.close()
