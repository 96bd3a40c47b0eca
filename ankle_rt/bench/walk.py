"""The walking experiment behind ``ankle-rt bench walk``: strides on the simulator's walking scenario
(``sim_backend.walking``) under the configured controller (the gait-phase controller with
``config/walk.yaml``), per wearer mass and cadence, in lockstep (the real daemon, controller and
safety layer on a simulated clock).

Wearers: the shipped gait-phase parameters are for 75 kg; for another mass m the stance and safe
phases' stiffness and damping and the load thresholds are scaled by m / 75 (the able-bodied moment
scales with mass, Winter 1991), stiffness capped at the joint-torque loop's stable set and the stance
phases' where their push-off would trip the gauge rail or ask more than the motors give
(:func:`ankle_rt.control.gait_phase.stance_torque_limits`); swing is the foot's alone and keeps its
parameters.

Per stride (heel strike to heel strike, from the scenario's ground truth), against the able-bodied
stride of that instant (the scenario's ground truth, :mod:`ankle_rt.gait_data`):

- moment error: RMS over the stride of (rendered plantarflexor moment, -strain-gauge DP torque, minus
  the able-bodied one) in % of the stride's able-bodied peak;
- angle error: RMS of (true DP angle - able-bodied angle), deg;
- push-off work: net ankle work over the controller's late-stance phase, -integral(M dtheta), J/kg;
- currents: peak |set value|, the stride's RMS (the larger motor); I2t headroom: 100 (1 - the
  largest I2t the safety layer accumulated / its budget), %.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ankle_rt.config import load_config

REFERENCE_MASS_KG = 75.0
MASS_SCALED_PHASES = ("early_stance", "late_stance", "safe")
MASS_SCALED_PARAMS = ("stiffness_dp", "damping_dp", "stiffness_ie", "damping_ie")
MASS_SCALED_THRESHOLDS = ("load_on_nm", "load_off_nm", "late_stance_load_nm")


def wearer_overrides(cfg: Mapping[str, Any], mass_kg: float, cadence: str, seed: int) -> dict:
    """Config overrides for a wearer of ``mass_kg`` at ``cadence``, whom the tuning is then for
    (``wearer.mass_kg``): the tuning rule of the module docstring applied to ``cfg``'s gait-phase
    parameters (a stiffness is capped at what the joint-torque loop renders stably and at
    controller.gain_limits, a stance phase's DP stiffness where its push-off would pass the rail or
    the motors, but never below ``cfg``'s own: a refused one stays refused)."""
    from ankle_rt.control.gait_phase import PHASES, STANCE_PHASES, stance_stiffness_cap
    from ankle_rt.control.torque_loop import ImpedanceLimits

    limits = ImpedanceLimits.from_config(cfg)
    cap = {"stiffness_dp": limits.max_stiffness[0], "stiffness_ie": limits.max_stiffness[1]}
    g, most = cfg["controller"]["gait_phase"], cfg["controller"]["gain_limits"]
    r = mass_kg / REFERENCE_MASS_KG
    gait = {p: {k: min(g[p][k] * r, cap.get(k, math.inf), most[k.split("_")[0]]) for k in MASS_SCALED_PARAMS}
            for p in MASS_SCALED_PHASES}
    for phase in STANCE_PHASES:
        p = PHASES[phase]
        gait[p]["stiffness_dp"] = min(gait[p]["stiffness_dp"], max(g[p]["stiffness_dp"], stance_stiffness_cap(cfg, phase)))
    gait.update({k: g[k] * r for k in MASS_SCALED_THRESHOLDS})
    return {"sim": {"scenario": "walking", "walking": {"mass_kg": mass_kg, "cadence": cadence, "seed": seed}},
            "wearer": {"mass_kg": mass_kg}, "controller": {"gait_phase": gait}}


@dataclass
class WalkRun:
    """One wearer's run: per-cycle columns and per-stride figures."""

    mass_kg: float
    cadence: str
    fault: str
    columns: dict[str, np.ndarray]
    strides: list[dict[str, float]]


def run_walk(cfg_path: str, mass_kg: float, cadence: str, strides: int, seed: int = 0, *,
             plant_friction: float = 1.0) -> WalkRun:
    """Walk ``strides`` strides (plus the first, a warm-up not counted) in lockstep; stops early on a fault.
    ``plant_friction``: the simulated plant's Coulomb-like friction x this, the controller keeping the
    config's statement (a device with less friction than stated)."""
    from ankle_rt.backend import open_backend
    from ankle_rt.bench.impedance import with_plant_friction
    from ankle_rt.clock import SimClock
    from ankle_rt.daemon import Daemon
    from ankle_rt.gait_data import stride_period_s

    base = load_config(cfg_path)
    cfg = load_config(cfg_path, wearer_overrides(base, mass_kg, cadence, seed))
    start = cfg["sim"]["walking"]["start_s"]
    duration = start + (strides + 1.5) * stride_period_s(cadence)
    clock = SimClock()
    backend = None if plant_friction == 1.0 else open_backend(with_plant_friction(cfg, plant_friction), clock)
    daemon = Daemon(cfg, clock, backend=backend)
    n = int(duration * cfg["controller"]["rate_hz"]) + 2
    cols = {k: np.full(n, np.nan) for k in ("t", "phase", "gait", "stride", "angle", "angle_ab", "moment",
                                           "moment_ab", "i1", "i2", "i2t")}
    plant = daemon.backend.plant
    walk, safety, ctl = plant.walking, daemon.safety, daemon.controller
    k = [0]

    def cycle(t_ns: int) -> None:
        daemon.cycle(t_ns)
        i = k[0]
        if i < n:
            cols["t"][i] = plant.t
            cols["phase"][i] = getattr(ctl, "phase", -1)
            cols["gait"][i] = walk.phase
            cols["stride"][i] = walk.stride if walk.phase >= 0.0 else -1
            cols["angle"][i] = plant.model.x[0]
            cols["angle_ab"][i] = walk.angle_ab
            cols["moment"][i] = -daemon.est.sg_torque[0]
            cols["moment_ab"][i] = walk.moment_ab
            cols["i1"][i], cols["i2"][i] = safety.current
            cols["i2t"][i] = max(safety.i2t)
            k[0] = i + 1
        if safety.fault:
            daemon.loop.stop()

    try:
        daemon.loop.run(cycle, round(duration * 1e9))
    finally:
        daemon.close()
        if backend is not None:
            backend.close()
    cols = {key: v[:k[0]] for key, v in cols.items()}
    cols["i2t_budget"] = np.array([safety.i2t_budget])
    from ankle_rt.safety import Fault

    return WalkRun(mass_kg, cadence, Fault(safety.fault).name, cols, stride_figures(cols, mass_kg))


def stride_figures(c: Mapping[str, np.ndarray], mass_kg: float) -> list[dict[str, float]]:
    """The per-stride figures of the module docstring for every complete stride but the first."""
    from ankle_rt.control.gait_phase import LATE_STANCE

    out = []
    stride = c["stride"]
    ids = [s for s in np.unique(stride[stride >= 0])]
    for s in ids[1:-1]:          # the first is a warm-up, the last may be cut off
        m = stride == s
        moment, ab = c["moment"][m], c["moment_ab"][m]
        peak = float(np.max(ab))
        angle = c["angle"][m]
        ls = m & (c["phase"] == LATE_STANCE)
        idx = np.flatnonzero(ls)
        work = 0.0
        if idx.size > 1:
            work = float(-np.sum(0.5 * (c["moment"][idx[1:]] + c["moment"][idx[:-1]]) * np.diff(c["angle"][idx])))
        i1, i2 = c["i1"][m], c["i2"][m]
        out.append({
            "moment_rms_error_pct": 100.0 * float(np.sqrt(np.mean((moment - ab) ** 2))) / peak,
            "angle_rms_error_deg": math.degrees(float(np.sqrt(np.mean((angle - c["angle_ab"][m]) ** 2)))),
            "push_off_work_j_per_kg": work / mass_kg,
            "current_peak_a": float(max(np.max(np.abs(i1)), np.max(np.abs(i2)))),
            "current_rms_a": float(max(np.sqrt(np.mean(i1 ** 2)), np.sqrt(np.mean(i2 ** 2)))),
            "moment_peak_nm": float(np.max(moment)), "moment_ab_peak_nm": peak,
        })
    return out


def summarize(runs: Sequence[WalkRun]) -> dict[str, Any]:
    """The bench's JSON object: totals and worst cases over ``runs`` (push-off work: the smallest
    wearer's mean at normal cadence)."""
    every = [s for r in runs for s in r.strides]
    normal = [np.mean([s["push_off_work_j_per_kg"] for s in r.strides]) for r in runs
              if r.cadence == "normal" and r.strides]
    headroom = min(100.0 * (1.0 - float(np.nanmax(r.columns["i2t"])) / float(r.columns["i2t_budget"][0]))
                   for r in runs)
    worst = lambda key: max((s[key] for s in every), default=math.nan)  # noqa: E731
    return {
        "strides": len(every),
        "faults": sum(r.fault != "NONE" for r in runs),
        "moment_rms_error_pct": worst("moment_rms_error_pct"),
        "angle_rms_error_deg": worst("angle_rms_error_deg"),
        "push_off_work_j_per_kg": float(min(normal)) if normal else math.nan,
        "current_peak_a": worst("current_peak_a"),
        "current_rms_a": worst("current_rms_a"),
        "i2t_headroom_pct": headroom,
        "wearers": [{"mass_kg": r.mass_kg, "cadence": r.cadence, "fault": r.fault, "strides": len(r.strides),
                     **{k: (float(np.mean([s[k] for s in r.strides])) if r.strides else math.nan)
                        for k in ("moment_rms_error_pct", "angle_rms_error_deg", "push_off_work_j_per_kg",
                                  "current_rms_a", "moment_peak_nm", "moment_ab_peak_nm")}}
                    for r in runs],
    }


def walk_bench(cfg_path: str, masses: Sequence[float], cadences: Sequence[str], strides: int,
               progress: Callable[[float, float, str], None] | None = None) -> tuple[dict[str, Any], list[WalkRun]]:
    """Every wearer at every cadence; returns the summary and the runs (for the plot)."""
    runs = []
    total = len(masses) * len(cadences)
    for i, mass in enumerate(masses):
        for j, cadence in enumerate(cadences):
            if progress is not None:
                progress(i * len(cadences) + j, total, f"{mass:g} kg {cadence}")
            runs.append(run_walk(cfg_path, mass, cadence, strides, seed=i * len(cadences) + j))
    if progress is not None:
        progress(total, total, "done")
    return summarize(runs), runs


def plot_walk(runs: Sequence[WalkRun], png: str) -> str:
    """Ankle moment against angle per controller phase, one panel per cadence at the middle mass,
    with the able-bodied curve."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ankle_rt.control.gait_phase import PHASES
    from ankle_rt.gait_data import able_bodied

    cadences = list(dict.fromkeys(r.cadence for r in runs))
    masses = sorted({r.mass_kg for r in runs})
    mass = masses[len(masses) // 2]
    fig, axes = plt.subplots(1, len(cadences), figsize=(4.5 * len(cadences), 4.2), squeeze=False)
    for ax, cadence in zip(axes[0], cadences):
        run = next(r for r in runs if r.cadence == cadence and r.mass_kg == mass)
        c = run.columns
        keep = c["stride"] >= 1
        for p, name in enumerate(PHASES):
            m = keep & (c["phase"] == p)
            if m.any():
                ax.plot(np.degrees(c["angle"][m]), c["moment"][m] / mass, ".", ms=1.2, label=name.replace("_", " "))
        ab = able_bodied(cadence)
        ax.plot(np.degrees(ab["angle_dp"]), ab["moment_dp"], "k-", lw=1.2, label="able-bodied (Winter 1991)")
        ax.set_title(f"{mass:g} kg, {cadence} cadence")
        ax.set_xlabel("ankle DP angle (deg, dorsiflexion +)")
        ax.set_ylabel("plantarflexor moment (N m/kg)")
        ax.grid(True, lw=0.3)
    axes[0][0].legend(fontsize=7, markerscale=6)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return f"plot: {png}"


def default_walk_config() -> str:
    """The shipped config/walk.yaml."""
    from ankle_rt.paths import default_config_path

    return str(default_config_path("walk.yaml"))
