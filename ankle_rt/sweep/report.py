"""The study summary (pass rates, worst cases, the parameters that matter) and its plots."""

from __future__ import annotations

import math
import re
from collections import Counter
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ankle_rt.sweep.spec import Study

WORST = 5


def badness(row: dict[str, Any]) -> float:
    """Larger is worse: a failed run ranks above any passed one, then the larger tracking RMS."""
    rms = max(row["tracking_rms_dp_deg"], row["tracking_rms_ie_deg"])
    rms = rms if math.isfinite(rms) else 1e6
    return (0.0 if row["passed"] else 1e6) + (1e6 if row["faulted"] else 0.0) + rms


def rank_correlation(x: np.ndarray, y: np.ndarray) -> float:
    """Spearman's rho (average ranks for ties); NaN when either side is constant."""
    def ranks(v: np.ndarray) -> np.ndarray:
        order = np.argsort(v, kind="mergesort")
        r = np.empty(len(v))
        r[order] = np.arange(len(v), dtype=float)
        sv = v[order]
        start = 0
        for i in range(1, len(v) + 1):          # average the ranks of tied values
            if i == len(v) or sv[i] != sv[start]:
                r[order[start:i]] = 0.5 * (start + i - 1)
                start = i
        return r
    if len(x) < 3 or np.all(x == x[0]) or np.all(y == y[0]):
        return math.nan
    rx, ry = ranks(x), ranks(y)
    return float(np.corrcoef(rx, ry)[0, 1])


def numeric_parameters(study: Study, rows: Sequence[dict[str, Any]]) -> list[str]:
    return [p.column for p in study.parameters
            if all(isinstance(r[p.column], (int, float)) and not isinstance(r[p.column], bool) for r in rows)]


def summarize(study: Study, rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    n = len(rows)
    by_scenario: dict[str, dict[str, Any]] = {}
    for name in study.scenarios:
        sub = [r for r in rows if r["scenario"] == name]
        by_scenario[name] = {"runs": len(sub), "pass_rate": _rate(sub, "passed"), "stable_rate": _rate(sub, "stable"),
                             "faults": dict(Counter(r["fault"] for r in sub if r["faulted"]))}
    worst = sorted(rows, key=badness, reverse=True)[:WORST]
    keys = [p.column for p in study.parameters]
    influence = []
    bad = np.array([badness(r) for r in rows])
    passed = np.array([1.0 if r["passed"] else 0.0 for r in rows])
    for key in numeric_parameters(study, rows):
        x = np.array([float(r[key]) for r in rows])
        influence.append({"parameter": key, "rho_badness": rank_correlation(x, bad),
                          "rho_passed": rank_correlation(x, passed)})
    influence.sort(key=lambda d: -abs(d["rho_badness"]) if math.isfinite(d["rho_badness"]) else 0.0)
    return {
        "runs": n, "samples": len({r["sample"] for r in rows}), "pass_rate": _rate(rows, "passed"),
        "stable_rate": _rate(rows, "stable"), "by_scenario": by_scenario,
        "faults": dict(Counter(r["fault"] for r in rows if r["faulted"])),
        "worst": [{"run_id": r["run_id"], "scenario": r["scenario"], "passed": r["passed"], "fault": r["fault"],
                   "tracking_rms_dp_deg": r["tracking_rms_dp_deg"], "tracking_rms_ie_deg": r["tracking_rms_ie_deg"],
                   "parameters": {k: r[k] for k in keys}} for r in worst],
        "influence": influence,
    }


def _rate(rows: Sequence[dict[str, Any]], key: str) -> float:
    return sum(1 for r in rows if r[key]) / len(rows) if rows else math.nan


def format_summary(s: dict[str, Any]) -> str:
    lines = [f"{s['runs']} runs ({s['samples']} samples): {100 * s['pass_rate']:.1f} % passed, "
             f"{100 * s['stable_rate']:.1f} % stable"]
    for name, d in s["by_scenario"].items():
        faults = ", ".join(f"{k} {v}" for k, v in d["faults"].items()) or "none"
        lines.append(f"  {name:12s} {d['runs']:5d} runs  passed {100 * d['pass_rate']:5.1f} %  "
                     f"stable {100 * d['stable_rate']:5.1f} %  faults: {faults}")
    lines.append("most influential parameters (Spearman rho against badness / against passing):")
    for d in s["influence"]:
        lines.append(f"  {d['parameter']:40s} {_rho(d['rho_badness'])} / {_rho(d['rho_passed'])}")
    lines.append("worst runs:")
    for w in s["worst"]:
        params = ", ".join(f"{k}={_fmt(v)}" for k, v in w["parameters"].items())
        lines.append(f"  #{w['run_id']} {w['scenario']}: {'passed' if w['passed'] else 'FAILED'}"
                     f"{' (' + w['fault'] + ')' if w['fault'] != 'none' else ''}, tracking RMS "
                     f"{w['tracking_rms_dp_deg']:.3g} / {w['tracking_rms_ie_deg']:.3g} deg; {params}")
    return "\n".join(lines)


def _rho(v: float) -> str:
    return f"{v:+.2f}" if math.isfinite(v) else "  n/a"


def _fmt(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


# Units a schema field's doc starts with (longest first), e.g. "N m s/rad, viscous friction D".
_UNIT = re.compile(r"^(kg m\^2|N m s/rad|N m/rad|N m/A|N m|N/m|rad/s|rad|Hz|1/s|kg|m|s|A)(?=$|[ ,;])")


def _field(study: Study, key: str) -> Any:
    """The schema field of a sampled config key (an effect's parameter from its effect's schema)."""
    parts = key.split(".")
    if parts[:2] == ["sim", "effects"] and len(parts) == 4 and parts[2].isdigit():
        from ankle_rt.backend import load_by_name

        effects = (study.runs[0].config["sim"]["effects"] if study.runs else []) or []
        index = int(parts[2])
        kind = effects[index].get("type") if index < len(effects) else None
        registry = load_by_name("sim_backend.effects.base:EFFECTS")
        return registry[kind].PARAMS.fields.get(parts[3]) if kind in registry else None
    from ankle_rt.config_schema import SCHEMA
    from ankle_rt.schema import numeric_fields

    return dict(numeric_fields(SCHEMA)).get(".".join("*" if q.isdigit() else q for q in parts))


def axis_label(study: Study, column: str) -> str:
    """A plot axis for a table column of a sampled parameter, with its unit (``delay (s)``), or
    ``(factor)`` for a relative one."""
    param = next((p for p in study.parameters if p.column == column), None)
    if param is None or param.relative:
        return column
    match = _UNIT.match(getattr(_field(study, param.key), "doc", "") or "")
    return f"{column} ({match.group(1)})" if match else column


def plot(study: Study, rows: Sequence[dict[str, Any]], summary: dict[str, Any], directory: Path) -> list[Path]:
    """Histograms of the main metrics and the failure region over the two most influential
    parameters. Returns the files written (none without matplotlib)."""
    from ankle_rt.plotting import pyplot

    plt = pyplot()
    if plt is None:
        return []
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    metrics = [("tracking_rms_dp_deg", "tracking RMS DP (deg)"), ("tracking_rms_ie_deg", "tracking RMS IE (deg)"),
               ("current_rms_ratio", "RMS current / continuous limit"), ("overshoot_dp_pct", "overshoot DP (%)"),
               ("settling_dp_s", "settling DP (s)"), ("cable_torque_peak_nm", "peak cable torque (N m)")]
    fig, axes = plt.subplots(2, 3, figsize=(13, 7))
    for ax, (key, label) in zip(axes.ravel(), metrics):
        v = np.array([r[key] for r in rows], dtype=float)
        v = v[np.isfinite(v)]
        if v.size:
            ax.hist(v, bins=40)
        ax.set_xlabel(label)
        ax.set_ylabel("runs")
    fig.tight_layout()
    path = directory / "histograms.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    written.append(path)
    top = [d["parameter"] for d in summary["influence"][:2]]
    if len(top) == 2:
        fig, ax = plt.subplots(figsize=(7, 6))
        x = np.array([float(r[top[0]]) for r in rows])
        y = np.array([float(r[top[1]]) for r in rows])
        ok = np.array([bool(r["passed"]) for r in rows])
        ax.scatter(x[ok], y[ok], s=10, c="tab:green", label="passed")
        ax.scatter(x[~ok], y[~ok], s=14, c="tab:red", marker="x", label="failed")
        ax.set_xlabel(axis_label(study, top[0]))
        ax.set_ylabel(axis_label(study, top[1]))
        ax.set_title("failure region over the two most influential parameters")
        ax.legend()
        fig.tight_layout()
        path = directory / "failure_region.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        written.append(path)
    return written
