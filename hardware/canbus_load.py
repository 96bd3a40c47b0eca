"""CAN bus load of the control loop: SYNC + RPDOs + TPDOs every cycle, plus the heartbeats.

Frame length is the classic CAN 2.0A (11-bit identifier) frame with the worst-case bit stuffing:
47 fixed bits (SOF, identifier, RTR, IDE, r0, DLC, CRC, delimiters, ACK, EOF, 3-bit interframe
space) + 8 bits per data byte + one stuff bit per 4 bits of the 34 + 8n stuffed bits (SOF..CRC).
A 0-byte SYNC is 55 bits, an 8-byte PDO 135 bits. The loop refuses a configuration above
:data:`MAX_BUS_LOAD` so that SDO, EMCY and retransmissions after errors still fit.
"""

from __future__ import annotations

from dataclasses import dataclass

from ankle_rt.config import ConfigError
from hardware.canopen_pdo import NodeLayout

MAX_BUS_LOAD = 0.70  # fraction of the bit rate the cyclic traffic may use


def frame_bits(data_bytes: int) -> int:
    """Bits on the wire for one 11-bit-identifier data frame, worst-case stuffing, with interframe space."""
    if not 0 <= data_bytes <= 8:
        raise ValueError(f"classic CAN carries 0..8 data bytes, got {data_bytes}")
    stuffed = 34 + 8 * data_bytes
    return 47 + 8 * data_bytes + (stuffed - 1) // 4


@dataclass(frozen=True)
class FrameLoad:
    """One kind of frame on the bus."""

    name: str
    data_bytes: int
    per_second: float     # frames/s
    every_cycle: bool     # sent once per control cycle (scales with the rate)

    @property
    def bits_per_second(self) -> float:
        return frame_bits(self.data_bytes) * self.per_second


@dataclass(frozen=True)
class BusLoad:
    """The cyclic traffic of the loop against the bit rate."""

    frames: tuple[FrameLoad, ...]
    bitrate: int  # bit/s

    @property
    def bits_per_second(self) -> float:
        return sum(f.bits_per_second for f in self.frames)

    @property
    def load(self) -> float:
        """Fraction of the bit rate used (0..1, may exceed 1)."""
        return self.bits_per_second / self.bitrate

    def max_rate_hz(self) -> float:
        """The highest control rate that keeps the load within :data:`MAX_BUS_LOAD`."""
        cyclic_bits = sum(frame_bits(f.data_bytes) for f in self.frames if f.every_cycle)
        other = sum(f.bits_per_second for f in self.frames if not f.every_cycle)
        return (MAX_BUS_LOAD * self.bitrate - other) / cyclic_bits

    def table(self) -> str:
        """A printable table: one row per frame, then the total against the bit rate and the limit."""
        lines = [f"{'frame':<22}{'bytes':>6}{'bits':>6}{'per s':>9}{'kbit/s':>9}"]
        for f in self.frames:
            lines.append(f"{f.name:<22}{f.data_bytes:>6}{frame_bits(f.data_bytes):>6}"
                         f"{f.per_second:>9.0f}{f.bits_per_second / 1e3:>9.1f}")
        lines.append(f"total {self.bits_per_second / 1e3:.1f} kbit/s of {self.bitrate / 1e3:.0f} kbit/s: "
                     f"bus load {100 * self.load:.1f} % (limit {100 * MAX_BUS_LOAD:.0f} %, "
                     f"reached at {self.max_rate_hz():.0f} Hz)")
        return "\n".join(lines)


def loop_bus_load(layout: NodeLayout, rate_hz: float, bitrate: int, heartbeat_ms: int) -> BusLoad:
    """Bus load when the loop sends one SYNC and the node's RPDOs and TPDOs every cycle at
    ``rate_hz``, and the node sends a 1-byte heartbeat every ``heartbeat_ms`` (0: none)."""
    frames = [FrameLoad("SYNC", 0, rate_hz, True)]
    frames += [FrameLoad(p.name, p.size, rate_hz, True) for p in layout.rpdos + layout.tpdos]
    if heartbeat_ms > 0:
        frames.append(FrameLoad(f"heartbeat_node{layout.node_id}", 1, 1000.0 / heartbeat_ms, False))
    return BusLoad(tuple(frames), bitrate)


def check_bus_load(load: BusLoad, source: str | None) -> None:
    """Refuse a configuration whose cyclic traffic exceeds :data:`MAX_BUS_LOAD` of the bus."""
    if load.load > MAX_BUS_LOAD:
        raise ConfigError(
            f"the CAN bus load would be {100 * load.load:.1f} % of {load.bitrate / 1e3:.0f} kbit/s "
            f"(limit {100 * MAX_BUS_LOAD:.0f} %, reached at {load.max_rate_hz():.0f} Hz); lower the rate, "
            f"raise canopen.bitrate or map fewer PDOs", source, "controller.rate_hz")
