"""The metrics of one run, from a batch trace: faults, tracking, step response, currents, impedance, cables.

Angles in degrees, times in seconds, currents in amperes (names say so). Tracking is measured from
the activation on (before it the amplifiers are off by design), on the joint encoders' angles (the true
ones to 12 urad).

- ``stable``: no fault, and the tracking error RMS over the last 20 % of the run stays below
  ``criteria.max_final_rms_deg`` (default 2 deg): an oscillation that grows or persists fails it.
- overshoot / settling (step references only): per axis, relative to the step size; settling is the
  time from the step until the error stays inside 2 % of the step (at least 0.05 deg), measured up
  to the next disturbance or the end of the run; NaN if it never settles.
- currents: peak and RMS of the limited set values, against the ESCON peak and continuous limits.
- rendered impedance (impedance controller, a disturbance on that axis): the applied torque over the
  mean deflection in the second half of the push, against the commanded stiffness, in %.
- cable slack: a motor's cable torque reached 2 r T0 (the unloaded side of its loop went slack at
  pretension T0, ``metrics.cable_pretension_n``); events are counted per motor.
- ``passed``: stable, RMS currents inside the continuous limit, and every given criterion met.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from ankle_rt.safety import Fault
from ankle_rt.sweep.cycle import BatchTrace

# criteria a spec may set, and their defaults (None: not checked unless given)
CRITERIA: dict[str, float | None] = {
    "max_final_rms_deg": 2.0,       # stability: error RMS over the last 20 % of the run
    "max_tracking_rms_deg": None,   # per axis
    "max_tracking_peak_deg": None,  # per axis
    "max_overshoot_pct": None,
    "max_settling_s": None,
    "max_current_rms_ratio": 1.0,   # RMS current / continuous limit
    "max_slack_events": None,
    "max_impedance_error_pct": None,
}
AXES = ("dp", "ie")


STEP_MIN_RAD = 1e-3   # a reference jump smaller than this (0.06 deg) is not a step


def _step_of(ref: np.ndarray) -> tuple[int, float] | None:
    """(index, size) of the step of a reference with exactly one jump (of at least STEP_MIN_RAD), else None."""
    d = np.diff(ref)
    jumps = np.flatnonzero(np.abs(d) >= STEP_MIN_RAD)
    if len(jumps) != 1 or np.any((np.abs(d) > 1e-9) & (np.abs(d) < STEP_MIN_RAD)):
        return None
    k = jumps[0] + 1
    return k, float(ref[k] - ref[k - 1])


def run_metrics(trace: BatchTrace, j: int, cfg: Mapping[str, Any], criteria: Mapping[str, float]) -> dict[str, Any]:
    """The metrics row of plant ``j`` of a batch trace."""
    crit = {**{k: v for k, v in CRITERIA.items() if v is not None}, **criteria}
    t = trace.t
    out: dict[str, Any] = {}
    fault = int(trace.fault[j])
    out["faulted"] = fault != 0
    out["fault"] = Fault(fault).name.lower()
    out["fault_time_s"] = float(trace.fault_time[j])
    t_act = float(trace.activation_time[j])
    k0 = int(np.searchsorted(t, t_act)) if math.isfinite(t_act) else len(t)
    k_end = int(np.searchsorted(t, trace.fault_time[j])) if fault else len(t)
    ankle = trace.ankle[:, :, j].astype(float)
    ref = trace.reference[:, :, j].astype(float)
    err = np.degrees(ankle - ref)
    window = slice(k0, max(k_end, k0 + 1))
    late = slice(max(k0, int(0.8 * len(t))), max(k_end, k0 + 1))
    final_rms = 0.0
    dists = cfg["sim"]["disturbances"]
    for a, name in enumerate(AXES):
        e = err[window, a]
        out[f"tracking_rms_{name}_deg"] = float(np.sqrt(np.mean(e * e))) if e.size else math.nan
        out[f"tracking_peak_{name}_deg"] = float(np.max(np.abs(e))) if e.size else math.nan
        el = err[late, a]
        final_rms = max(final_rms, float(np.sqrt(np.mean(el * el))) if el.size else math.inf)
        step = _step_of(ref[:, a])
        overshoot = settling = math.nan
        if step is not None and step[0] > k0:
            k, size = step
            nxt = [d["start"] for d in dists if d["start"] > t[k] and (d["torque_dp"] if a == 0 else d["torque_ie"])]
            k_stop = min([k_end] + [int(np.searchsorted(t, s)) for s in nxt])
            seg = ankle[k:k_stop, a] - ref[k:k_stop, a]
            if seg.size:
                overshoot = 100.0 * max(0.0, float(np.max(seg * np.sign(size)))) / abs(size)
                band = max(0.02 * abs(size), math.radians(0.05))
                outside = np.flatnonzero(np.abs(seg) > band)
                if not outside.size:
                    settling = 0.0
                elif outside[-1] < seg.size - 1:
                    settling = float(t[k + outside[-1] + 1] - t[k])
        out[f"overshoot_{name}_pct"] = overshoot
        out[f"settling_{name}_s"] = settling
    out["final_rms_deg"] = final_rms if math.isfinite(final_rms) else math.nan
    out["stable"] = (not out["faulted"]) and final_rms <= crit["max_final_rms_deg"]

    i_peak, i_cont = cfg["amplifier"]["current_limit_peak"], cfg["amplifier"]["current_limit_continuous"]
    cur = trace.current[:, :, j].astype(float)
    active = cur[k0:]
    peak = float(np.max(np.abs(active))) if active.size else 0.0
    rms = float(np.max(np.sqrt(np.mean(active * active, axis=0)))) if active.size else 0.0
    out["current_peak_a"] = peak
    out["current_rms_a"] = rms
    out["current_peak_ratio"] = peak / i_peak
    out["current_rms_ratio"] = rms / i_cont
    out["saturated_cycles"] = int(trace.saturated[j])

    for a, name in enumerate(AXES):
        out[f"impedance_error_{name}_pct"] = _rendered_impedance_error(cfg, t, ankle[:, a], a, k0, k_end)
    out["slack_events_1"] = int(trace.slack_events[0, j])
    out["slack_events_2"] = int(trace.slack_events[1, j])
    out["cable_torque_peak_nm"] = float(np.max(trace.cable_torque_peak[:, j]))

    ok = out["stable"] and out["current_rms_ratio"] <= crit["max_current_rms_ratio"]
    checks = {"max_tracking_rms_deg": ("tracking_rms_{}_deg",), "max_tracking_peak_deg": ("tracking_peak_{}_deg",),
              "max_overshoot_pct": ("overshoot_{}_pct",), "max_settling_s": ("settling_{}_s",),
              "max_impedance_error_pct": ("impedance_error_{}_pct",)}
    for c, (pattern,) in checks.items():
        if c in crit:
            for name in AXES:
                v = out[pattern.format(name)]
                if c == "max_impedance_error_pct":
                    v = abs(v)
                if c == "max_settling_s" and math.isnan(v) and not math.isnan(out[f"overshoot_{name}_pct"]):
                    ok = False                      # a step that never settled
                elif math.isfinite(v) and v > crit[c]:
                    ok = False
    if "max_slack_events" in crit and out["slack_events_1"] + out["slack_events_2"] > crit["max_slack_events"]:
        ok = False
    out["passed"] = bool(ok)
    return out


def _rendered_impedance_error(cfg, t, angle, axis, k0, k_end) -> float:
    """% error of the rendered ankle stiffness on ``axis`` under the first disturbance on it."""
    c = cfg["controller"]
    if c["type"] != "impedance":
        return math.nan
    commanded = c["impedance"]["stiffness_dp" if axis == 0 else "stiffness_ie"]
    for d in cfg["sim"]["disturbances"]:
        torque = d["torque_dp"] if axis == 0 else d["torque_ie"]
        if torque == 0.0 or commanded <= 0.0:
            continue
        ks, ke = int(np.searchsorted(t, d["start"])), int(np.searchsorted(t, d["stop"]))
        kb = int(np.searchsorted(t, d["start"] - 0.2))
        if kb < k0 or ke > k_end or ke - ks < 4:
            continue
        deflection = float(np.mean(angle[(ks + ke) // 2:ke]) - np.mean(angle[kb:ks]))
        if deflection == 0.0:
            return math.nan
        return 100.0 * (torque / deflection - commanded) / commanded
    return math.nan
