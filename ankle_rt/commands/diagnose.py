"""``ankle-rt diagnose``: name what the simulation gets wrong in measured data, fit the effect, measure
the gain (method: docs/diagnosis.md)."""

from __future__ import annotations

import argparse
import os
import sys

from ankle_rt.commands.outputs import output_problem


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "diagnose", help="find, name and fit the model discrepancy in measured data",
        description="Re-fit the baseline model (J, D, kc; cable stiffness) to an interchange CSV or a run log, "
                    "test every named effect (stribeck, asymmetric_friction, load_dependent_friction, backlash, "
                    "cogging, delay, stiffness_nonlinear, torque_offset) and a catch-all after screening the data for "
                    "sensor artefacts, name every effect present (or none / unknown), and report the validation "
                    "gain of the extended model.")
    p.add_argument("data", nargs="?", help="identification data: interchange CSV or `ankle-rt run` log")
    p.add_argument("--batch", metavar="DIR", help="every log under DIR, one row each, with parameter trends "
                                                  "over time (docs/sweeps.md; --report DIR for the outputs)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="with --batch: run on this Dask scheduler")
    p.add_argument("--validation", metavar="FILE",
                   help="validation data (default: the last 25 %% of the identification data is held out)")
    p.add_argument("--plant", choices=("ankle", "actuator"), default="ankle",
                   help="ankle: two motors on the cables (needs --config); actuator: motors off the cables")
    p.add_argument("--config", metavar="FILE", help="nominal model config (optional for --plant actuator)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--report", metavar="DIR", help="write report.md and PNG plots here")
    p.add_argument("--write-model", metavar="FILE", help="write the config that switches the named effects on")
    p.add_argument("--no-closed-loop", action="store_true",
                   help="skip the free-run closed-loop simulation gain on daemon runs")
    p.set_defaults(handler=run)


def _format(diag, closed) -> str:
    lines = [f"causes: {', '.join(diag.causes)}  (confidence {diag.confidence:.2f}"
             + (f", {diag.channel} channel)" if diag.channel else ")")]
    for w in diag.data_warnings:
        lines.append(f"data warning: {w}")
    for e in diag.effects:
        lines.append(f"effect {e['type']} ({e['channel']} channel, confidence {e['confidence']:.2f}, "
                     f"validation gain {e['gain']:.2f}x, {100 * e['rss_share']:.1f} % of the baseline residual)"
                     + (f": fits about as well as {e['alternative']}" if "alternative" in e else ""))
        for k, v in e["parameters"].items():
            lines.append(f"  {k} = {v['value']:.6g} ± {v['sd']:.2g}")
    for name, u in (diag.unexplained or {}).items():
        lines.append(f"unexplained ({name} channel): correlates with "
                     + ", ".join(f"{c['with']} ({100 * c['share']:.0f} %)" for c in u["correlates_with"]))
    for label, fits in (("re-fitted alone", diag.baseline), ("within the extended model", diag.baseline_extended)):
        for name, params in (fits or {}).items():
            vals = ", ".join(f"{k} {', '.join(f'{x:.4g}' for x in p['value'])}" for k, p in params.items())
            lines.append(f"baseline ({name}, {label}): {vals}")
    lines.append(f"inverse-model NRMSE on {diag.validation}: baseline {diag.nrmse_baseline:.4f}, "
                 f"extended {diag.nrmse_extended:.4f}, gain {diag.gain:.2f}x")
    if closed is not None:
        lines.append(f"closed-loop position NRMSE ({closed.duration_s:.1f} s free run): baseline "
                     f"{closed.nrmse_baseline:.3g}, extended {closed.nrmse_extended:.3g}, gain {closed.gain:.2f}x")
    lines.append("candidates, each alone (score = information-criterion gain over the baseline):")
    for c in diag.candidates:
        name = "unknown (catch-all)" if c.get("catch_all") else c["cause"]
        lines.append(f"  {name:<24} {c['channel'] or '-':<6} score {c['score']:>10.1f}  "
                     f"residual removed {100 * c['rss_reduction']:5.1f} %")
    lines += [f"note: {n}" for n in diag.notes]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from ankle_rt import jsonout

    try:
        import scipy  # noqa: F401
    except ImportError:
        print("ankle-rt diagnose: needs the analysis extra (scipy, matplotlib): pip install 'ankle-rt[analysis]'",
              file=sys.stderr)
        return 3
    if args.report and os.path.exists(args.report) and not os.path.isdir(args.report):
        print(f"ankle-rt diagnose: --report {args.report}: exists and is not a directory", file=sys.stderr)
        return 2
    if args.batch:
        from ankle_rt.sweep.logs import batch_command
        return batch_command(args)
    if args.data is None:
        print("ankle-rt diagnose: give a data file (or --batch DIR)", file=sys.stderr)
        return 2
    from ankle_rt.config import ConfigError, load_config
    from ankle_rt.diagnosis import DiagnosisError, diagnose
    from ankle_rt.diagnosis.closed_loop import applicable, closed_loop_gain
    from ankle_rt.diagnosis.model_fragment import write_fragment
    from ankle_rt.identification.data import load_recording
    from ankle_rt.interchange import InterchangeError
    from ankle_rt.progress import Progress

    if args.write_model:
        problem = output_problem(args.write_model, (args.data, args.validation, args.config))
        if problem:
            print(f"ankle-rt diagnose: --write-model {args.write_model}: {problem}", file=sys.stderr)
            return 2
    cfg = load_config(args.config) if args.config else None
    progress = Progress("diagnose", 4)   # stages: read, fit and select, closed-loop gain, write
    try:
        progress.update(0, "reading the data")
        # sampling and units checked (against cfg when given); the screening masks around time gaps
        ident = load_recording(args.data, cfg=cfg, gaps_masked=True)
        valid = load_recording(args.validation, cfg=cfg, gaps_masked=True) if args.validation else None
        for rec in (ident, valid):
            for warning in (rec.extra["warnings"] if rec is not None else ()):
                print(f"ankle-rt diagnose: warning: {warning}", file=sys.stderr)
        progress.update(1, "fitting the baseline and the candidate effects")
        diag = diagnose(ident, valid, plant=args.plant, cfg=cfg)
    except (InterchangeError, DiagnosisError) as exc:
        progress.close()
        print(f"ankle-rt diagnose: {exc}", file=sys.stderr)
        return 2
    closed = None
    run_data = valid if valid is not None else ident
    if (not args.no_closed_loop and args.config and args.plant == "ankle" and diag.effects
            and applicable(run_data)):
        progress.update(2, "closed-loop simulation of both models")
        try:
            closed = closed_loop_gain(run_data, args.config, diag)
        except ConfigError as exc:       # the controller built on the re-fit refuses it: no re-run, a note
            diag.notes.append(f"closed-loop gain not computed: {exc}")
    progress.update(3, "writing the results")
    if args.write_model:
        try:
            write_fragment(args.write_model, diag, args.config)
        except OSError as exc:
            progress.close()
            print(f"ankle-rt diagnose: cannot write {args.write_model}: {exc.strerror}", file=sys.stderr)
            return 1
    if args.report:
        from ankle_rt.diagnosis.report import write_report
        write_report(args.report, diag, closed)
    progress.close()
    if args.json:
        out = diag.to_json()
        if closed is not None:
            out["closed_loop"] = closed.to_json()
        print(jsonout.dumps(out, indent=2))
    else:
        print(_format(diag, closed))
    return 0
