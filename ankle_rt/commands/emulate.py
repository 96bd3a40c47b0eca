"""``ankle-rt emulate``: run a device emulator standalone, the simulated plant behind the real protocol.

This is the bench set-up without the prosthesis: the emulator runs on a second computer (or in a
second terminal) on a real serial or CAN link, and the daemon on the prosthesis computer runs its
hardware config against it without knowing the difference.

    ankle-rt emulate --transport serial --config config/bench-serial.yaml --port pty
    ankle-rt emulate --transport serial --config config/bench-serial.yaml --port /dev/ttyUSB0
    ankle-rt emulate --transport serial --config config/bench-serial.yaml --port pty --core c
    ankle-rt emulate --transport canopen --config config/bench-canopen.yaml --interface socketcan --channel can0

The plant steps once per command frame (serial) or SYNC (CANopen): the daemon's clock paces it.
Faults are injected with ``--inject NAME@START[:STOP]`` (seconds of plant time; see the transport's
documentation for the names). Each transport registers ``run_standalone(cfg, args) -> int`` in
:data:`EMULATORS`; the core loads it by name and never imports ``hardware`` itself.
"""

from __future__ import annotations

import argparse

# transport -> "module:function" taking (validated config, parsed arguments) and returning an exit code
EMULATORS: dict[str, str] = {
    "serial": "hardware.emulators.serial_emulator:run_standalone",
    "canopen": "hardware.emulators.canopen_emulator:run_standalone",
}


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "emulate", help="run a device emulator (simulated plant behind the serial or CANopen protocol)",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--transport", required=True, choices=sorted(EMULATORS), help="protocol to speak")
    parser.add_argument("--config", metavar="FILE",
                        help="plant parameters and the device's calibration (default: the shipped "
                             "config/bench-serial.yaml or config/bench-canopen.yaml, by --transport)")
    parser.add_argument("--port", help="serial: device path (/dev/ttyUSB0) or 'pty' for a new pseudo-terminal "
                        "whose path is printed (default: serial.port of the config)")
    parser.add_argument("--baudrate", type=int, help="serial: bit/s (default: serial.baudrate of the config)")
    parser.add_argument("--interface", help="canopen: python-can interface (default: canopen.interface)")
    parser.add_argument("--channel", help="canopen: python-can channel (default: canopen.channel)")
    parser.add_argument("--free-run", action="store_true", help="serial: tick on the emulator's own clock at "
                        "controller.rate_hz like the real bridge (default: lockstep, one tick per command)")
    parser.add_argument("--core", choices=("python", "c"), default="python",
                        help="serial: the bridge firmware core behind the emulated board: the Python reference "
                        "or the firmware's C core compiled natively with the host's gcc (firmware in the loop)")
    parser.add_argument("--duration", type=float, default=0.0, metavar="S",
                        help="stop after this many seconds of wall time (0: until Ctrl-C)")
    parser.add_argument("--inject", action="append", default=[], metavar="NAME@START[:STOP]",
                        help="inject a fault from START to STOP s of plant time (repeatable)")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from ankle_rt.backend import load_by_name
    from ankle_rt.config import load_config
    from ankle_rt.paths import default_config_path

    cfg = load_config(args.config or default_config_path(f"bench-{args.transport}.yaml"))
    return int(load_by_name(EMULATORS[args.transport])(cfg, args) or 0)
