"""The identification report: a parameter table laid out like the paper's Table 1, the numbers behind
its Figs 2-4 as text, the paper-friction analysis, and (with matplotlib) PNG plots of Figs 2-4.
Also the parameter YAML a config includes directly."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml

from ankle_rt.identification.actuator import ActuatorIdentification
from ankle_rt.identification.paper import PAPER_TABLE1, paper_friction_analysis
from ankle_rt.identification.signals import centred_velocity, motor_channel
from ankle_rt.identification.stats import Measured
from ankle_rt.interchange import Recording
from ankle_rt.plotting import MISSING, pyplot


def _row(name: str, unit: str, prior: float | None, m: Measured | None, paper: str) -> str:
    pr = "-" if prior is None else f"{prior:.4f}"
    if m is None:
        return f"  {name:<22} {unit:<10} {pr:>8} {'-':>10} {'-':>8} {'-':>3}  {paper}"
    sd = "n/a" if math.isnan(m.sd) else f"{m.sd:.4f}"
    return f"  {name:<22} {unit:<10} {pr:>8} {m.mean:>10.4f} {sd:>8} {m.n:>3}  {paper}"


def table1(res: ActuatorIdentification) -> list[str]:
    """Table 1 of the paper: nominal (here: the config), identified and SD, plus the paper's values."""
    p = res.prior
    def paper(key: str) -> str:
        v, sd = PAPER_TABLE1[key]
        return f"{v:g} ± {sd:g}"
    st, vi, ine = res.stiction, res.viscous, res.inertia
    return [
        "Table 1: motor dynamic parameters (reflected to the load side; SD over repeats)",
        f"  {'parameter':<22} {'unit':<10} {'config':>8} {'identified':>10} {'SD':>8} {'n':>3}  paper",
        _row("J (step fit)", "kg m^2", p.get("inertia"), ine.inertia if ine else None, paper("J")),
        _row("D (step fit)", "N m s/rad", p.get("damping"), ine.damping if ine else None, paper("D")),
        _row("kv+ (viscous, CCW)", "N m s/rad", p.get("damping"), vi.kv_pos if vi else None, paper("D")),
        _row("kv- (viscous, CW)", "N m s/rad", p.get("damping"), vi.kv_neg if vi else None, paper("D")),
        _row("kc+ (stiction, CCW)", "N m", p.get("coulomb"), st.kc_pos if st else None, paper("kc_pos")),
        _row("kc- (stiction, CW)", "N m", p.get("coulomb"), st.kc_neg if st else None, paper("kc_neg")),
        _row("kc+ (sliding, CCW)", "N m", p.get("coulomb"), vi.kc_pos if vi else None, "-"),
        _row("kc- (sliding, CW)", "N m", p.get("coulomb"), vi.kc_neg if vi else None, "-"),
    ]


def report_lines(res: ActuatorIdentification, header: str) -> list[str]:
    """The whole text report."""
    out = [header, ""] + table1(res)
    pair = res.kc_pair()
    if pair is not None:
        out.append(f"  asymmetry kc+ - kc- = {pair[0].mean - pair[1].mean:+.4f} N m")
    out += [""] + [f"note: {n}" for n in res.notes]
    if res.stiction is not None:
        out += ["", "Fig. 2 (stiction): breakaway friction torque of each ramp"]
        out += [f"  t = {e.t:8.3f} s  {'CCW' if e.direction > 0 else 'CW '}  {e.torque:+.4f} N m"
                for e in res.stiction.events]
        out += [f"  skipped: {s}" for s in res.stiction.skipped]
    if res.viscous is not None:
        v = res.viscous
        out += ["", "Fig. 3 (viscous): steady speeds held by the PI loop and their torques"]
        out += [f"  {p.speed:+8.3f} rad/s  {p.torque:+.4f} N m  ({(p.stop - p.start)} rows)" for p in v.plateaus]
        out += [f"  affine fit CCW: |tau| = {v.fit_pos.kc:.4f} + {v.fit_pos.kv:.4f} |v|;  "
                f"CW: |tau| = {v.fit_neg.kc:.4f} + {v.fit_neg.kv:.4f} |v|",
                f"  through-origin fit (the paper's method): kv = {v.kv_origin:.4f} N m s/rad"]
    if res.inertia is not None:
        i = res.inertia
        how = "kc fixed from the viscous experiment" if i.friction_given else "kc fitted per step"
        out += ["", f"Fig. 4 (inertia): least-squares fit of each torque step ({how})"]
        out += [f"  step {k + 1} {'CCW' if f.direction > 0 else 'CW '}: J = {f.inertia:.5f} kg m^2, "
                f"D = {f.damping:.5f} N m s/rad, kc = {f.coulomb:.4f} N m, {len(f.history)} evaluations, "
                f"residual {f.rms:.4f} rad/s RMS" for k, f in enumerate(i.fits)]
    out += [""] + paper_friction_analysis().lines()
    return out


def parameter_yaml(res: ActuatorIdentification, header: str) -> str:
    """The parameter fragment as YAML, with a comment saying how to include it."""
    comment = "\n".join(f"# {line}" for line in [
        header, "Include it from a config after the nominal parameters, e.g.",
        "  include: [nominal-params.yaml, this-file.yaml]",
        "A config that sets sim.effects itself overrides the list below: copy the entry there."])
    return comment + "\n" + yaml.safe_dump(res.parameter_fragment(), sort_keys=False)


def write_plots(res: ActuatorIdentification, recordings: dict[str, Recording], out_dir: Path, motor: int,
                kt: float | None) -> list[str]:
    """PNG plots like the paper's Figs 2-4 into ``out_dir``; returns the lines to print (file names,
    or a plain message when matplotlib is missing)."""
    plt = pyplot()
    if plt is None:
        return [f"plots: {MISSING}; text report only"]
    written = []
    if res.stiction is not None and "stiction" in recordings:
        t, pos, tau = motor_channel(recordings["stiction"], motor, kt)
        vel = centred_velocity(t, pos, 0.01)
        fig, (a, b) = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
        a.plot(t, tau)
        a.set_ylabel("motor torque (N m)")
        b.plot(t, vel)
        for e in res.stiction.events:
            a.plot(e.t, np.interp(e.t, t, tau), "ko", mfc="none")
            b.plot(e.t, np.interp(e.t, t, vel), "ko", mfc="none")
        b.set_ylabel("speed (rad/s)")
        b.set_xlabel("time (s)")
        a.set_title("Fig. 2: torque ramps CW/CCW and breakaway (circles)")
        written.append(_save(fig, out_dir / "fig2_stiction.png", plt))
    if res.viscous is not None and "viscous" in recordings:
        t, pos, tau = motor_channel(recordings["viscous"], motor, kt)
        v = res.viscous
        fig, (a, b, c) = plt.subplots(3, 1, figsize=(8, 9))
        a.plot(t, centred_velocity(t, pos, 0.01))
        a.set_ylabel("speed (rad/s)")
        b.plot(t, tau)
        b.set_ylabel("motor torque (N m)")
        b.set_xlabel("time (s)")
        for p in v.plateaus:
            b.plot([t[p.start], t[p.stop]], [p.torque, p.torque], "k-", lw=2)
        speeds = np.linspace(0, 9, 50)
        c.plot([abs(p.speed) for p in v.plateaus if p.speed > 0], [p.torque for p in v.plateaus if p.speed > 0], "o", label="CCW")
        c.plot([abs(p.speed) for p in v.plateaus if p.speed < 0], [-p.torque for p in v.plateaus if p.speed < 0], "s", label="CW")
        c.plot(speeds, v.fit_pos.predict(speeds), "-", label="affine CCW")
        c.plot(speeds, v.fit_neg.predict(speeds), "--", label="affine CW")
        c.plot(speeds, v.kv_origin * speeds, ":", label="through origin")
        c.set_xlabel("|speed| (rad/s)")
        c.set_ylabel("|torque| (N m)")
        c.legend()
        a.set_title("Fig. 3: PI velocity holds and the friction they reveal")
        written.append(_save(fig, out_dir / "fig3_viscous.png", plt))
    if res.inertia is not None and "inertia" in recordings:
        t = recordings["inertia"]["t"]
        fits = res.inertia.fits
        fig, (a, b) = plt.subplots(2, 1, figsize=(8, 6))
        hist = np.array(fits[0].history)
        a.plot(hist[:, 0], label="J (kg m^2)")
        a.plot(hist[:, 1], label="D (N m s/rad)")
        a.set_xlabel("cost evaluation")
        a.legend()
        for f in fits:
            b.plot(t[f.start:f.stop], f.measured, "-", lw=0.8)
            b.plot(t[f.start:f.stop], f.model, "k--", lw=1)
        b.set_xlabel("time (s)")
        b.set_ylabel("speed (rad/s)")
        a.set_title("Fig. 4: step-response fit (a) convergence of the first step, (b) Exp vs Est (dashed)")
        written.append(_save(fig, out_dir / "fig4_inertia.png", plt))
    return [f"plot: {w}" for w in written]


def _save(fig, path: Path, plt) -> str:
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return str(path)
