"""Study (issue 19, sixth pass): the joint-torque loop searched for the torque step, the rendered damping and
the current noise at once, on the project's sampled linear model.

The fourth pass (benchmarks/study_torque_loop_shaping.py) searched for the dynamic stiffness alone; its best
loops ring on a held foot (the torque step overshoots 45-55 %), and nothing weighed what the loop makes of the
strain gauges' noise. Here one axis's loop - kp, ki, kd (torque_rate), its torque filter, two band-stops
(``notch``, ``notch2``) and the high-passed motor-rate damping (``motor_rate_damping``, its corner) - is
searched by differential evolution for the worst overshoot of the held-foot torque step (rigid and soft ground,
K_dp 50 and 200, K_ie half: the bench's), subject to

- the dynamic stiffness: |Re Z / K - 1| at 0.5-2 Hz within ``--dynamic`` % (foot free, nominal plant);
- the rendered damping Im Z / w within ``--damping`` % of the commanded (the model's held input adds
  K dt / 2 to it, taken off first);
- >= ``--margin`` dB over the 108 cases of :func:`ankle_rt.analysis.loop_margin_db` (stable down to -20 dB of
  the correction's gain too) and passivity (Re of the felt admittance >= 0, 0.1-50 Hz, free-foot cases);
- the current noise: the RMS of the larger motor's set value that the axis's strain gauge's noise (0.02 N m
  per sample, ``sensors.strain_gauge_noise_rms``) and the encoders' quantisation (motor 2 pi / 116640, joint
  2 pi / 2^19 rad a count) make through the closed loop (a discrete Lyapunov equation;
  :func:`ankle_rt.analysis.sensor_noise_current_a`), at most ``--noise`` A.

``--walk-config FILE`` (e.g. a file including ``walk.yaml`` and ``--config``'s loop) adds its gait phases' impedances to
the margin and passivity constraints, for each of ``--walk-masses`` as ``ankle-rt bench walk`` scales them (100 kg:
early stance 429 N m/rad at 8.5 N m s/rad), checked as the gait-phase controller checks them when it is built (each
phase's (K, B) on :func:`ankle_rt.control.gait_phase.phase_margin_config`, the loop of
:func:`ankle_rt.analysis.gain_set_loop`): walking is where a loop is judged, and its stiff, damped stance springs
(early stance 400 N m/rad) cost margin the bench's impedances do not.

``--rate-source encoders`` searches the loop whose rate terms differentiate the cables' stretch torque from the
motor and joint encoders (``controller.torque_loop.torque_rate_source``) rather than the gauges'.

The other axis keeps ``--config``'s loop (default: the shipped one). Run:
``PYTHONPATH=$PWD nice python3 benchmarks/study_torque_loop_step.py --axis dp [--noise 0.22] [--maxiter 20]``
(1-2 s per candidate on one core; a few hundred per generation).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np
from scipy.optimize import differential_evolution

from ankle_rt import analysis as an
from ankle_rt.bench.walk import wearer_overrides
from ankle_rt.config import load_config
from ankle_rt.config_schema import IMPEDANCE_GAINS, MAX_CUTOFF_HZ, torque_loop_cutoffs
from ankle_rt.control.gait_phase import PHASES, phase_margin_config
from ankle_rt.notch import notch_section
from ankle_rt.params import PlantParams
from ankle_rt.passivity import least_rendered_damping
from ankle_rt.paths import default_config_path
from study_torque_loop_shaping import AXES, Setup, felt

# the searched parameters of one axis: (name, low, high)
PARAMS = (("kp", 15.0, 90.0), ("ki", 2.0, 30.0), ("torque_rate", 0.02, 0.8), ("cutoff_hz", 60.0, MAX_CUTOFF_HZ),
          ("notch_hz", 45.0, 120.0), ("notch_zeta", 0.1, 1.5), ("notch_depth", 0.05, 0.95),
          ("notch2_hz", 90.0, 250.0), ("notch2_zeta", 0.1, 1.5), ("notch2_depth", 0.05, 1.0),
          ("motor_rate_damping", 0.0, 300.0), ("motor_rate_damping_hz", 3.0, 80.0))
GROUNDS = (((1000.0, 500.0), 1.0), ((300.0, 150.0), 1.0))    # the bench's rigid and soft grounds
GAUGE_NOISE_NM = 0.02
ENCODER_NOISE_RAD = an.encoder_noise_rad(load_config(default_config_path()))   # rad [motor, joint]: a count / sqrt(12)


def loops_for(setup: Setup, x: np.ndarray, axis: int) -> list[an.ImpedanceLoop]:
    """The bench's loops with ``axis``'s parameters from ``x`` (PARAMS' order)."""
    kp, ki, kd, cut, f1, z1, d1, f2, z2, d2, rd, rf = (float(v) for v in x)
    pick = lambda pair, v: tuple(v if a == axis else pair[a] for a in (0, 1))  # noqa: E731
    dt = setup.loops[0].dt
    sections = tuple(s for s in (notch_section(f1, z1, d1, dt), notch_section(f2, z2, d2, dt)))
    return [dataclasses.replace(l, kp=pick(l.kp, kp), ki=pick(l.ki, ki), torque_rate_gain=pick(l.torque_rate_gain, kd),
                                axis_cutoff_hz=pick(l.axis_cutoff_hz, cut), shaping=pick(l.shaping, sections),
                                rate_damping=pick(l.rate_damping, rd), rate_damping_hz=pick(l.rate_damping_hz, rf))
            for l in setup.loops]


def walk_phases(walk_config: str, masses: list[float]) -> tuple[list[PlantParams], list[an.ImpedanceLoop]]:
    """The plant and the loops the gait-phase controller checks its phases' (K, B) on (its ``margin_cfg``; the
    friction feed-forward's viscous terms are off under the joint-torque loop), for each wearer of ``masses`` as
    ``ankle-rt bench walk`` tunes the phases for them (:func:`ankle_rt.bench.walk.wearer_overrides`), each distinct
    gain set once."""
    base = load_config(walk_config)
    sets = {}
    for mass in masses:
        cfg = load_config(walk_config, wearer_overrides(base, mass, "normal", 0))
        phases = cfg["controller"]["gait_phase"]
        for name in PHASES:
            gains = {k: phases[name][k] for k in IMPEDANCE_GAINS}
            sets.setdefault(tuple(gains.values()), an.gain_set_loop(phase_margin_config(cfg), gains))
    return [PlantParams.from_config(base)] * len(sets), list(sets.values())


def margin_db(setup: Setup, loops: list[an.ImpedanceLoop]) -> float:
    """dB: the least gain margin over the 108 cases at every impedance of ``setup`` (the bench's, the phases')."""
    return min(an.loop_margin_db(p, l, load_coefficient=0.12) for p, l in zip(setup.plants, loops))


def least_damping(setup: Setup, loops: list[an.ImpedanceLoop], axis: int) -> float:
    """N m s/rad: the least damping rendered on ``axis`` at every impedance of ``setup`` over the acceptance
    check's plant range (:func:`ankle_rt.passivity.least_rendered_damping`; >= 0: passive)."""
    return min(least_rendered_damping(p, l)[axis].damping for p, l in zip(setup.plants, loops))


def step_overshoots(setup: Setup, loops: list[an.ImpedanceLoop], axis: int) -> list[float]:
    """% overshoot of the held-foot desired-torque step on ``axis`` per bench stiffness and ground."""
    out = []
    for loop in loops[:len(setup.free)]:
        for ground in GROUNDS:
            y = an.torque_step_response(setup.plants[0], loop, tuple(float(a == axis) for a in (0, 1)), 1000,
                                        ground=ground)[:, axis]
            out.append(100.0 * (y.max() / y[-150:].mean() - 1.0))
    return out


def current_noise_a(p: an.PlantParams, loop: an.ImpedanceLoop, axis: int, kt: float = 1.66) -> float:
    """A: the larger motor's set-value RMS from ``axis``'s gauge noise (GAUGE_NOISE_NM white per sample) and the
    encoders' quantisation, foot free, nominal plant (:func:`ankle_rt.analysis.sensor_noise_current_a`)."""
    gauge = (GAUGE_NOISE_NM * (axis == 0), GAUGE_NOISE_NM * (axis == 1))
    return max(an.sensor_noise_current_a(p, loop, gauge, kt, ENCODER_NOISE_RAD))


def figures(setup: Setup, x: np.ndarray, axis: int) -> dict:
    loops = loops_for(setup, x, axis)
    f = felt(setup, loops, axis)
    commanded = setup.loops[0].damping[axis]
    return {"loops": loops,
            "dynamic_pct": max(abs(e) for v in f.values() for e in v["err_pct"]),
            "damping_pct": max(abs((b - k * setup.loops[0].dt / 2.0) / commanded - 1.0) * 100.0
                               for k, v in f.items() for b in v["damping"]),
            "j_app": {k: v["j_app"] for k, v in f.items()}}


def cost(x: np.ndarray, setup: Setup, axis: int, args: argparse.Namespace) -> float:
    """The worst step overshoot (%), plus penalties: the constraints' shortfalls, graded."""
    fig = figures(setup, x, axis)
    pen = 20.0 * max(0.0, fig["dynamic_pct"] - args.dynamic) + 3.0 * max(0.0, fig["damping_pct"] - args.damping)
    if pen > 400.0:
        return 3000.0 + pen
    loops = fig["loops"]
    margin = margin_db(setup, loops)
    if margin == -math.inf:
        return 2000.0 + pen
    pen += 100.0 * max(0.0, args.margin - margin)
    if pen > 300.0:
        return 1000.0 + pen
    if least_damping(setup, loops, axis) < 0.0:
        return 900.0 + pen
    pen += 200.0 * max(0.0, current_noise_a(setup.plants[0], loops[0], axis) - args.noise)
    return max(step_overshoots(setup, loops, axis)) + pen


def report(setup: Setup, x: np.ndarray, axis: int) -> None:
    fig = figures(setup, x, axis)
    loops = fig["loops"]
    margins = [an.loop_margin_db(p, l, load_coefficient=0.12) for p, l in zip(setup.plants, loops)]
    print(", ".join(f"{n}_{AXES[axis]} {v:.4g}" for (n, *_), v in zip(PARAMS, x)))
    print(f"  margin {min(margins):.2f} dB (per impedance: {[round(m, 2) for m in margins]}), passive "
          f"{least_damping(setup, loops, axis) >= 0.0}, dynamic {fig['dynamic_pct']:.1f} %, "
          f"damping {fig['damping_pct']:.1f} %, J_app {fig['j_app']}, noise "
          f"{current_noise_a(setup.plants[0], loops[0], axis):.3f} A, steps (K50 rigid, soft, K200 rigid, soft) "
          f"{[round(float(v), 1) for v in step_overshoots(setup, loops, axis)]}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--axis", choices=AXES, default="dp")
    ap.add_argument("--config", help="the loop the search starts from and the other axis keeps (default: the shipped)")
    ap.add_argument("--walk-config", help="a gait-phase config (on --config's loop) whose phases' impedances the margin "
                                          "and passivity must hold at too, e.g. one including walk.yaml then the loop")
    ap.add_argument("--walk-masses", default="50,75,100", metavar="KG,KG,...",
                    help="with --walk-config, the wearers whose phases count (ankle-rt bench walk's default)")
    ap.add_argument("--noise", type=float, default=0.22, help="A, the most current noise from the axis's gauge")
    ap.add_argument("--dynamic", type=float, default=11.0, help="%%, the dynamic stiffness error allowed")
    ap.add_argument("--damping", type=float, default=18.0, help="%%, the rendered damping error allowed")
    ap.add_argument("--margin", type=float, default=6.5, help="dB")
    ap.add_argument("--rate-source", choices=("gauges", "encoders"), default="gauges",
                    help="what the rate terms differentiate (controller.torque_loop.torque_rate_source)")
    ap.add_argument("--rate-crossover-hz", type=float, default=5.0,
                    help="with encoders, the gauges' torque below this (controller.torque_loop.torque_rate_crossover_hz_*)")
    ap.add_argument("--spread", type=float, default=0.0,
                    help="search within +- this fraction of the configured loop (0: the whole range)")
    ap.add_argument("--maxiter", type=int, default=20)
    ap.add_argument("--popsize", type=int, default=6)
    ap.add_argument("--seed", type=int, default=11)
    args = ap.parse_args()
    axis = AXES.index(args.axis)
    full = Setup.build(args.config)
    encoders = args.rate_source == "encoders"     # the searched axis's rate source, the other axis's as configured
    pick = lambda pair, v: tuple(v if a == axis else pair[a] for a in (0, 1))  # noqa: E731
    plants, loops = full.plants[:2], full.loops[:2]      # the bench's two impedances, then the phases'
    if args.walk_config:
        walk_plants, walk_loops = walk_phases(args.walk_config, [float(m) for m in args.walk_masses.split(",")])
        plants, loops = plants + walk_plants, loops + walk_loops
    loops = [dataclasses.replace(l, rate_from_encoders=pick(l.rate_from_encoders, encoders),
                                 rate_crossover_hz=pick(l.rate_crossover_hz, args.rate_crossover_hz))
             for l in loops]
    setup = Setup(plants, loops, full.free)
    tl = load_config(args.config or default_config_path())["controller"]["torque_loop"]
    start = np.array([float(tl[f"{n}_{args.axis}"] if n != "cutoff_hz" else torque_loop_cutoffs(tl)[axis])
                      for n, *_ in PARAMS])
    if start[7] == 0.0:       # no second band-stop: its depth 1 is none wherever the search puts it
        start[9] = 1.0
    bounds = [(lo, hi) for _, lo, hi in PARAMS]
    start = np.clip(start, *zip(*bounds))
    if args.spread:           # a local search: within +-spread of the start
        bounds = [(max(lo, v * (1.0 - args.spread)), min(hi, v * (1.0 + args.spread))) for v, (lo, hi) in zip(start, bounds)]
    print("configured:"); report(setup, start, axis)
    t0 = time.monotonic()
    progress = lambda xk, convergence=None: print(  # noqa: E731
        f"  [{time.monotonic() - t0:.0f} s] best {cost(xk, setup, axis, args):.2f}: "
        + ", ".join(f"{v:.4g}" for v in xk), flush=True)
    res = differential_evolution(cost, bounds, args=(setup, axis, args), maxiter=args.maxiter, popsize=args.popsize,
                                 seed=args.seed, polish=False, tol=0.0, atol=0.1, init="sobol", x0=start,
                                 callback=progress)
    print(f"[{res.nfev} candidates, {time.monotonic() - t0:.0f} s, cost {res.fun:.2f}]")
    report(setup, res.x, axis)


if __name__ == "__main__":
    main()
