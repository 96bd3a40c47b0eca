"""What a run did, from its records: tracking errors per axis, peak currents, loop timing, faults.
Shared by ``ankle-rt run`` (printed at the end) and ``ankle-rt log info``. Both read at most
SUMMARY_MAX_RECORDS of the most recent records, so a run of days is summarised in bounded memory and
time (the summary then says which part of the run it covers)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ankle_rt.log.reader import RunLog
from ankle_rt.plotting import MISSING, pyplot
from ankle_rt.safety import Fault, State

STEADY_WINDOW_S = 0.5   # the "final error" is the mean |error| over the run's last 0.5 s of activity
SETTLE_S = 0.5          # "settled": the reference has not changed for this long (step transients excluded)
SUMMARY_MAX_RECORDS = 300_000   # records a summary reads (read_log(last=...)): 5 min at 1 kHz, ~50 MB


def _percentiles(values: np.ndarray) -> dict[str, float]:
    """p50/p99/p99.9/max of ``values`` (NaN when empty)."""
    if not len(values):
        return {"p50": math.nan, "p99": math.nan, "p99.9": math.nan, "max": math.nan}
    p50, p99, p999 = np.percentile(values, (50, 99, 99.9))
    return {"p50": float(p50), "p99": float(p99), "p99.9": float(p999), "max": float(values.max())}


def summarize(records: np.ndarray, meta: dict[str, Any] | None = None) -> dict[str, Any]:
    """Summary of a run's records (RECORD_DTYPE); ``meta`` is the log header's metadata (its
    ``clock`` says whether loop timing was measured). Angles in degrees, currents in A, times in µs."""
    n = len(records)
    out: dict[str, Any] = {"cycles": n, "clock": (meta or {}).get("clock", "monotonic")}
    if n == 0:
        return out
    t = records["t"]
    state = records["state"]
    active = state == State.ACTIVE
    out["duration_s"] = float(t[-1] - t[0])
    out["active_s"] = float(active.sum() * np.median(np.diff(t))) if n > 1 else 0.0
    out["final_state"] = State(int(state[-1])).name
    i = first_fault(records)
    if i is not None:
        code = Fault(int(records["fault"][i]))
        out["fault"] = {"name": code.name, "description": code.description, "t": float(t[i])}
    has_joint = not np.isnan(records["ankle_dp"]).all()
    has_ref = not np.isnan(records["ref_dp"]).all()
    out["ankle_source"] = "joint encoders" if has_joint else "estimate (R^-1 theta_m - K^-1 tau_j)"
    if has_ref and active.any():
        t_act = t[active]
        steady = active & (t >= t_act[-1] - STEADY_WINDOW_S)
        changed = np.zeros(n, dtype=bool)
        changed[0] = True
        changed[1:] = (np.diff(records["ref_dp"]) != 0) | (np.diff(records["ref_ie"]) != 0)
        last_change = t[np.maximum.accumulate(np.where(changed, np.arange(n), 0))]
        settled = active & (t - last_change >= SETTLE_S)
        errors = {}
        for axis in ("dp", "ie"):
            ankle = records[f"ankle_{axis}"] if has_joint else records[f"est_ankle_{axis}"]
            err = np.abs(np.degrees(ankle - records[f"ref_{axis}"]))
            errors[axis.upper()] = {"rms_deg": float(np.sqrt(np.mean(err[active] ** 2))),
                                    "max_abs_deg": float(np.max(err[active])),
                                    "settled_max_abs_deg": float(np.max(err[settled])) if settled.any() else math.nan,
                                    "settled_mean_abs_deg": float(np.mean(err[settled])) if settled.any() else math.nan,
                                    "final_abs_deg": float(np.mean(err[steady]))}
        out["tracking_error"] = errors
    out["peak_current_a"] = [float(np.max(np.abs(records[f"current_cmd_{i}"]))) for i in (1, 2)]
    out["rms_current_a"] = [float(np.sqrt(np.mean(records[f"current_cmd_{i}"][active] ** 2))) if active.any()
                            else 0.0 for i in (1, 2)]
    period = records["period_us"][1:].astype(float)
    nominal = float(np.median(period)) if len(period) else math.nan
    err = np.abs(period - nominal)
    lat = records["latency_us"].astype(float)
    out["loop"] = {
        "period_nominal_us": nominal,
        "period_error_us": _percentiles(err),
        "latency_us": _percentiles(lat),
        "overruns": int(records["overruns"][-1]),
        "late_cycles": int(np.sum(period > 2 * nominal)) if len(period) else 0,
    }
    return out


def summarize_log(log: RunLog) -> dict[str, Any]:
    """:func:`summarize` of the records read; when they are only the tail of a longer run, ``window``
    says what they cover (the records read, all records, the whole run's duration in s)."""
    out = summarize(log.records, log.meta)
    if log.is_tail and len(log.records):
        out["window"] = {"records": len(log.records), "total_records": log.total_records,
                         "run_s": float(log.records["t"][-1] - log.first_t)}
    return out


def format_summary(s: dict[str, Any]) -> str:
    """A few readable lines."""
    if s.get("cycles", 0) == 0:
        return "empty run (no records)"
    lines = [f"{s['cycles']} cycles, {s['duration_s']:.3f} s ({s['active_s']:.3f} s active), "
             f"final state {s['final_state']}"]
    if "window" in s:
        w = s["window"]
        lines.append(f"(summary of the last {s['duration_s']:.1f} s of a {w['run_s']:.1f} s run: the last "
                     f"{w['records']} of {w['total_records']} records; overruns count the whole run)")
    if "fault" in s:
        f = s["fault"]
        lines.append(f"FAULT {f['name']} at t = {f['t']:.3f} s: {f['description']}")
    if "tracking_error" in s:
        lines.append(f"tracking error |ankle - reference|, deg (ankle from {s['ankle_source']}):")
        lines.append("        rms      max   settled mean   settled max   final")
        never_settled = False
        for axis, e in s["tracking_error"].items():
            mean, peak = e["settled_mean_abs_deg"], e["settled_max_abs_deg"]
            never_settled |= math.isnan(mean)
            lines.append(f"  {axis}  {e['rms_deg']:6.3f}  {e['max_abs_deg']:7.3f}  {_or_dash(mean, 13, '.4f')}  "
                         f"{_or_dash(peak, 12, '.4f')}  {e['final_abs_deg']:6.4f}")
        lines.append(f"  (settled: the reference unchanged for >= {SETTLE_S} s, disturbances included"
                     + (" - never, in this run" if never_settled else "")
                     + f"; final: mean over the last {STEADY_WINDOW_S} s)")
    pk, rms = s["peak_current_a"], s["rms_current_a"]
    lines.append(f"current: peak {pk[0]:.2f} / {pk[1]:.2f} A, rms while active {rms[0]:.2f} / {rms[1]:.2f} A")
    lp = s["loop"]
    if s.get("clock") == "simulated":
        lines.append("loop: lockstep on a simulated clock (no timing to measure); "
                     "`ankle-rt bench loop` measures the real-time loop")
        return "\n".join(lines)
    pe, la = lp["period_error_us"], lp["latency_us"]
    lines.append(f"loop: period {lp['period_nominal_us']:.0f} us; period error p50/p99/p99.9/max "
                 f"{pe['p50']:.1f} / {pe['p99']:.1f} / {pe['p99.9']:.1f} / {pe['max']:.1f} us")
    lines.append(f"      read-to-write latency p50/p99/p99.9/max {la['p50']:.1f} / {la['p99']:.1f} / "
                 f"{la['p99.9']:.1f} / {la['max']:.1f} us; overruns {lp['overruns']}, "
                 f"late cycles (> 2 periods) {lp['late_cycles']}")
    return "\n".join(lines)


def _or_dash(value: float, width: int, spec: str) -> str:
    """``value`` formatted, or a right-aligned '-' where there is none (NaN)."""
    return f"{'-':>{width}}" if math.isnan(value) else f"{value:{width}{spec}}"


def first_fault(records: np.ndarray) -> int | None:
    """Index of the first record that carries a fault, None when none does."""
    faults = np.flatnonzero(records["fault"] != Fault.NONE)
    return int(faults[0]) if faults.size else None


def run_outcome(records: np.ndarray) -> str:
    """How a run ended, in words: its first fault and when, else its final state."""
    i = first_fault(records)
    if i is not None:
        return f"FAULT {Fault(int(records['fault'][i])).name} at t = {float(records['t'][i]):.3f} s"
    return f"ended {State(int(records['state'][-1])).name}" if len(records) else "no records"


def state_marks(records: np.ndarray) -> dict[str, np.ndarray]:
    """Sample times (s) at which the run was activated, left ACTIVE (deactivated, stopped or
    faulted), and its first fault."""
    t, active = records["t"], records["state"] == State.ACTIVE
    i = first_fault(records)
    return {"activate": t[1:][active[1:] & ~active[:-1]], "deactivate": t[1:][~active[1:] & active[:-1]],
            "fault": t[:0] if i is None else t[i:i + 1]}


MARK_STYLE = {"activate": {"color": "tab:green", "ls": ":", "lw": 1.0},
              "deactivate": {"color": "0.35", "ls": ":", "lw": 1.0},
              "fault": {"color": "tab:red", "ls": "-", "lw": 1.5}}


def plot_run(records: np.ndarray, torque_constant: float, out_png: str, what: str = "") -> str:
    """A figure like the paper's Figs 13-15: (a) ankle and motor angles with the references,
    (b) motor torques; titled with ``what`` ran and how it ended, with the activations,
    deactivations and the first fault marked. Returns a note; matplotlib is optional (the analysis
    extra)."""
    plt = pyplot()
    if plt is None:
        return f"plot skipped: {MISSING}"
    t = records["t"]
    has_joint = not np.isnan(records["ankle_dp"]).all()
    src = "ankle" if has_joint else "est_ankle"
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 7.4), sharex=True)
    for axis, colour in (("dp", "C0"), ("ie", "C1")):
        ax1.plot(t, np.degrees(records[f"{src}_{axis}"]), colour, label=f"theta_{axis.upper()}")
        ax1.plot(t, np.degrees(records[f"ref_{axis}"]), colour, ls="--", lw=0.8, label=f"r_{axis.upper()}")
    for i, colour in ((1, "C2"), (2, "C3")):
        ax1.plot(t, np.degrees(records[f"motor_pos_{i}"]), colour, lw=0.8, label=f"theta_{i} (motor)")
        ax2.plot(t, torque_constant * records[f"current_cmd_{i}"], colour, lw=0.8, label=f"tau_{i}")
    outcome = run_outcome(records)
    for name, times in state_marks(records).items():
        for k, x in enumerate(times):
            for ax in (ax1, ax2):
                ax.axvline(x, **MARK_STYLE[name], label=(outcome if name == "fault" else name) if k == 0 and ax is ax2
                           else None)
    ax1.set_ylabel("angle (deg)")
    ax1.legend(ncol=3, fontsize=8)
    ax1.set_title("(a) ankle and motor positions")
    ax2.set_ylabel("motor torque (N m)")
    ax2.set_xlabel("t (s)")
    ax2.legend(fontsize=8)
    ax2.set_title("(b) motor torques (kt x set value)")
    phase = records["gait_phase"]
    if phase.any():            # the gait-phase controller ran: its phase on the torque panel
        from ankle_rt.control.gait_phase import PHASE_NAMES

        ax3 = ax2.twinx()
        ax3.step(t, phase, "k", where="post", lw=0.6, alpha=0.6)
        ax3.set_yticks(range(len(PHASE_NAMES)))
        ax3.set_yticklabels([n.replace("_", " ") for n in PHASE_NAMES], fontsize=7)
        ax3.set_ylim(-0.5, len(PHASE_NAMES) - 0.5)
    fig.suptitle(f"{what}\n{outcome}" if what else outcome, fontsize=10,
                 color="tab:red" if outcome.startswith("FAULT") else "black")
    fig.tight_layout()
    fig.savefig(out_png, dpi=110)
    plt.close(fig)
    return f"plot: {out_png}"
