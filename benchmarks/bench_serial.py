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
import time
from pathlib import Path

from ankle_rt.config import load_config
from hardware.serial_backend import SerialBackend, link_load
from hardware.serial_protocol import MsgType, StreamParser, encode_frame, frame_size
from transport_timing import print_table, timed_repeats

ROOT = Path(__file__).resolve().parent.parent


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
    rows = timed_repeats(lambda _, clock: SerialBackend(cfg, clock), "receive", args.cycles, args.repeats)
    print(f"\nserial bridge over the emulator on a pty in lockstep, {args.cycles} cycles x {args.repeats} repeats "
          f"(µs per cycle):")
    print_table(rows, "backend+pty")
    hw = load_config(ROOT / "config" / "hw-serial.yaml")
    rate = hw["controller"]["rate_hz"]
    print(f"\nframes: SAMPLE {frame_size(MsgType.SAMPLE)} B, COMMAND {frame_size(MsgType.COMMAND)} B; "
          f"at {rate} Hz and {hw['serial']['baudrate']} bit/s the sample stream uses {link_load(hw):.1%} of the link "
          f"(limit 70 %)")
    print(f"parser: {parser_throughput(False):.1f} MB/s clean, {parser_throughput(True):.1f} MB/s with 30 noise "
          f"bytes per frame (1 kHz needs {frame_size(MsgType.SAMPLE) * rate / 1e6:.3f} MB/s)")


if __name__ == "__main__":
    main()
