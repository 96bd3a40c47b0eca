"""``ankle-rt analyze``: the linearised model's poles and the paper's model figures (Figs 8-11),
each beside the paper's value, with PNG Bode plots when matplotlib is installed.

Exit code 0 when every figure the model must reproduce is within tolerance (the known, explained
mismatches of Fig. 10 and the IE torque resonance do not count), 1 otherwise.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

DEFAULT_PLOT_DIR = "analysis-plots"
NO_MATPLOTLIB = ("matplotlib is not installed: no Bode plots written "
                 "(install the analysis extra: pip install -e \".[analysis]\")")


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "analyze", help="linear analysis: poles and the paper's Figs 8-11 beside the paper's values",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", metavar="FILE", help="configuration (default: the shipped config/sim.yaml)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the table "
                        "(no plots unless --plots is given)")
    plots = parser.add_mutually_exclusive_group()
    plots.add_argument("--plots", metavar="DIR", help=f"write PNG Bode plots into DIR (default without --json: "
                       f"./{DEFAULT_PLOT_DIR})")
    plots.add_argument("--no-plots", action="store_true", help="do not write plots")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from ankle_rt.analysis import analyze
    from ankle_rt import jsonout
    from ankle_rt.config import load_config
    from ankle_rt.params import PlantParams
    from ankle_rt.paths import default_config_path

    config_path = Path(args.config) if args.config else default_config_path()
    params = PlantParams.from_config(load_config(config_path))
    plot_dir = None if args.no_plots else (args.plots or (None if args.json else DEFAULT_PLOT_DIR))
    result = analyze(params, with_bodes=plot_dir is not None)
    written, plot_note = (write_plots(result.bodes, result.values, Path(plot_dir)) if plot_dir else ([], ""))

    if args.json:
        out = {"config": str(config_path), **result.to_json(),
               "plots": [str(p) for p in written] if plot_dir else None}
        if plot_note:
            out["plots_note"] = plot_note
            print(f"ankle-rt analyze: {plot_note}", file=sys.stderr)
        print(jsonout.dumps(out, indent=2))
    else:
        print(format_report(result, str(config_path)))
        if plot_dir:
            print(f"\nPlots: {plot_note}" if plot_note else
                  "\nPlots:\n" + "\n".join(f"  {p}" for p in written))
    return 0 if result.ok else 1


def format_report(result, config: str) -> str:
    """The human-readable table of :class:`ankle_rt.analysis.Analysis`."""
    from ankle_rt.analysis import QUANTITY, pole_json

    lines = [
        f"Linear analysis of the compliant model at rest (paper eq. 6), config {config}",
        f"transmission form: {result.form}; included: viscous friction D, cable damping beta, gravity "
        "(linearised); left out: Coulomb friction (not linear)",
        "input: decoupled motor torque tau_m = R^-T e_DP or R^-T e_IE (unit ankle torque on one axis)",
        "",
        f"{'fig':>3}  {'quantity':<50} {'axis':<4} {'model':>9} {'paper':>9}  {'error':<16}  {'tol':<8} status",
    ]
    notes: list[str] = []
    for c in result.checks:
        rel = f" ({100 * c.error / c.paper:+.1f} %)" if c.unit == "Hz" else ""
        mark = ""
        if c.note:
            if c.note not in notes:
                notes.append(c.note)
            mark = f" [{notes.index(c.note) + 1}]"
        lines.append(f"{c.figure:>3}  {QUANTITY[c.key]:<50} {c.axis.upper():<4} {c.model:>6.2f} {c.unit:<2}"
                     f" {c.paper:>6.1f} {c.unit:<2} {c.error:>+6.2f}{rel:<11}  {c.tolerance_text:<8} {c.status}{mark}")
    if notes:
        lines.append("")
        lines += [f"[{i}] known mismatch, not fitted: {n}." for i, n in enumerate(notes, 1)]
    lines += ["", "Poles, actual geometry (1/s; natural frequency, damping ratio):"]
    for s, axis in zip(result.poles, result.pole_axes):
        pj = pole_json(s)
        if pj["im"] < 0:
            continue  # print one of each conjugate pair
        zeta = "free motion" if pj["damping_ratio"] is None else f"zeta {pj['damping_ratio']:.4f}"
        pair = f" +/- {pj['im']:.1f}j" if pj["im"] > 0 else ""
        lines.append(f"  {pj['re']:>10.4f}{pair:<14} {pj['freq_hz']:>9.3f} Hz  {axis.upper()}  {zeta}")
    n_fail = sum(c.status == "FAIL" for c in result.checks)
    n_mis = sum(c.status == "MISMATCH" for c in result.checks)
    lines.append("")
    lines.append(("RESULT: all reproducible figures within tolerance" if result.ok else
                  f"RESULT: {n_fail} figure(s) out of tolerance") +
                 (f"; {n_mis} known mismatch(es), explained above" if n_mis else ""))
    return "\n".join(lines)


def write_plots(bodes: dict, values: dict, out_dir: Path) -> tuple[list[Path], str]:
    """Write one PNG per figure; returns (paths, note). The note says why nothing was written."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        return [], NO_MATPLOTLIB
    import numpy as np

    from ankle_rt.analysis import PAPER

    marked = {"fig8_unit_ratio": "resonance_unit_ratio_hz", "fig10_soft_cables": "fig10_resonance_hz",
              "fig11_joint_torque": "torque_resonance_hz"}
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return [], f"cannot create the plot directory {out_dir}: {exc.strerror}; no Bode plots written"
    from ankle_rt.progress import Progress

    written = []
    progress = Progress("analyze: Bode plots", len(bodes))
    for k, (name, bode) in enumerate(bodes.items()):
        progress.update(k, name)
        fig = Figure(figsize=(11, 7), layout="constrained")
        axes = fig.subplots(2, 2, sharex=True)
        fig.suptitle(bode.title)
        for col, (axis, curves) in enumerate(bode.curves.items()):
            mag_ax, ph_ax = axes[0, col], axes[1, col]
            peak = max(float(np.max(np.abs(h))) for h in curves.values())
            for label, h in curves.items():
                if np.max(np.abs(h)) < 1e-9 * peak:
                    continue  # an output the decoupled input does not reach
                style = "--" if label.endswith("_2") else "-"  # motor 2 often lies on motor 1
                mag_ax.semilogx(bode.freqs_hz, 20 * np.log10(np.abs(h)), style, label=label)
                ph_ax.semilogx(bode.freqs_hz, np.degrees(np.unwrap(np.angle(h))), style, label=label)
            if name in marked:
                f_res = values[marked[name]][axis]
                f_paper = PAPER[marked[name]][axis]
                mag_ax.axvline(f_res, color="grey", ls="--", lw=0.8, label=f"model peak {f_res:.1f} Hz")
                mag_ax.axvline(f_paper, color="black", ls=":", lw=0.8, label=f"paper {f_paper:g} Hz")
            mag_ax.set_title(f"decoupled {axis.upper()} input")
            mag_ax.set_ylabel(f"magnitude (dB re 1 {bode.ylabel})")
            ph_ax.set_ylabel("phase (deg)")
            ph_ax.set_xlabel("frequency (Hz)")
            mag_ax.grid(True, which="both", alpha=0.3)
            ph_ax.grid(True, which="both", alpha=0.3)
            mag_ax.legend(fontsize=8)
        path = out_dir / f"{name}.png"
        fig.savefig(path, dpi=100)
        written.append(path)
    progress.close()
    return written, ""
