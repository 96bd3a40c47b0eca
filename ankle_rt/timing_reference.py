"""A fixed reference workload that every timing benchmark measures in the same run, so that its
figures can also be given in units of it ("ref steps") and compared between machines.

The workload: one classical RK4 step (h = 1 ms) of the 8-state cable model (docs/design.md "Nominal
model": ankle and motor angles and rates, dx/dt = A x + B f) with the nominal parameters of the
shipped ``config/sim.yaml``, written in plain Python floats (no numpy): the rates, the accelerations
as dense rows of [A B] (zeros included, so the cost does not depend on the parameters' values), the
non-linear gravity remainder (``sin``) and smoothed Coulomb friction (``tanh``) of both motors.
Its code is frozen here: a change of the project's simulator or daemon does not change the unit. A
machine 3x faster does the reference step and the benchmarked code about 3x faster, so a figure in
ref steps stays.

``reference_step_s()`` times it (the median of many short slices, as the benchmarks time theirs); a
benchmark's figure in reference steps is its time divided by that.
"""

from __future__ import annotations

import math
import statistics
import time
from functools import lru_cache

H_S = 1e-3          # s, the RK4 step (one control period at 1 kHz)
STEPS = 20          # reference steps per timed slice (~0.3-1 ms on this project's machines)
REPEATS = 200
START = (0.05, -0.02, 0.3, -0.1, 0.2, 0.1, -0.5, 0.4)   # rad, rad/s: the state each slice starts from


@lru_cache(maxsize=1)
def _nominal_model() -> tuple[tuple[tuple[float, ...], ...], float, float, float]:
    """The rows of [A B] that give the accelerations (4 rows of 8 + 4: the state is [q, q'], so the
    first four rows of dx/dt are the rates), the gravity gain (N m), Coulomb friction (N m) and its
    smoothing velocity (rad/s) of the shipped nominal configuration."""
    from ankle_rt.config import load_config
    from ankle_rt.linear_model import LinearModel
    from ankle_rt.params import PlantParams
    from ankle_rt.paths import default_config_path

    p = PlantParams.from_config(load_config(default_config_path()))
    lin = LinearModel.from_params(p)
    rows = tuple(tuple(lin.A[i].tolist() + lin.B[i].tolist()) for i in range(4, 8))
    return (rows, float(p.foot.gravity_gain), float(p.actuator.coulomb),
            float(p.actuator.friction_smoothing_velocity))


def _derivative(x: list[float], rows: tuple[tuple[float, ...], ...], grav: float, kc: float, inv_vs: float,
                tau1: float, tau2: float) -> list[float]:
    x0, x1, x2, x3, x4, x5, x6, x7 = x
    f0, f1 = -grav * (math.sin(x0) - x0), 0.0
    f2 = tau1 - kc * math.tanh(x6 * inv_vs)
    f3 = tau2 - kc * math.tanh(x7 * inv_vs)
    out = [x4, x5, x6, x7]
    for a in rows:
        out.append(a[0] * x0 + a[1] * x1 + a[2] * x2 + a[3] * x3 + a[4] * x4 + a[5] * x5 + a[6] * x6
                   + a[7] * x7 + a[8] * f0 + a[9] * f1 + a[10] * f2 + a[11] * f3)
    return out


def reference_step(x: list[float], tau1: float, tau2: float) -> list[float]:
    """The state ``x`` (8 floats) one RK4 step of H_S later with motor torques ``tau1``, ``tau2`` N m."""
    rows, grav, kc, vs = _nominal_model()
    inv_vs, h = 1.0 / vs, H_S
    k1 = _derivative(x, rows, grav, kc, inv_vs, tau1, tau2)
    k2 = _derivative([a + 0.5 * h * b for a, b in zip(x, k1)], rows, grav, kc, inv_vs, tau1, tau2)
    k3 = _derivative([a + 0.5 * h * b for a, b in zip(x, k2)], rows, grav, kc, inv_vs, tau1, tau2)
    k4 = _derivative([a + h * b for a, b in zip(x, k3)], rows, grav, kc, inv_vs, tau1, tau2)
    return [a + h / 6.0 * (b + 2.0 * c + 2.0 * d + e) for a, b, c, d, e in zip(x, k1, k2, k3, k4)]


def reference_step_s(repeats: int = REPEATS, steps: int = STEPS) -> float:
    """Seconds per reference step on this machine now: the median over ``repeats`` slices of
    ``steps`` steps from START with alternating motor torques (short slices: on a busy machine
    most of them run undisturbed, as the benchmarks' own slices do)."""
    _nominal_model()
    times = []
    for r in range(repeats):
        x = list(START)       # each slice from the same state: bounded whatever the parameters
        t0 = time.perf_counter()
        for k in range(steps):
            x = reference_step(x, 0.1 if r % 10 < 5 else -0.1, 0.05)
        times.append((time.perf_counter() - t0) / steps)
    return statistics.median(times)
