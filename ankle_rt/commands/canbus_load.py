"""``ankle-rt canbus-load``: the CAN bus load of a config's control rate and PDO mapping.

Prints one row per frame (SYNC, RPDOs, TPDOs every cycle; the node's heartbeat) with its worst-case
length in bits, and the total against ``canopen.bitrate``. Exits 2, naming the key, when the load is
above the 70 % the CANopen backend accepts. The core loads the hardware module by name.
"""

from __future__ import annotations

import argparse
import importlib
import sys


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("canbus-load", help="print the CAN bus load of a CANopen config",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", metavar="FILE", help="a CANopen config (default: the shipped "
                        "config/hw-canopen.yaml)")
    parser.add_argument("--rate", type=int, metavar="HZ", help="control rate instead of controller.rate_hz")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from ankle_rt.config import load_config
    from ankle_rt.paths import default_config_path

    cfg = load_config(args.config or default_config_path("hw-canopen.yaml"),
                      {"controller": {"rate_hz": args.rate}} if args.rate else None)
    if cfg["backend"] != "canopen":
        print(f"ankle-rt canbus-load: {cfg.source} uses backend {cfg['backend']!r}, not canopen: it puts no load on "
              "a CAN bus (give a CANopen config, e.g. config/hw-canopen.yaml or config/bench-canopen.yaml)",
              file=sys.stderr)
        return 2
    canbus = importlib.import_module("hardware.canbus_load")
    load = importlib.import_module("hardware.canopen_backend").configured_bus_load(cfg)
    print(f"{cfg.source}: {cfg['controller']['rate_hz']} Hz, {cfg['canopen']['bitrate']} bit/s")
    print(load.table())
    canbus.check_bus_load(load, cfg.source)
    return 0
