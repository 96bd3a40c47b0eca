"""``--report DIR``: a Markdown report with PNG plots, so a person sees the effect at a glance.

Plots (identification data, baseline residual of each channel): residual against motor velocity,
against cable torque, against motor angle (or cable stretch); the residual spectrum before and after
the extension; measured / baseline / extended overlays on the validation data (inverse model, and the
closed-loop positions when they were simulated)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ankle_rt.diagnosis.core import ChannelFit, Diagnosis
from ankle_rt.diagnosis.selection import ChannelResult
from ankle_rt.diagnosis.signals import MotorChannel
from ankle_rt.plotting import MISSING, pyplot

OVERLAY_S = 3.0


def _scatter(plt, path: Path, x: np.ndarray, r: np.ndarray, xlabel: str, title: str, labels: list[str]) -> str:
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for label, xs, rs in zip(labels, np.split(x, len(labels)), np.split(r, len(labels))):
        ax.plot(xs, rs, ".", ms=2, alpha=0.5, label=label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("baseline residual (N m)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path.name


def _extended_residual(cf: ChannelFit) -> np.ndarray | None:
    """The residual of the channel's extended model on the identification data (None without effects)."""
    if not cf.specs:
        return None
    models = cf.result.models
    y, X = models.system(models.terms([(c, v) for c, v, _ in cf.specs]))
    return y - X @ cf.coef


def _spectrum(plt, path: Path, cs: ChannelResult, ext: np.ndarray | None) -> str:
    from scipy.signal import welch
    ch = cs.channel
    fs = 1.0 / (ch.dt * ch.sm.step)
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for label, r in (("baseline", cs.baseline.residual), ("extended", ext)):
        if r is None:
            continue
        f, p = welch(np.split(r, ch.m)[0], fs=fs, nperseg=min(512, len(r) // ch.m))
        ax.semilogy(f, p, label=label)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("PSD (N^2 m^2 / Hz)")
    ax.set_title(f"{cs.name} residual spectrum (first {'motor' if cs.name == 'motor' else 'axis'})")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path.name


def _overlay(plt, path: Path, diag: Diagnosis) -> str:
    results = diag.detail["results"]
    cs = next((r for r in results if r.name == diag.channel), results[0])
    cf = diag.detail["fits"][cs.name]
    vch = diag.detail["validation_channels"][cs.name]
    Xb = vch.baseline_design()
    measured = vch.torque() if isinstance(vch, MotorChannel) else vch.target()
    offset = measured - vch.target()          # the cable torque the motor feels (zero for the cable side)
    base = Xb @ cs.baseline.coef + offset
    ext = None
    if cf.specs:
        vmodels = diag.detail["validation_models"][cs.name]
        y, X = vmodels.system(vmodels.terms([(c, v) for c, v, _ in cf.specs]))
        ext = X @ cf.coef + offset + (measured - offset - y)   # back to the undelayed torque
    k = len(measured) // vch.m
    t = np.arange(k) * vch.dt * vch.sm.step
    show = t < OVERLAY_S
    fig, ax = plt.subplots(figsize=(7.5, 3.8))
    ax.plot(t[show], measured[:k][show], "k", lw=1.2, label="measured")
    ax.plot(t[show], base[:k][show], lw=1, label=f"baseline (NRMSE {diag.nrmse_baseline:.4f})")
    if ext is not None:
        ax.plot(t[show], ext[:k][show], "--", lw=1, label=f"extended (NRMSE {diag.nrmse_extended:.4f})")
    ax.set_xlabel("kept rows (s, decimated; masked samples left out)")
    ax.set_ylabel("torque (N m), filtered")
    ax.set_title(f"validation, {cs.name} channel ({'motor 1' if cs.name == 'motor' else 'DP axis'})")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path.name


def _closed_loop(plt, path: Path, closed) -> str:
    """Simulated minus measured positions: the baseline's error beside the extended model's."""
    cols = closed.columns
    t = closed.traces["t"]
    fig, axes = plt.subplots(len(cols), 1, figsize=(7.5, 1.9 * len(cols)), sharex=True)
    axes = np.atleast_1d(axes)
    for ax, c in zip(axes, cols):
        for name, style in (("baseline", "-"), ("extended", "--")):
            ax.plot(t, closed.traces[name][c] - closed.traces["measured"][c], style, lw=1, label=name)
        ax.set_ylabel(f"{c} error (rad)", fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[0].set_title(f"closed-loop free run, simulated - measured: position NRMSE {closed.nrmse_baseline:.3g} "
                      f"-> {closed.nrmse_extended:.3g}", fontsize=9)
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path.name


def write_report(directory: str | Path, diag: Diagnosis, closed=None) -> Path:
    """Write report.md and its PNGs into ``directory`` (created); returns the report's path."""
    plt = pyplot()
    if plt is None:
        raise ImportError(MISSING)
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    images: list[tuple[str, str]] = []
    for cs in diag.detail["results"]:
        ch, r = cs.channel, cs.baseline.residual
        motors = [f"motor {i + 1}" for i in range(ch.m)]
        if cs.name == "motor":
            images.append(("Residual against motor velocity",
                           _scatter(plt, out / "residual_vs_velocity.png", ch.pick(ch.vel), r,
                                    "motor velocity (rad/s)", "motor residual vs velocity", motors)))
            if np.any(ch.tc):
                images.append(("Residual against cable torque",
                               _scatter(plt, out / "residual_vs_cable_torque.png", ch.pick(ch.tc), r,
                                        "cable torque felt by the motor (N m)", "motor residual vs cable tension",
                                        motors)))
            images.append(("Residual against motor angle",
                           _scatter(plt, out / "residual_vs_motor_angle.png", ch.pick(ch.pos), r,
                                    "motor angle (rad)", "motor residual vs motor angle", motors)))
        else:
            images.append(("Cable residual against stretch",
                           _scatter(plt, out / "cable_residual_vs_stretch.png", ch.pick(ch.phi), r,
                                    "cable stretch phi (rad, ankle coordinates)", "cable residual vs stretch",
                                    ["DP", "IE"])))
        ext = _extended_residual(diag.detail["fits"][cs.name])
        images.append((f"{cs.name.capitalize()} residual spectrum",
                       _spectrum(plt, out / f"{cs.name}_residual_spectrum.png", cs, ext)))
    images.append(("Validation overlay", _overlay(plt, out / "validation_overlay.png", diag)))
    if closed is not None:
        images.append(("Closed-loop free run", _closed_loop(plt, out / "closed_loop.png", closed)))

    lines = ["# Model discrepancy diagnosis", "",
             f"**Causes: {', '.join(f'`{c}`' for c in diag.causes)}** (confidence {diag.confidence:.2f}"
             + (f", strongest in the {diag.channel} channel)" if diag.channel else ")"), ""]
    if diag.data_warnings:
        lines += ["## Data warnings", ""] + [f"- {w}" for w in diag.data_warnings] + [""]
    for e in diag.effects:
        lines += [f"## Effect `{e['type']}` ({e['channel']} channel)", "",
                  f"Confidence {e['confidence']:.2f}; removes {100 * e['rss_share']:.1f} % of the baseline residual "
                  f"with the other effects in; validation NRMSE without it / with all: {e['gain']:.2f}x"
                  + (f"; fits about as well as `{e['alternative']}`" if "alternative" in e else "") + ".", "",
                  "| parameter | value | sd |", "|---|---|---|"]
        lines += [f"| {k} | {v['value']:.6g} | {v['sd']:.2g} |" for k, v in e["parameters"].items()]
        lines.append("")
    for name, u in (diag.unexplained or {}).items():
        lines += [f"## Unexplained residual ({name} channel)", "",
                  f"The catch-all removes {100 * u['residual_removed_by_catch_all']:.0f} % of what the named effects "
                  "leave; it correlates with " + ", ".join(f"{c['with']} ({100 * c['share']:.0f} %)"
                                                            for c in u["correlates_with"]) + ".", ""]
    lines += [f"Inverse-model NRMSE on {diag.validation}: baseline {diag.nrmse_baseline:.4f}, extended "
              f"{diag.nrmse_extended:.4f} (gain {diag.gain:.2f}x).", ""]
    if closed is not None:
        lines += [f"Closed-loop free-run position NRMSE: baseline {closed.nrmse_baseline:.3g}, extended "
                  f"{closed.nrmse_extended:.3g} (gain {closed.gain:.2f}x).", ""]
    lines += ["## Re-fitted baseline", ""]
    for name, params in diag.baseline.items():
        for k, p in params.items():
            lines.append(f"- {name} {k}: {', '.join(f'{x:.5g}' for x in p['value'])} {p.get('unit', '')}")
    lines += ["", "## Candidates", "", "| cause | channel | score | residual removed |", "|---|---|---|---|"]
    lines += [f"| {c['cause']} | {c['channel'] or '-'} | {c['score']:.1f} | {100 * c['rss_reduction']:.1f} % |"
              for c in diag.candidates]
    if diag.notes:
        lines += ["", "## Notes", ""] + [f"- {n}" for n in diag.notes]
    lines += ["", "## Plots", ""]
    for title, name in images:
        lines += [f"### {title}", "", f"![{title}]({name})", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path
