"""Serial transport over the bridge emulator in lockstep: round-trip time per cycle, and link load.

One cycle is what the daemon does with the backend: ``read`` (drain the pty, parse, convert the
newest sample) then ``write`` (pack a COMMAND, write it to the pty; the lockstep link passes it to
the emulator, which steps the plant and writes the next SAMPLE back). Backend and emulator share one
thread, so the round trip includes the emulator's work (parsing, plant step, packing) and four pty
crossings; the time inside the emulator is also shown on its own, and the rest is the backend's
side plus the pty. Timing is noisy on shared cores: percentiles over all cycles, best and median of
the repeats. Then the frame sizes and link load at 1 kHz of config/hw-serial.yaml, and the parser's
throughput on clean and on noisy streams.

    python benchmarks/bench_serial.py [--cycles 3000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

from ankle_rt.backend import SensorFrame
from ankle_rt.clock import SimClock
from ankle_rt.config import Config, load_config
from hardware.serial_backend import SerialBackend, link_load
from hardware.serial_protocol import MsgType, StreamParser, encode_frame, frame_size

ROOT = Path(__file__).resolve().parent.parent


def run_once(cfg: Config, cycles: int) -> tuple[list[float], float]:
    """Per-cycle round trips (s) and the total time spent inside the emulator (s)."""
    clock = SimClock()
    backend = SerialBackend(cfg, clock)
    emulator = backend.emulator
    inside = [0.0]
    receive = emulator.receive

    def timed_receive(data: bytes) -> None:
        t0 = time.perf_counter()
        receive(data)
        inside[0] += time.perf_counter() - t0

    emulator.receive = timed_receive
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


def parser_throughput(noisy: bool) -> float:
    """MB/s the stream parser gets through: 2000 samples, with 30 random bytes before each if noisy."""
    frame = encode_frame(MsgType.SAMPLE, 1, 10**6, 1, 2, 3, 4, 5, 6, 3, 0x80, 7)
    chunk = (os.urandom(30) if noisy else b"") + frame
    stream = chunk * 2000
    parser = StreamParser()
    t0 = time.perf_counter()
    for k in range(0, len(stream), 512):
        parser.feed(stream[k:k + 512])
        while parser.next_frame():
            pass
    return len(stream) / (time.perf_counter() - t0) / 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cycles", type=int, default=3000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    cfg = load_config(ROOT / "config" / "bench-serial.yaml")
    rows = []
    for _ in range(args.repeats):
        rtt, inside = run_once(cfg, args.cycles)
        rows.append((statistics.median(rtt), pct(rtt, 0.99), max(rtt), inside / args.cycles))
    print(f"\nserial bridge over the emulator on a pty in lockstep, {args.cycles} cycles x {args.repeats} repeats "
          f"(µs per cycle):")
    print(f"{'':>8}{'p50':>9}{'p99':>9}{'max':>9}{'emulator':>10}{'backend+pty':>13}")
    for name, pick in (("best", min), ("median", statistics.median)):
        p50, p99, mx, emu = (pick(r[i] for r in rows) for i in range(4))
        print(f"{name:>8}{p50 * 1e6:>9.0f}{p99 * 1e6:>9.0f}{mx * 1e6:>9.0f}{emu * 1e6:>10.0f}{(p50 - emu) * 1e6:>13.0f}")
    hw = load_config(ROOT / "config" / "hw-serial.yaml")
    rate = hw["controller"]["rate_hz"]
    print(f"\nframes: SAMPLE {frame_size(MsgType.SAMPLE)} B, COMMAND {frame_size(MsgType.COMMAND)} B; "
          f"at {rate} Hz and {hw['serial']['baudrate']} bit/s the sample stream uses {link_load(hw):.1%} of the link "
          f"(limit 70 %)")
    print(f"parser: {parser_throughput(False):.1f} MB/s clean, {parser_throughput(True):.1f} MB/s with 30 noise "
          f"bytes per frame (1 kHz needs {frame_size(MsgType.SAMPLE) * rate / 1e6:.3f} MB/s)")


if __name__ == "__main__":
    main()
