"""``ankle-rt validate``: the paper's section 4 model validation, on the configured backend or on a
recorded interchange CSV, against the simulation driven by the same references or inputs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "validate", help="compare the backend (or a recording) with the simulated model (NRMSE per channel)",
        description="Run the paper's section 4 checks on the configured backend (Fig. 6 torque steps with "
                    "the motors off the cables, Fig. 7 IE sine tracking under PD kp=80, kd=0.3) or take "
                    "--from FILE.csv, drive the simulation the same way and report NRMSE and max error per "
                    "channel. With --from the closed-loop replay uses the controller the recording was made with: "
                    "a run log's header records it; for a CSV it is --config's controller section. "
                    "Exit 0: agrees; 1: discrepancy; 2: error.")
    p.add_argument("--config", help="config file: the backend to run on, and the model (default: the shipped "
                   "config/sim.yaml)")
    p.add_argument("--model", help="model config for the simulation side (default: --config)")
    p.add_argument("--from", dest="source", metavar="FILE",
                   help="validate recorded data (interchange CSV or daemon run log) instead of running checks")
    p.add_argument("--check", choices=("sine", "step", "all"), default="all", help="which checks to run (default all)")
    p.add_argument("--frequencies", type=float, nargs="+", metavar="HZ", help="sine frequencies (default 0.5 1 2)")
    p.add_argument("--drive", choices=("reference", "input"),
                   help="with --from: drive the simulation by the references (closed loop, the recording's "
                        "controller) or by the "
                        "recorded inputs (open loop); default: references when the file has them")
    p.add_argument("--tolerance", type=float, default=None, help="NRMSE above which a channel disagrees (default 0.02)")
    p.add_argument("--out", default="validation", help="output directory for plots and recordings (default ./validation)")
    p.set_defaults(handler=run)


def next_steps(comparisons: list, failed: list, args: argparse.Namespace, out: Path) -> list[str]:
    """What to run to name the cause of each failed check: ``ankle-rt diagnose`` on its data against the
    model validated (a check's recording is saved as validate_N.csv; the Fig. 6 steps are actuator data)."""
    model = args.model or args.config
    lines = []
    for k, c in enumerate(comparisons, start=1):
        if not any(c is f for f in failed):   # by identity: the comparisons hold numpy columns
            continue
        data = args.source or str(out / f"validate_{k}.csv")
        plant = " --plant actuator" if not c.measured.two_motors or "off the cables" in c.label else ""
        lines.append(f"next: ankle-rt diagnose {data}{plant} --config {model}   "
                     "(re-fits the baseline and names the effects behind the discrepancy)")
    return lines


def run(args: argparse.Namespace) -> int:
    from ankle_rt.config import ConfigError, load_config
    from ankle_rt.identification.runner import actuator_config
    from ankle_rt.identification.signals import IdentificationError
    from ankle_rt.identification.validation import (DEFAULT_TOLERANCE, SINE_FREQUENCIES_HZ, model_config,
                                                    recorded_controller, recorded_disturbances, run_checks,
                                                    validate_recording,
                                                    write_overlays)
    from ankle_rt.identification.data import load_recording
    from ankle_rt.interchange import InterchangeError, write_csv

    from ankle_rt.paths import default_config_path
    from ankle_rt.progress import Progress

    args.config = args.config or str(default_config_path())
    cfg = load_config(args.config)
    model = load_config(args.model) if args.model else cfg
    tolerance = args.tolerance if args.tolerance is not None else DEFAULT_TOLERANCE
    out = Path(args.out)
    notes = []
    try:
        if args.source:
            rec = load_recording(args.source, cfg=model)   # sampling and units checked against the model
            for warning in rec.extra["warnings"]:
                print(f"ankle-rt validate: warning: {warning}", file=sys.stderr)
            if not rec.two_motors:   # single-actuator data: the motors were off the cables
                model = actuator_config(model_config(model))[0]
            controller = recorded_controller(rec)   # the controller the run log says was running
            origin = "the run log header"
            if controller is None:   # an interchange CSV carries none: the user's --config names it
                controller, origin = cfg["controller"], f"--config {args.config} (the file records no controller)"
            comparisons = [validate_recording(rec, model, args.drive, f"{args.source}", controller)]
            if comparisons[0].drive == "reference":
                notes.append(f"  controller taken from {origin}")
                disturbances = recorded_disturbances(rec)
                notes.append("  ankle disturbances replayed from the run log header: " + "; ".join(
                    f"{d['torque_dp']:g} / {d['torque_ie']:g} N m DP / IE from {d['start']:g} to {d['stop']:g} s"
                    for d in disturbances) if disturbances else
                    "  no ankle disturbance recorded: an external torque during the recording counts as model error")
        else:
            checks = ("sine", "step") if args.check == "all" else (args.check,)
            print(f"running {' and '.join(checks)} check(s) on backend {cfg['backend']!r}; model: "
                  f"{args.model or args.config} on the simulator (noise-free) ...", flush=True)
            with Progress("validate", 1.0) as progress:
                comparisons = run_checks(cfg, model, checks, tuple(args.frequencies or SINE_FREQUENCIES_HZ),
                                         progress=progress.callback)
    except (InterchangeError, IdentificationError, ConfigError) as exc:
        print(f"ankle-rt validate: {exc}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    lines = []
    for k, c in enumerate(comparisons, start=1):
        lines += c.lines(tolerance) + notes
        if not args.source:
            write_csv(out / f"validate_{k}.csv", c.measured.columns)
    lines += write_overlays(comparisons, out)
    failed = [c for c in comparisons if not c.passed(tolerance)]
    lines.append(f"verdict: {'DISCREPANCY in ' + str(len(failed)) + ' of ' if failed else 'model agrees in all '}"
                 f"{len(comparisons)} check(s) (NRMSE tolerance {100 * tolerance:g} %)")
    lines += next_steps(comparisons, failed, args, out)
    print("\n".join(lines))
    return 1 if failed else 0
