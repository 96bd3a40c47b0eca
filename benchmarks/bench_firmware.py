"""The serial bridge firmware: its core's cost per tick (native), the size of the STM32F405 image
(cross-compiled), and the daemon's round trip per cycle through the pty with each firmware core.

1. Native tick cost: hardware/firmware/host/bench_core.c (built here with gcc -O2) runs the core's
   tick as the board does (one COMMAND received, watchdog, SAMPLE built and taken) and the worst
   case a 2 Mbit/s link can deliver in a tick (200 bytes of frame headers that pass every check but
   the CRC). Nanoseconds on this machine, not scaled: the Cortex-M4 figure is the cycle estimate in
   docs/firmware.md.
   Instructions per tick on the Cortex-M4: the same program cross-compiled (-Os, as the image) and
   run in QEMU's STM32F405 (netduinoplus2) with -icount shift=0, timed with the SysTick; skipped
   without qemu-system-arm. Cycles = instructions x CPI (1.2-1.5 on a Cortex-M4 for this code).
2. Image size: ``make -C hardware/firmware`` and arm-none-eabi-size: flash = text + data, static
   RAM = data + bss (the core's state included), plus the linker script's 4 KiB stack reserve.
3. Round trip: the serial backend against the lockstep emulator on a pty (read + write per cycle,
   emulator included), with the Python reference core and with the C core (ctypes).

    python benchmarks/bench_firmware.py [--ticks 200000] [--cycles 3000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
from pathlib import Path

from ankle_rt.config import load_config
from hardware.emulators.serial_emulator import CORES, open_lockstep
from hardware.serial_backend import SerialBackend
from transport_timing import print_table, timed_repeats

ROOT = Path(__file__).resolve().parent.parent
FIRMWARE = ROOT / "hardware" / "firmware"


def native_tick_ns(ticks: int) -> dict[str, float]:
    """ns per tick of the core, normal and worst case, built and run natively."""
    with tempfile.TemporaryDirectory() as tmp:
        exe = Path(tmp) / "bench_core"
        subprocess.run(["gcc", "-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-o", str(exe),
                        str(FIRMWARE / "host" / "bench_core.c"), str(FIRMWARE / "core" / "frame.c"),
                        str(FIRMWARE / "core" / "bridge.c")], check=True)
        out = subprocess.run([str(exe), str(ticks)], check=True, capture_output=True, text=True).stdout
    return {name: float(value) for name, value in (line.split() for line in out.splitlines())}


def m4_instructions() -> dict[str, float] | None:
    """Instructions per tick of the core on the Cortex-M4 (QEMU), or None without the tools."""
    if not (shutil.which("arm-none-eabi-gcc") and shutil.which("qemu-system-arm")):
        return None
    subprocess.run(["make", "-s", "-C", str(FIRMWARE), "build/bench_m4.elf"], check=True)
    out = subprocess.run(["qemu-system-arm", "-M", "netduinoplus2", "-nographic", "-monitor", "none", "-serial",
                          "null", "-semihosting", "-icount", "shift=0", "-kernel",
                          str(FIRMWARE / "build" / "bench_m4.elf")], check=True, capture_output=True, text=True,
                         timeout=120).stdout
    return {name: float(value) for name, value in (line.split() for line in out.splitlines())}


def image_size() -> tuple[int, int, int] | None:
    """(text, data, bss) of the cross-compiled image, or None without arm-none-eabi-gcc."""
    if not shutil.which("arm-none-eabi-gcc"):
        return None
    subprocess.run(["make", "-s", "-C", str(FIRMWARE), "build/bridge.bin"], check=True)
    out = subprocess.run(["arm-none-eabi-size", str(FIRMWARE / "build" / "bridge.elf")], check=True,
                         capture_output=True, text=True).stdout
    text, data, bss = (int(v) for v in out.splitlines()[1].split()[:3])
    return text, data, bss


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ticks", type=int, default=200_000)
    parser.add_argument("--cycles", type=int, default=3000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    ns = native_tick_ns(args.ticks)
    print(f"core tick, native (gcc -O2, this machine): {ns['normal']:.0f} ns per tick with one command; "
          f"{ns['worst']:.0f} ns with a tick's worth of CRC-failing headers (200 bytes)")
    m4 = m4_instructions()
    if m4 is None:
        print("core tick, Cortex-M4: needs arm-none-eabi-gcc and qemu-system-arm")
    else:
        print(f"core tick, Cortex-M4 (QEMU, instructions): {m4['normal']:.0f} per tick with one command, "
              f"{m4['worst']:.0f} worst case; at CPI 1.2-1.5 and 168 MHz: {m4['normal'] * 1.2 / 168:.0f}-"
              f"{m4['normal'] * 1.5 / 168:.0f} µs and {m4['worst'] * 1.2 / 168:.0f}-{m4['worst'] * 1.5 / 168:.0f} µs "
              f"of the 1000 µs period")
    size = image_size()
    if size is None:
        print("image: arm-none-eabi-gcc not installed (apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi)")
    else:
        text, data, bss = size
        print(f"image (STM32F405, arm-none-eabi-gcc -Os): flash {text + data} B of 1 MiB, static RAM {data + bss} B "
              f"+ 4096 B stack reserve of 128 KiB")

    cfg = load_config(ROOT / "config" / "bench-serial.yaml")
    for core in CORES:
        rows = timed_repeats(lambda _, clock: SerialBackend(cfg, clock, port=open_lockstep(cfg, core)), "receive",
                             args.cycles, args.repeats)
        print(f"\nround trip through the pty, {core} core, lockstep, {args.cycles} cycles x {args.repeats} repeats "
              f"(µs per cycle):")
        print_table(rows, "backend+pty")


if __name__ == "__main__":
    main()
