"""Study (issue 19, item 1, fourth pass): can a broader joint-torque-loop controller class render the
commanded impedance in motion with the stated gain margin?

On the project's sampled linear model (:mod:`ankle_rt.analysis`: the plant discretised exactly, one
more cycle of delay than the simulator, the estimator, the impedance law, the torque loop), the loop's
proportional and rate terms ``kp e - kd d/dt LP(tau_sg)`` are passed through second-order sections
(``ImpedanceLoop.shaping``) of one class at a time:

- ``shipped``: none, the shipped structure with its gains re-tuned (the reference);
- ``notch``: a band-stop over the cable modes (60-110 Hz with cables +-30 %);
- ``lag``: a low-frequency gain boost (high-frequency gain 1, so kp is what the cable modes see);
- ``lag+notch``; ``lead+rolloff``: a lead at the held-foot crossover and a second-order low-pass.

For each class the parameters (and kp, ki, kd of one axis; on DP also the shared cutoff) are
optimised by differential evolution for the worst dynamic-stiffness error |Re Z / K - 1| at 0.5 / 1 /
2 Hz for K_dp 50 and 200 (K_ie half; damping 0.5 / 0.25), subject to >= MARGIN_DB over the 108 cases
of :func:`ankle_rt.analysis.loop_margin_db` at both stiffnesses and at the gait-phase controller's five
phases (walking: K_dp up to 400, B_dp up to 9) and to passivity: Re of the felt
admittance s Theta / T (foot free, that axis) >= 0 at 0.1-50 Hz on every free-foot case. The other
axis keeps the gains of ``--config`` (default: the shipped ones).

Z(jw) = T / Theta is the felt impedance of the foot-free closed loop (an ankle torque T in), the
bench's definitions: dynamic stiffness Re Z, damping Im Z / w, apparent inertia (K - Re Z) / w^2 at
5 Hz. Run: ``PYTHONPATH=$PWD nice python3 benchmarks/study_torque_loop_shaping.py [--axis ie]
[--config FILE] [--classes notch ...]`` (about 1-2 min per class on one core).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from typing import Callable

import numpy as np
from scipy.optimize import differential_evolution

from ankle_rt import analysis as an
from ankle_rt.bench.impedance import bench_config
from ankle_rt.config import load_config
from ankle_rt.config_schema import GAIT_PHASE_DEFAULTS
from ankle_rt.discretize import zoh
from ankle_rt.lag import lag_section
from ankle_rt.linear_model import LinearModel
from ankle_rt.notch import notch_section
from ankle_rt.params import PlantParams
from ankle_rt.passivity import free_plant_with_ankle_input, least_rendered_damping, receptance
from ankle_rt.paths import default_config_path

PLANT = [{"type": "load_dependent_friction", "coefficient": 0.12},
         {"type": "stribeck", "static_excess": 0.15, "stribeck_velocity": 0.1}]
STIFFNESS_DP = (50.0, 200.0)                  # N m/rad, K_ie half
DAMPING = (0.5, 0.25)                         # N m s/rad, the bench's
# margin only: the gait-phase controller's shipped phases ((K_dp, K_ie), (B_dp, B_ie)), config_schema.GAIT_PHASE_DEFAULTS
MARGIN_ONLY = tuple(((k_dp, k_ie), (b_dp, b_ie)) for k_dp, b_dp, _, k_ie, b_ie, _ in GAIT_PHASE_DEFAULTS.values())
JUDGED_HZ = (0.5, 1.0, 2.0)                   # the dynamic-stiffness goal's frequencies
INERTIA_HZ = 5.0                              # where the apparent inertia is read (the bench's)
AXES = ("dp", "ie")
MARGIN_DB = 7.0                               # the search's constraint (6 required, 1 dB for robustness)
Section = tuple[float, float, float, float, float]


# -- the sections (continuous prototypes, Tustin with prewarping at their own frequency) -----------
def tustin(num: tuple[float, float, float], den: tuple[float, float, float], f_warp: float, dt: float) -> Section:
    """(b0, b1, b2, a1, a2) of (n2 s^2 + n1 s + n0) / (d2 s^2 + d1 s + d0), Tustin prewarped at f_warp;
    a first-order one (n2 = d2 = 0) stays first order (no pole-zero pair at z = -1)."""
    w = 2.0 * math.pi * f_warp
    c = w / math.tan(w * dt / 2.0)
    (n2, n1, n0), (d2, d1, d0) = num, den
    if n2 == d2 == 0.0:
        b = (n1 * c + n0, n0 - n1 * c, 0.0)
        a = (d1 * c + d0, d0 - d1 * c, 0.0)
    else:
        b = (n2 * c * c + n1 * c + n0, 2.0 * (n0 - n2 * c * c), n2 * c * c - n1 * c + n0)
        a = (d2 * c * c + d1 * c + d0, 2.0 * (d0 - d2 * c * c), d2 * c * c - d1 * c + d0)
    return (b[0] / a[0], b[1] / a[0], b[2] / a[0], a[1] / a[0], a[2] / a[0])


# the band-stop and the lag as the daemon runs them (controller.torque_loop notch_* and lag_*)
notch, lag = notch_section, lag_section


def lead(f_center: float, ratio: float, dt: float) -> Section:
    """(1 + s / wz) / (1 + s / wp), wp / wz = ``ratio``, centred (most phase) at f_center, gain 1 at DC."""
    wc = 2.0 * math.pi * f_center
    wz, wp = wc / math.sqrt(ratio), wc * math.sqrt(ratio)
    return tustin((0.0, 1.0 / wz, 1.0), (0.0, 1.0 / wp, 1.0), f_center, dt)


def rolloff(f0: float, zeta: float, dt: float) -> Section:
    """Second-order low-pass at f0 Hz, damping ratio zeta, gain 1 at DC."""
    w = 2.0 * math.pi * f0
    return tustin((0.0, 0.0, w * w), (1.0, 2.0 * zeta * w, w * w), f0, dt)


# -- the classes: (names, bounds, sections from the class's parameters) -------------------------------
LOOP_PARAMS = (("kp", 2.0, 80.0), ("ki", 2.0, 20.0), ("kd", 0.005, 0.25), ("cutoff_hz", 30.0, 300.0))
CLASSES: dict[str, tuple[tuple[tuple[str, float, float], ...], Callable[..., tuple[Section, ...]]]] = {
    "shipped": ((), lambda dt: ()),   # each class's parameters: (name, low, high); NEUTRAL: where it does nothing
    "notch": ((("notch_hz", 50.0, 120.0), ("notch_zeta", 0.1, 1.0), ("notch_depth", 0.02, 0.7)),
              lambda dt, f, z, d: (notch(f, z, d, dt),)),
    "lag": ((("lag_hz", 0.2, 15.0), ("lag_boost", 1.0, 8.0)),
            lambda dt, f, b: (lag(f, b, dt),)),
    "lag+notch": ((("lag_hz", 0.2, 15.0), ("lag_boost", 1.0, 8.0), ("notch_hz", 50.0, 120.0),
                   ("notch_zeta", 0.1, 1.0), ("notch_depth", 0.02, 0.7)),
                  lambda dt, f, b, fn, z, d: (lag(f, b, dt), notch(fn, z, d, dt))),
    "lead+rolloff": ((("lead_hz", 5.0, 40.0), ("lead_ratio", 1.0, 10.0), ("rolloff_hz", 30.0, 200.0),
                      ("rolloff_zeta", 0.3, 1.0)),
                     lambda dt, f, r, fr, z: (lead(f, r, dt), rolloff(fr, z, dt))),
}


@dataclasses.dataclass
class Setup:
    """The bench's two commanded impedances, then the gait phases' (margin only): plants and loops."""

    plants: list[PlantParams]
    loops: list[an.ImpedanceLoop]
    free: list[tuple]         # per bench stiffness: (Ad, Bd_motor, Bd_ankle, Cy, kin) of each free-foot plant case

    @classmethod
    def build(cls, config: str | None = None) -> "Setup":
        base = load_config(config or default_config_path())
        plants, loops, free = [], [], []
        bench = [((k, k / 2.0), DAMPING) for k in STIFFNESS_DP]
        for i, (stiffness, damping) in enumerate(bench + list(MARGIN_ONLY)):
            cfg = bench_config(base, stiffness=stiffness, damping=damping, torque_feedback="auto",
                               friction_ff=None, effects=PLANT)
            p = PlantParams.from_config(cfg)
            loop = an.ImpedanceLoop.from_config(cfg, closed=True)
            plants.append(p)
            loops.append(loop)
            if i < len(bench):
                free.append([free_plant_with_ankle_input(pp, loop.dt, slope)
                             for kf, vf, slope, foot, pp in an._plant_cases(p, 0.12) if foot == "free"])
        return cls(plants, loops, free)


def passive(setup: Setup, loops: list[an.ImpedanceLoop], axis: int = 0) -> float:
    """N m s/rad: the least damping the loops render on ``axis`` (0 DP) at the bench's stiffnesses, over
    the acceptance check's plant range (:func:`ankle_rt.passivity.least_rendered_damping`; >= 0: passive)."""
    return min(least_rendered_damping(p, loop)[axis].damping for p, loop in zip(setup.plants[:len(setup.free)], loops))


def felt(setup: Setup, loops: list[an.ImpedanceLoop], axis: int = 0) -> dict:
    """The figures on the nominal plant (``axis``, 0 DP): Re Z error % at JUDGED_HZ, damping Im Z / w,
    J_app, keyed by the axis's commanded stiffness."""
    out = {}
    freqs = np.array([*JUDGED_HZ, INERTIA_HZ])
    w = 2.0 * math.pi * freqs
    for loop, cases in zip(loops, setup.free):
        k = loop.stiffness[axis]
        nominal = cases[len(cases) // 2]          # x1 cables, x1 viscous, no load slope (middle case)
        Z = 1.0 / receptance(nominal, loop, freqs)[:, axis, axis]
        out[k] = {"err_pct": [100.0 * (z.real / k - 1.0) for z in Z[:-1]],
                  "damping": [z.imag / wi for z, wi in zip(Z[:-1], w)],
                  "j_app": float((k - Z[-1].real) / w[-1] ** 2)}
    return out


def step_overshoot(setup: Setup, loop: an.ImpedanceLoop, axis: int = 0) -> dict[str, float]:
    """% overshoot of the held-foot desired-torque step (1 N m on ``axis``), rigid and soft ground."""
    out = {}
    for name, ground in (("rigid", ((1000.0, 500.0), 1.0)), ("soft", ((300.0, 150.0), 1.0))):
        y = an.torque_step_response(setup.plants[0], loop, tuple(float(a == axis) for a in (0, 1)), 1500,
                                    ground=ground)[:, axis]
        out[name] = 100.0 * (y.max() / y[-200:].mean() - 1.0)
    return out


# a start inside the feasible set: the configured loop with each class's sections doing (almost) nothing
NEUTRAL = {"notch_hz": 100.0, "notch_zeta": 0.2, "notch_depth": 0.7, "lag_hz": 1.0, "lag_boost": 1.0,
           "lead_hz": 20.0, "lead_ratio": 1.0, "rolloff_hz": 200.0, "rolloff_zeta": 0.7}


def params_of(cls: str, cutoff: bool) -> tuple[tuple[str, float, float], ...]:
    """The searched parameters: the axis's kp, ki, kd (with ``cutoff`` also the shared cutoff), the class's."""
    return (LOOP_PARAMS if cutoff else LOOP_PARAMS[:3]) + CLASSES[cls][0]


def loops_for(setup: Setup, cls: str, x: np.ndarray, axis: int, cutoff: bool) -> list[an.ImpedanceLoop]:
    """``axis``'s gains (``cutoff``: and the cutoff) and the class's sections from the parameter vector
    ``x``, the rest as configured."""
    kp, ki, kd, *rest = (float(v) for v in x)
    cutoff_hz = rest.pop(0) if cutoff else setup.loops[0].cutoff_hz
    sections = CLASSES[cls][1](setup.loops[0].dt, *rest)
    pick = lambda pair, v: tuple(v if a == axis else pair[a] for a in (0, 1))  # noqa: E731
    return [dataclasses.replace(l, kp=pick(l.kp, kp), ki=pick(l.ki, ki), torque_rate_gain=pick(l.torque_rate_gain, kd),
                                cutoff_hz=cutoff_hz, shaping=pick(l.shaping, sections))
            for l in setup.loops]


def margin(setup: Setup, loops: list[an.ImpedanceLoop]) -> float:
    """The least gain margin (dB, at most 12) over the 108 cases at every impedance of ``setup``."""
    return min(an.loop_margin_db(p, l, load_coefficient=0.12) for p, l in zip(setup.plants, loops))


def shortfall(setup: Setup, loops: list[an.ImpedanceLoop], margin_db: float) -> float:
    """0 when stable at every gain up to ``margin_db`` on every case at every impedance (checked on a
    1 dB grid, then a 0.25 dB one: a lightly damped held-foot mode can cross the unit circle for a
    window of gains only); else the number of failing grid points plus the nominal gain's
    spectral-radius excess (a graded penalty). Then the daemon's own check (:func:`margin`), which
    also scans the correction's gain down (a large lag is conditionally stable: docs/daemon.md, "Fifth
    pass"; not searched for before): its shortfall in dB."""
    matrices = [an._loop_matrices(p, l, 0.12) for p, l in zip(setup.plants, loops)]
    for step in (1.0, 0.25):
        grid = 10.0 ** (np.arange(0.0, margin_db + 1e-9, step) / 20.0)
        worst = 0.0
        for T0, Tu in matrices:
            rho = np.abs(np.linalg.eigvals(T0[None] + grid[:, None, None, None] * Tu[None])).max(axis=-1).max(axis=-1)
            worst = max(worst, float((rho >= 1.0).sum()) + max(0.0, float(rho[0]) - 1.0))
        if worst > 0.0:
            return worst
    return max(0.0, margin_db - margin(setup, loops))


def cost(x: np.ndarray, setup: Setup, cls: str, axis: int, cutoff: bool) -> float:
    """The worst |Re Z / K - 1| (%) at 0.5-2 Hz at both stiffnesses, plus J_app (5 Hz, x10) as a
    tie-breaker; 1e3 x the margin's shortfall (+ 1e3) when it fails, 500 when not passive."""
    loops = loops_for(setup, cls, x, axis, cutoff)
    f = felt(setup, loops, axis)
    err = min(max(abs(e) for k in f for e in f[k]["err_pct"]), 400.0)
    miss = shortfall(setup, loops, MARGIN_DB)
    if miss > 0.0:
        return 1e3 * (1.0 + miss) + err
    if passive(setup, loops, axis) < 0.0:
        return 500.0 + err
    return err + 10.0 * next(iter(f.values()))["j_app"]


def report(setup: Setup, loops: list[an.ImpedanceLoop], axis: int, name: str, params: dict[str, float]) -> dict:
    """Every figure of ``loops`` (the two stiffnesses) on ``axis``."""
    return {"class": name, "axis": AXES[axis], "params": params, "margin_db": margin(setup, loops),
            "passive_min": passive(setup, loops, axis), "felt": felt(setup, loops, axis),
            "step_pct": step_overshoot(setup, loops[0], axis)}


def show(r: dict) -> None:
    f = r["felt"]
    params = ", ".join(f"{k} {v:g}" for k, v in r["params"].items())
    print(f"\n== {r['class']} ({r['axis']}): {params}")
    print(f"   margin {r['margin_db']:.2f} dB, passive {r['passive_min'] >= 0.0} (min Re Y {r['passive_min']:.2e}), "
          f"step (K_dp 50) rigid / soft {r['step_pct']['rigid']:.0f} / {r['step_pct']['soft']:.0f} %")
    for k, v in f.items():
        print(f"   K {k:g}: Re Z err {' / '.join(f'{e:+.1f}' for e in v['err_pct'])} % at {JUDGED_HZ} Hz, "
              f"Im Z/w {' / '.join(f'{b:.2f}' for b in v['damping'])}, J_app(5 Hz) {v['j_app']:.3f} kg m^2")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--axis", choices=AXES, default="dp")
    ap.add_argument("--config", help="the configured loop the search starts from (default: the shipped)")
    ap.add_argument("--classes", nargs="*", default=list(CLASSES))
    ap.add_argument("--maxiter", type=int, default=30)
    ap.add_argument("--popsize", type=int, default=8)
    ap.add_argument("--seed", type=int, default=19)
    ap.add_argument("--fixed-cutoff", action="store_true", help="keep the configured cutoff_hz (always on IE)")
    args = ap.parse_args()
    axis = AXES.index(args.axis)
    cutoff = axis == 0 and not args.fixed_cutoff
    setup = Setup.build(args.config)
    l0 = setup.loops[0]
    configured = [l0.kp[axis], l0.ki[axis], l0.torque_rate_gain[axis], l0.cutoff_hz]
    show(report(setup, setup.loops, axis, "configured", dict(zip(("kp", "ki", "kd", "cutoff_hz"), configured))))
    for cls in args.classes:
        bounds = [(lo, hi) for _, lo, hi in params_of(cls, cutoff)]
        start = [*configured[:4 if cutoff else 3], *(NEUTRAL[n] for n, *_ in CLASSES[cls][0])]
        t0 = time.monotonic()
        res = differential_evolution(cost, bounds, args=(setup, cls, axis, cutoff), maxiter=args.maxiter, popsize=args.popsize,
                                     seed=args.seed, polish=False, tol=0.0, atol=0.05, init="sobol", x0=start)
        print(f"\n[{cls}: {res.nfev} evaluations, {time.monotonic() - t0:.0f} s, cost {res.fun:.1f}]")
        names = [n for n, *_ in params_of(cls, cutoff)]
        show(report(setup, loops_for(setup, cls, res.x, axis, cutoff), axis, cls,
                    dict(zip(names, (round(float(v), 4) for v in res.x)))))


if __name__ == "__main__":
    main()
