"""The one small interface between the daemon and a device, and the registry that picks a backend
by name from the config (``backend: sim | serial | canopen``), the way python-can picks an interface.

Lifecycle (after ros2_control's hardware components)::

    open_backend(cfg, clock)  -> configured   (transport opened, parameters checked, amplifiers off)
    activate()                -> active       (amplifiers enabled, set values start at zero)
    read(frame) / write(i1, i2)               (once per cycle, no allocation, no blocking I/O)
    deactivate()              -> configured   (set values zero, amplifiers disabled)
    close()                                   (transport released)

``read`` fills a preallocated :class:`SensorFrame` in place and reports transport or device problems
as :class:`BackendFault` bits in ``frame.faults``; the daemon's safety layer decides what to do.
The core never imports a backend's module directly: :data:`BACKENDS` maps names to import paths.
"""

from __future__ import annotations

import enum
import importlib
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from ankle_rt.config import ConfigError
from ankle_rt.float_buffer import float_buffer

if TYPE_CHECKING:
    from ankle_rt.clock import Clock
    from ankle_rt.config import Config

BACKENDS: dict[str, str] = {
    "sim": "sim_backend.backend:SimBackend",
    "serial": "hardware.serial_backend:SerialBackend",
    "canopen": "hardware.canopen_backend:CanopenBackend",
}


class BackendFault(enum.IntFlag):
    """Problems a backend reports in a sample. Zero means healthy."""

    NONE = 0
    LINK_LOST = enum.auto()        # no sample within the stated detection time
    CRC_ERROR = enum.auto()        # a corrupted frame was dropped
    SEQUENCE_GAP = enum.auto()     # samples were lost between two received ones
    STALE_SAMPLE = enum.auto()     # the newest sample is older than one period
    AMP_NOT_READY = enum.auto()    # an ESCON's ready output is low while enabled
    ENCODER_FAULT = enum.auto()    # an encoder is stuck or jumped implausibly
    STRAIN_GAUGE_RAIL = enum.auto()  # a strain-gauge channel sits at its rail / broken wire
    BUS_OFF = enum.auto()          # CAN controller bus-off
    DEVICE_FAULT = enum.auto()     # the bridge or I/O module reported a fault of its own


class BackendError(RuntimeError):
    """A backend could not be configured, activated or opened (names the device and the reason)."""


class SensorFrame:
    """One cycle's sensor sample, preallocated once and filled in place by :meth:`Backend.read`.

    Units: t in s (the backend's sample time), angles in rad, torques in N m. Motor quantities are
    at the gearbox output. ``ankle_pos`` is NaN when the device has no joint encoders.
    ``values`` holds the three pairs in that order, [motor 1, motor 2, sg DP, sg IE, ankle DP,
    ankle IE], as a memoryview: the cycle's own reads and writes go through it as plain floats
    (the arrays are views of the same memory).
    """

    __slots__ = ("t", "seq", "values", "motor_pos", "sg_torque", "ankle_pos", "amp_ready", "faults")

    def __init__(self) -> None:
        self.t = 0.0
        self.seq = 0
        self.values, pairs = float_buffer(6)
        self.motor_pos = pairs[0:2]           # rad, [motor 1, motor 2]
        self.sg_torque = pairs[2:4]           # N m, [DP, IE] from the strain gauges (tared)
        self.ankle_pos = pairs[4:6]           # rad, [DP, IE] joint encoders, if any
        self.ankle_pos[:] = np.nan
        self.amp_ready = [True, True]
        self.faults = BackendFault.NONE


class Backend(ABC):
    """A device the daemon can drive: the simulator, or a transport to the real amplifiers."""

    name: ClassVar[str] = ""

    @property
    def simulated_plant(self) -> bool:
        """True only when what this backend drives is simulated in this process (nothing physical
        moves). False unless a backend says otherwise: an unknown backend counts as hardware."""
        return False

    def __init__(self, cfg: "Config", clock: "Clock"):
        """Configure: open the transport and check the settings. Amplifiers stay disabled."""
        self.cfg = cfg
        self.clock = clock

    @abstractmethod
    def activate(self) -> None:
        """Enable the amplifiers with zero set values."""

    @abstractmethod
    def read(self, frame: SensorFrame) -> None:
        """Fill ``frame`` with the newest sample. Must not allocate or block beyond one period."""

    @abstractmethod
    def write(self, current_1: float, current_2: float) -> None:
        """Send the current set values (A) for this cycle. Ignored (zero sent) unless active."""

    @abstractmethod
    def deactivate(self) -> None:
        """Zero the set values and disable the amplifiers. Safe to call in any state, repeatedly."""

    def close(self) -> None:
        """Release the transport. Deactivates first."""
        self.deactivate()

    def counters(self) -> dict[str, int]:
        """Diagnostic counters (CRC errors, gaps, ...) for status reports; not for the hot loop."""
        return {}

    def __enter__(self) -> "Backend":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class ForwardingBackend(Backend):
    """Passes everything to the backend ``inner`` (same config and clock): subclass it to watch or
    change one call (benchmarks, tools), not to drive a device of its own."""

    def __init__(self, inner: Backend):
        super().__init__(inner.cfg, inner.clock)
        self.inner = inner

    def activate(self) -> None:
        self.inner.activate()

    def read(self, frame: SensorFrame) -> None:
        self.inner.read(frame)

    def write(self, current_1: float, current_2: float) -> None:
        self.inner.write(current_1, current_2)

    def deactivate(self) -> None:
        self.inner.deactivate()

    def close(self) -> None:
        self.inner.close()

    def counters(self) -> dict[str, int]:
        return self.inner.counters()

    @property
    def simulated_plant(self) -> bool:
        return self.inner.simulated_plant


BATCH_PLANTS: dict[str, str] = {
    "sim": "sim_backend.batch:BatchPlant",
}
"""Backends that can step many devices at once (``ankle-rt sweep``): the simulator only."""


def load_by_name(spec: str) -> Any:
    """The attribute ``spec`` ("package.module:name") names, imported on first use: how the core
    reaches backends, and a driver its device's emulator, without importing them (so each runs
    where the others are not installed)."""
    module_name, _, attr = spec.partition(":")
    return getattr(importlib.import_module(module_name), attr)


def _registered(table: dict[str, str], name: str, what: str, source: str | None) -> type:
    if name not in table:
        raise ConfigError(f"unknown {what} {name!r} (expected one of: {', '.join(table)})", source, "backend")
    return load_by_name(table[name])


def backend_class(name: str, source: str | None = None) -> type[Backend]:
    """Import and return the backend class registered under ``name`` (``source``: the config file, for errors)."""
    return _registered(BACKENDS, name, "backend", source)


def batch_plant_class(name: str, source: str | None = None) -> type:
    """The batch plant class of backend ``name`` (:data:`BATCH_PLANTS`), for studies over many devices."""
    return _registered(BATCH_PLANTS, name, "backend for a batch (sweeps simulate)", source)


def open_backend(cfg: "Config", clock: "Clock") -> Backend:
    """Build and configure the backend the config names (``backend:`` key)."""
    return backend_class(cfg["backend"], getattr(cfg, "source", None))(cfg, clock)
