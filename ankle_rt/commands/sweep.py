"""``ankle-rt sweep SPEC.yaml``: a robustness study over the device's uncertainty (docs/sweeps.md).

Samples the spec's parameters, runs every (sample, scenario) on the batch simulator with the
configured controller, and writes to ``--out`` (default: ``sweep-<spec name>/`` in the working
directory): ``results.parquet`` (or ``.csv`` without pyarrow; one row per run, every sampled
parameter and metric), ``summary.json``, ``plots/`` and ``batches/`` (per-batch results: started
again, a study resumes from them). Runs on all cores, or on a Dask cluster with ``--scheduler``.
``--rerun ID`` replays one run as a full logged ``ankle-rt run --fast``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ankle_rt import jsonout


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("sweep", help="robustness study: many simulated runs over sampled parameters",
                              description=__doc__.split("\n\n", 1)[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("spec", metavar="SPEC.yaml", help="the study spec")
    p.add_argument("--out", metavar="DIR", help="output directory (default: ./sweep-<spec name>)")
    p.add_argument("--runs", type=int, metavar="N", help="number of samples (overrides sampling.runs)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address (overrides dask.scheduler)")
    p.add_argument("--workers", type=int, metavar="N", help="local processes (default: all cores)")
    p.add_argument("--rerun", type=int, metavar="ID", help="replay run ID as a logged `ankle-rt run --fast`")
    p.add_argument("--no-plots", action="store_true", help="skip the plots")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(handler=sweep)


def sweep(args: argparse.Namespace) -> int:
    from ankle_rt.config import ConfigError
    from ankle_rt.sweep.spec import SpecError, load_study

    if args.runs is not None and args.runs < 1:
        print("ankle-rt sweep: --runs must be >= 1", file=sys.stderr)
        return 2
    try:
        study = load_study(args.spec, runs=args.runs, scheduler=args.scheduler)
    except (SpecError, ConfigError) as exc:
        print(f"ankle-rt sweep: bad spec {args.spec}: {exc}", file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else Path(f"sweep-{Path(args.spec).stem}")
    if args.rerun is not None:
        return rerun(study, args.rerun, out)
    from ankle_rt.sweep.engine import execute, write_table
    from ankle_rt.sweep.report import format_summary, plot, summarize

    where = f"Dask scheduler {study.scheduler}" if study.scheduler else "local cores"
    if not args.json:
        print(f"{len(study.runs)} runs ({study.runs_requested if study.method != 'grid' else 'grid'} samples x "
              f"{len(study.scenarios)} scenarios, {study.duration_s:g} s each) on {where} ...", flush=True)
    t0 = time.monotonic()
    try:
        rows = execute(study, out, scheduler=study.scheduler, workers=args.workers)
    except (OSError, RuntimeError) as exc:
        print(f"ankle-rt sweep: {exc}", file=sys.stderr)
        return 1
    wall = time.monotonic() - t0
    table = write_table(rows, out)
    summary = summarize(study, rows)
    summary["wall_s"] = wall
    summary["table"] = str(table)
    summary["plots"] = [] if args.no_plots else [str(p) for p in plot(study, rows, summary, out / "plots")]
    (out / "summary.json").write_text(jsonout.dumps(summary, indent=1))
    if args.json:
        print(jsonout.dumps(summary))
    else:
        print(format_summary(summary))
        print(f"{len(rows)} runs in {wall:.1f} s wall; table {table}, summary {out / 'summary.json'}"
              + (f", plots in {out / 'plots'}" if summary["plots"] else ""))
    return 0


def _without_none(value):
    if isinstance(value, dict):
        return {k: _without_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_without_none(v) for v in value]
    return value


def rerun(study, run_id: int, out: Path) -> int:
    """Write run ``run_id``'s config and replay it through the real daemon with a run log."""
    import yaml

    from ankle_rt.commands.run import run as run_command

    if not 0 <= run_id < len(study.runs):
        print(f"ankle-rt sweep: --rerun {run_id}: the study has runs 0..{len(study.runs) - 1}", file=sys.stderr)
        return 2
    r = study.runs[run_id]
    directory = out / "rerun"
    directory.mkdir(parents=True, exist_ok=True)
    cfg_path = directory / f"run-{run_id}.yaml"
    cfg = _without_none(dict(r.config))     # None is "the default" in a validated config
    cfg["logging"] = {**cfg["logging"], "directory": str(directory)}
    header = (f"# run {run_id} of {study.path}: sample {r.sample}, scenario {r.scenario}, seed {r.seed}\n"
              f"# sampled: {jsonout.dumps(r.values)}\n")
    cfg_path.write_text(header + yaml.safe_dump(cfg, sort_keys=False))
    print(f"run {run_id}: config {cfg_path}", flush=True)
    return run_command(argparse.Namespace(config=str(cfg_path), duration=study.duration_s, fast=True,
                                          log=str(directory / f"run-{run_id}.arlog"), no_log=False, socket=None,
                                          no_plot=False, json=False))
