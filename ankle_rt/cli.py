"""Command-line entry point of ankle-rt: real-time control, simulation and model tools for a
two-DOF cable-driven ankle-foot prosthesis.

Each subcommand lives in its own module under ``ankle_rt.commands`` and
exposes ``register(subparsers)``; heavy imports (scipy, matplotlib, backends) happen inside the
handlers, so ``ankle-rt --help`` stays fast on the prosthesis computer."""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from ankle_rt.blas_threads import limit_blas_threads

limit_blas_threads()    # before numpy's first import (ankle_rt.config's)

from ankle_rt.config import ConfigError  # noqa: E402

# Module names under ankle_rt.commands, in the order `--help` lists them.
COMMANDS: tuple[str, ...] = ("run", "config", "log", "analyze", "ctl", "identify", "validate", "emulate", "calibrate", "canbus_load", "diagnose", "bench", "sweep")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ankle-rt", description="Real-time control, simulation and model tools for a two-DOF cable-driven ankle-foot prosthesis.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"ankle_rt.commands.{name}").register(sub)
    return parser


EXIT_BROKEN_PIPE = 141   # 128 + SIGPIPE, what a shell shows for a tool whose reader went away


def main(argv: list[str] | None = None) -> int:
    """Run one command; its exit code. A closed output pipe (``ankle-rt analyze --json | head``)
    ends the command quietly instead of with a traceback."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.handler(args) or 0)
    except ConfigError as exc:
        print(f"ankle-rt: config error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # Python would try to flush stdout again at exit and print a second error: point it at /dev/null.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        return EXIT_BROKEN_PIPE


if __name__ == "__main__":
    sys.exit(main())
