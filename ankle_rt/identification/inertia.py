"""Actuator inertia (the paper's section 3.3): torque steps from rest; J and D from a nonlinear
least-squares fit (scipy.optimize.least_squares) of the step response.

The model is the motor alone, ``J w' + D w + kc(sign w) = tau``, with kc per direction either given
(from the viscous or stiction experiment) or fitted as a third parameter. It is integrated exactly
over each row (the input is held from one row to the next; Coulomb friction sticks the motor when
the speed reaches zero and the torque cannot overcome it), and the fit compares the model's mean
speed over each row with the measured one, (angle[k+1] - angle[k]) / dt: the paper's unfiltered
differentiation, without any lag. Each step with its coast-down is one repeat.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ankle_rt.estimation import Estimate
from ankle_rt.identification.runner import LEAD_S
from ankle_rt.identification.signals import IdentificationError, input_column, motor_channel
from ankle_rt.identification.stats import Measured, measured
from ankle_rt.interchange import Recording


class TorqueStepExperiment:
    """CycleController: torque steps of ``step_torque`` (N m) held ``on_s``, then zero for ``off_s``
    (the motor coasts to rest), alternating CCW (+) and CW (-), ``repeats`` per direction."""

    def __init__(self, motor: int = 1, step_torque: float = 1.0, on_s: float = 1.0, off_s: float = 0.8,
                 repeats: int = 2):
        self.i = motor - 1
        self.step_torque, self.on_s, self.period_s = step_torque, on_s, on_s + off_s
        self.steps = 2 * repeats
        self.t0 = 0.0

    @property
    def duration_s(self) -> float:
        return LEAD_S + self.steps * self.period_s

    def reset(self, est: Estimate) -> None:
        self.t0 = est.t

    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        out_torque[0] = out_torque[1] = 0.0
        phase = est.t - self.t0 - LEAD_S
        if phase < 0.0:
            return
        step = int(phase // self.period_s)
        if step < self.steps and phase - step * self.period_s < self.on_s:
            out_torque[self.i] = self.step_torque if step % 2 == 0 else -self.step_torque


def motor_response(tau: np.ndarray, dt: float, inertia: float, damping: float, kc_pos: float,
                   kc_neg: float, w0: float = 0.0) -> np.ndarray:
    """rad/s: mean speed over each row of the motor alone driven by ``tau`` (N m, held per row),
    integrated exactly (see the module docstring). ``kc_pos``/``kc_neg`` are friction magnitudes."""
    out = np.empty(len(tau))
    w = w0
    tc = inertia / damping
    a = math.exp(-dt / tc)
    for k, u in enumerate(tau.tolist()):
        if w == 0.0:
            if u > kc_pos:
                f = kc_pos
            elif u < -kc_neg:
                f = -kc_neg
            else:
                out[k] = 0.0
                continue
        else:
            f = kc_pos if w > 0.0 else -kc_neg
        wss = (u - f) / damping
        w_end = wss + (w - wss) * a
        if (w > 0.0 and w_end < 0.0) or (w < 0.0 and w_end > 0.0):   # stops within the row
            tz = -tc * math.log(-wss / (w - wss))
            out[k] = (wss * tz + (w - wss) * tc * (1.0 - math.exp(-tz / tc))) / dt
            w = 0.0
        else:
            out[k] = (wss * dt + (w - wss) * tc * (1.0 - a)) / dt
            w = w_end
    return out


@dataclass(frozen=True)
class StepFit:
    start: int            # row indices [start, stop) of the step and its coast-down
    stop: int
    direction: int        # +1 CCW, -1 CW
    inertia: float        # kg m^2
    damping: float        # N m s/rad
    coulomb: float        # N m, given or fitted
    history: tuple[tuple[float, float], ...]   # (J, D) at each cost evaluation, for the Fig. 4a plot
    measured: np.ndarray  # rad/s, mean speed per row
    model: np.ndarray     # rad/s, fitted model's
    rms: float            # rad/s, residual RMS


@dataclass(frozen=True)
class InertiaResult:
    inertia: Measured     # kg m^2
    damping: Measured     # N m s/rad
    fits: tuple[StepFit, ...]
    friction_given: bool


def _steps(tau: np.ndarray, threshold: float) -> list[tuple[int, int]]:
    """[start, stop) of each step: from a row where |tau| jumps above ``threshold`` to the next such row."""
    on = np.abs(tau) > threshold
    starts = np.flatnonzero(on[1:] & ~on[:-1]) + 1
    if on[0]:
        starts = np.concatenate([[0], starts])
    bounds = list(starts) + [len(tau) - 1]
    return [(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]


def _initial_guess(u: np.ndarray, meas: np.ndarray, dt: float, direction: int,
                   coulomb: tuple[float, float] | None) -> list[float]:
    """[J, D] (and kc when it is fitted) from the start and the peak of the step response."""
    amplitude = abs(float(np.mean(u[: max(1, len(u) // 4)])))
    kc = (coulomb[0] if direction > 0 else coulomb[1]) if coulomb is not None else 0.25 * amplitude
    drive = max(amplitude - kc, 0.1 * amplitude)
    n = min(len(meas) - 1, max(1, int(round(0.05 / dt))))
    accel = abs(float(meas[n])) / (n * dt)
    J = drive / accel if accel > 0 else 0.03
    D = drive / max(float(np.max(np.abs(meas))), 1e-6)
    return [J, D] + ([] if coulomb is not None else [kc])


def estimate_inertia(rec: Recording, motor: int = 1, kt: float | None = None, *,
                     coulomb: tuple[float, float] | None = None, min_step_s: float = 0.3) -> InertiaResult:
    """J and D (mean +- SD over steps) from every torque step of ``rec``. ``coulomb`` = (kc+, kc-) N m
    fixes the friction; None fits one kc per step. The fit starts from the data alone (no prior):
    J from the mean acceleration over the first 50 ms, D from the largest speed."""
    try:
        from scipy.optimize import least_squares
    except ImportError:
        raise IdentificationError("the inertia fit needs scipy: pip install 'ankle-rt[analysis]'") from None
    t, pos, tau = motor_channel(rec, motor, kt)
    dt = rec.dt
    speed = np.diff(pos) / np.diff(t)
    col = input_column(rec, motor)
    threshold = 0.2 * float(np.max(np.abs(tau))) if len(tau) else 0.0
    fits = []
    for a, b in _steps(tau, threshold):
        if (b - a) * dt < min_step_s:
            continue
        meas = speed[a:b]
        u = tau[a:b]
        direction = 1 if np.mean(u[: max(1, len(u) // 4)]) > 0 else -1
        history: list[tuple[float, float]] = []

        def residual(x: np.ndarray) -> np.ndarray:
            J, D = x[0], x[1]
            kc = (coulomb[0], coulomb[1]) if coulomb is not None else (x[2], x[2])
            history.append((float(J), float(D)))
            return motor_response(u, dt, J, D, kc[0], kc[1], 0.0) - meas

        x0 = _initial_guess(u, meas, dt, direction, coulomb)
        lower = [1e-6, 1e-6] + ([] if coulomb is not None else [0.0])
        sol = least_squares(residual, x0, bounds=(lower, np.inf), x_scale=np.abs(x0) + 1e-3)
        kc = (coulomb[0] if direction > 0 else coulomb[1]) if coulomb is not None else float(sol.x[2])
        model = meas + sol.fun
        fits.append(StepFit(a, b, direction, float(sol.x[0]), float(sol.x[1]), kc, tuple(history),
                            meas, model, float(np.sqrt(np.mean(sol.fun ** 2)))))
    if not fits:
        raise IdentificationError(f"{rec.source}: column {col!r}: no torque step of at least {min_step_s} s found")
    return InertiaResult(measured(f.inertia for f in fits), measured(f.damping for f in fits), tuple(fits),
                         coulomb is not None)
