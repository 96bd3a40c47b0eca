"""``ankle-rt identify``: the paper's actuator identification (section 3), run on the configured
backend with the motors off the cables, or estimated from recorded interchange CSV files."""

from __future__ import annotations

import argparse
import sys
from datetime import datetime, timezone
from pathlib import Path


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "identify", help="identify actuator J, D and friction (stiction, viscous, inertia experiments)",
        description="Run the paper's actuator experiments on the configured backend (motors off the "
                    "cables: sim.cables false) or estimate from recorded CSV files; write a parameter "
                    "YAML a config can include, a text report like Table 1 and Figs 2-4, and PNG plots.")
    p.add_argument("experiment", choices=("stiction", "viscous", "inertia", "all"))
    p.add_argument("--config", help="config file (backend, torque constant, prior parameters); default for "
                   "running the experiments: the shipped config/sim.yaml; with --from: none (no torque constant)")
    p.add_argument("--from", dest="source", metavar="PATH",
                   help="estimate from data: an interchange CSV (or a daemon run log) for one experiment, or "
                        "for 'all' a directory holding stiction.csv, viscous.csv and inertia.csv (what a "
                        "run writes to --out)")
    p.add_argument("--motor", type=int, choices=(1, 2), default=1, help="which motor (default 1)")
    p.add_argument("--repeats", type=_positive_int, default=3, help="repeats per direction of each experiment (default 3)")
    p.add_argument("--out", default="identification", help="output directory (default ./identification)")
    p.add_argument("--batch", metavar="DIR", help="every session folder under DIR holding the experiment's CSVs: "
                                                  "one row each, parameter trends over time (docs/sweeps.md)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="with --batch: run on this Dask scheduler")
    p.set_defaults(handler=run)


def _read(args: argparse.Namespace, names: tuple[str, ...]) -> dict:
    from ankle_rt.identification.actuator import MIN_ROWS
    from ankle_rt.identification.data import load_recording
    from ankle_rt.identification.signals import IdentificationError

    src = Path(args.source)
    if len(names) == 1 and not src.is_dir():
        return {names[0]: load_recording(src, MIN_ROWS[names[0]])}
    if not src.is_dir():
        raise IdentificationError(f"{src}: for 'all', --from takes a directory holding "
                                  f"{', '.join(n + '.csv' for n in names)}")
    return {name: load_recording(src / f"{name}.csv", MIN_ROWS[name]) for name in names}


def run(args: argparse.Namespace) -> int:
    from ankle_rt.config import load_config
    from ankle_rt.identification.actuator import EXPERIMENTS, identify, run_experiments
    from ankle_rt.identification.report import parameter_yaml, report_lines, write_plots
    from ankle_rt.identification.runner import actuator_config
    from ankle_rt.identification.signals import IdentificationError
    from ankle_rt.interchange import InterchangeError, write_csv
    from ankle_rt.paths import default_config_path
    from ankle_rt.progress import Progress

    if args.batch:
        from ankle_rt.sweep.logs import identify_batch_command
        return identify_batch_command(args)
    names = EXPERIMENTS if args.experiment == "all" else (args.experiment,)
    if args.config is None and not args.source:
        args.config = str(default_config_path())
    cfg = load_config(args.config) if args.config else None
    out = Path(args.out)
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    try:
        if args.source:
            recordings = _read(args, names)
            header = f"Actuator identification from {args.source}, motor {args.motor} ({stamp})"
        else:
            acfg, note = actuator_config(cfg)
            sim = acfg["sim"]
            noise = (f"; quantisation {'on' if sim['quantization'] else 'off'}, strain-gauge noise "
                     f"{'on' if sim['sensor_noise'] else 'off'}") if acfg["backend"] == "sim" else ""
            print(f"running {', '.join(names)} on backend {acfg['backend']!r}, motor {args.motor}, "
                  f"{args.repeats} repeats per direction ({note}{noise}) ...", flush=True)
            with Progress("identify", 1.0) as progress:
                recordings = run_experiments(acfg, names, args.motor, args.repeats, progress=progress.callback)
            header = (f"Actuator identification on backend {acfg['backend']!r}, motor {args.motor}, {note}{noise} "
                      f"({stamp})")
        kt = cfg["actuator"]["torque_constant"] if cfg else None
        result = identify(recordings, args.motor, kt, prior=cfg["actuator"] if cfg else None)
    except (InterchangeError, IdentificationError) as exc:
        print(f"ankle-rt identify: {exc}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    if not args.source:
        for name, rec in recordings.items():
            write_csv(out / f"{name}.csv", rec.columns)
    lines = report_lines(result, header)
    lines += [""] + write_plots(result, recordings, out, args.motor, kt)
    (out / "params.yaml").write_text(parameter_yaml(result, header))
    (out / "report.txt").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"\nwrote {out / 'params.yaml'} (include it from a config) and {out / 'report.txt'}")
    return 0
