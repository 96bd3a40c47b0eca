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
import functools
from pathlib import Path

from ankle_rt.clock import SimClock
from ankle_rt.config import Config, load_config
from hardware.canopen_backend import CanopenBackend, configured_bus_load
from transport_timing import print_table, timed_repeats

ROOT = Path(__file__).resolve().parent.parent


def open_lockstep(cfg: Config, repeat: int, clock: SimClock) -> CanopenBackend:
    """The backend and its emulator on a virtual channel of this repeat's own."""
    cfg = cfg.deep_copy()
    cfg.source = str(ROOT / "config" / "bench-canopen.yaml")
    cfg["canopen"]["channel"] = f"bench-canopen-{repeat}"
    return CanopenBackend(cfg, clock)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cycles", type=int, default=3000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    cfg = load_config(ROOT / "config" / "bench-canopen.yaml")
    rows = timed_repeats(functools.partial(open_lockstep, cfg), "service", args.cycles, args.repeats)
    print(f"\nCANopen over the emulator in lockstep, {args.cycles} cycles x {args.repeats} repeats (µs per cycle):")
    print_table(rows, "backend")
    hw = load_config(ROOT / "config" / "hw-canopen.yaml")
    print(f"\nbus load of config/hw-canopen.yaml at {hw['controller']['rate_hz']} Hz:")
    print(configured_bus_load(hw).table())


if __name__ == "__main__":
    main()
