"""``ankle-rt calibrate``: record the strain-gauge tare and check the amplifier and encoder signs.

With the foot unloaded and free to move a few degrees near neutral:

1. the strain gauges are averaged for ``--tare`` s with the amplifiers off: the new
   ``strain_gauges.tare`` is printed (and written with ``--output``);
2. each motor in turn gets a short current pulse (``--current`` A for ``--pulse`` s) and then the
   same pulse back. The motor must turn forward, more than the other motor, and (with joint
   encoders) move the ankle the way the kinematics predict. A failed check names the config key to
   fix (e.g. ``escon.amplifiers.1.sign``).

Works on any backend through the Backend interface. ``--fast`` runs on a simulated clock (the
simulator, or a hardware config with an in-process lockstep emulator). Exit code 0: all checks
passed; 1: a check failed or the device faulted; 2: bad configuration.
"""

from __future__ import annotations

import argparse
import math
import sys


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("calibrate", help="strain-gauge tare and amplifier / encoder sign check",
                              description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", metavar="FILE", help="configuration of the device (default: the shipped "
                   "config/sim.yaml, the simulator; use it with --fast)")
    p.add_argument("--fast", action="store_true", help="lockstep on a simulated clock (simulator or emulator)")
    p.add_argument("--current", type=float, default=0.5, metavar="A", help="pulse current (default 0.5 A)")
    p.add_argument("--pulse", type=float, default=0.05, metavar="S", help="pulse duration (default 0.05 s)")
    p.add_argument("--tare", type=float, default=0.5, metavar="S", help="tare averaging time (default 0.5 s)")
    p.add_argument("--output", metavar="FILE", help="also write the calibration values as YAML to FILE")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from ankle_rt.backend import BackendError, open_backend
    from ankle_rt.calibration import CalibrationAborted, calibrate
    from ankle_rt.clock import MonotonicClock, SimClock
    from ankle_rt.config import load_config

    if not 0.0 < args.current <= 3.0:
        print("ankle-rt calibrate: --current must be in (0, 3] A", file=sys.stderr)
        return 2
    from ankle_rt.paths import default_config_path

    args.config = args.config or str(default_config_path())
    cfg = load_config(args.config)
    clock = SimClock() if args.fast else MonotonicClock()
    try:
        backend = open_backend(cfg, clock)
    except BackendError as exc:
        print(f"ankle-rt calibrate: {exc}", file=sys.stderr)
        return 1
    try:
        report = calibrate(cfg, backend, clock, tare_s=args.tare, current=args.current, pulse_s=args.pulse)
    except CalibrationAborted as exc:
        print(f"ankle-rt calibrate: stopped, amplifiers off: {exc}", file=sys.stderr)
        return 1
    finally:
        backend.close()
    _print(report)
    if args.output:
        with open(args.output, "w") as f:
            f.write(f"# ankle-rt calibrate --config {args.config}\n" + report.yaml())
        print(f"written to {args.output}")
    return 0 if report.ok else 1


def _print(report) -> None:
    d = math.degrees
    m, s = report.tare_mean, report.tare_noise
    print(f"strain-gauge tare: {report.tare_samples} samples, amplifiers off: offset DP {m[0]:+.4f} N m, "
          f"IE {m[1]:+.4f} N m (noise {s[0]:.4f} / {s[1]:.4f} N m rms)")
    for c in report.motors:
        line = (f"motor {c.motor}: {c.current:+g} A pulse turned motor 1 {d(c.motor_motion[0]):+.3f} deg, "
                f"motor 2 {d(c.motor_motion[1]):+.3f} deg")
        if c.ankle_motion is not None:
            line += (f"; ankle DP {d(c.ankle_motion[0]):+.3f} IE {d(c.ankle_motion[1]):+.3f} deg "
                     f"(kinematics {d(c.expected_ankle[0]):+.3f} / {d(c.expected_ankle[1]):+.3f})")
        print(line + ("  ok" if not c.problems else "  FAILED"))
    print("calibration values for the hardware config:")
    print(report.yaml(), end="")
    for p in report.problems:
        print(f"PROBLEM: {p}")
    print("all checks passed" if report.ok else f"{len(report.problems)} check(s) failed")
