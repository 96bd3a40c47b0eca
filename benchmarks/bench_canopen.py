"""CANopen transport over its emulator in lockstep: round-trip time per cycle, and the bus load.

One cycle is what the daemon does with the backend: ``read`` (SYNC out, the emulator applies the
last RPDO, steps the plant and answers with its TPDOs, the backend decodes them) then ``write`` (the
RPDO out, stored by the emulator). Backend and emulator share one thread on python-can's in-process
``virtual`` bus, so the round trip includes the emulator's work (canopen dispatch, plant step, TPDO
packing) and python-can's per-frame cost; the time spent inside the emulator is also shown on its
own, and the rest is the backend's side. Timing is noisy on shared cores: percentiles over all
cycles, best and median of the repeats. Then the computed bus load at 1 kHz of config/hw-canopen.yaml.

    python benchmarks/bench_canopen.py [--cycles 3000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import copy
import statistics
import time
from pathlib import Path

from ankle_rt.backend import SensorFrame
from ankle_rt.clock import SimClock
from ankle_rt.config import Config, load_config
from hardware.canopen_backend import CanopenBackend, configured_bus_load

ROOT = Path(__file__).resolve().parent.parent


def run_once(cfg: Config, cycles: int, channel: str) -> tuple[list[float], float]:
    """Per-cycle round trips (s) and the total time spent inside the emulator (s)."""
    cfg = Config(copy.deepcopy(dict(cfg)))
    cfg.source = str(ROOT / "config" / "bench-canopen.yaml")
    cfg["canopen"]["channel"] = channel
    clock = SimClock()
    backend = CanopenBackend(cfg, clock)
    emulator = backend.emulator
    inside = [0.0]
    service = emulator.service

    def timed_service() -> None:
        t0 = time.perf_counter()
        service()
        inside[0] += time.perf_counter() - t0

    emulator.service = timed_service
    frame = SensorFrame()
    backend.activate()
    rtt = []
    for k in range(cycles):
        t0 = time.perf_counter()
        backend.read(frame)
        backend.write(0.5 if (k // 200) % 2 else -0.5, 0.3)
        rtt.append(time.perf_counter() - t0)
        clock.advance(backend.period_ns)
    backend.close()
    return rtt, inside[0]


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(q * len(s)))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cycles", type=int, default=3000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    cfg = load_config(ROOT / "config" / "bench-canopen.yaml")
    rows = []
    for r in range(args.repeats):
        rtt, inside = run_once(cfg, args.cycles, f"bench-canopen-{r}")
        rows.append((statistics.median(rtt), pct(rtt, 0.99), max(rtt), inside / args.cycles))
    print(f"\nCANopen over the emulator in lockstep, {args.cycles} cycles x {args.repeats} repeats (µs per cycle):")
    print(f"{'':>8}{'p50':>9}{'p99':>9}{'max':>9}{'emulator':>10}{'backend':>9}")
    for name, pick in (("best", min), ("median", statistics.median)):
        p50, p99, mx, emu = (pick(r[i] for r in rows) for i in range(4))
        print(f"{name:>8}{p50 * 1e6:>9.0f}{p99 * 1e6:>9.0f}{mx * 1e6:>9.0f}{emu * 1e6:>10.0f}{(p50 - emu) * 1e6:>9.0f}")
    hw = load_config(ROOT / "config" / "hw-canopen.yaml")
    print(f"\nbus load of config/hw-canopen.yaml at {hw['controller']['rate_hz']} Hz:")
    print(configured_bus_load(hw).table())


if __name__ == "__main__":
    main()
