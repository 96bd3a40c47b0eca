"""How accurate the integrator is: one fixed excitation and its fine RK4 reference solution.

Shared by the tests (which assert the error bounds) and by ``benchmarks/bench_plant.py`` (which
prints the speed/accuracy trade of the substep count). The excitation moves both motors with
sines and torque steps (Coulomb friction switches direction many times) and kicks the ankle with a
0.5 N m disturbance pulse, so the ~100 Hz cable modes ring.
"""

from __future__ import annotations

import math

import numpy as np

from sim_backend.model import CompliantModel, rk4_step


def excitation(t: float) -> tuple[float, float, float, float]:
    """(tau1, tau2, tau_d_DP, tau_d_IE) in N m at time ``t`` (s), held over each control tick."""
    tau1 = 0.6 * math.sin(2 * math.pi * 2.0 * t) + (0.4 if t >= 0.3 else 0.0)
    tau2 = 0.5 * math.sin(2 * math.pi * 3.3 * t + 1.0) - (0.3 if t >= 0.55 else 0.0)
    pulse = 0.6 <= t < 0.7
    return tau1, tau2, (0.5 if pulse else 0.0), (-0.5 if pulse else 0.0)


def model_trajectory(model: CompliantModel, ticks: int) -> np.ndarray:
    """States (ticks + 1, 8) of ``model`` stepped from rest under :func:`excitation`."""
    model.set_rest_at((0.0, 0.0))
    out = np.empty((ticks + 1, 8))
    out[0] = model.x
    for k in range(ticks):
        model.step(*excitation(k * model.dt))
        out[k + 1] = model.x
    return out


def reference_trajectory(model: CompliantModel, ticks: int, h: float = 1e-5) -> np.ndarray:
    """The same run integrated with classical RK4 at step ``h`` (s): the reference solution.

    ``model`` supplies the equations only (its substeps and state are not used)."""
    n = max(1, round(model.dt / h))
    x = np.zeros(8)
    out = np.empty((ticks + 1, 8))
    out[0] = x
    for k in range(ticks):
        tau1, tau2, td_dp, td_ie = excitation(k * model.dt)
        tau1, tau2 = model.command_torque(tau1, tau2)
        for _ in range(n):
            x = rk4_step(model, x, model.dt / n, tau1, tau2, td_dp, td_ie)
        out[k + 1] = x
    return out


def max_errors(trajectory: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """(rad, rad/s): the largest position and rate error over the run and over all four coordinates."""
    err = np.abs(trajectory - reference)
    return float(err[:, 0:4].max()), float(err[:, 4:8].max())
