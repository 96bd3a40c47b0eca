"""The named candidate effects as blocks of regressors, and the catch-all block.

A candidate adds columns to the baseline regression of its channel (coefficients shared by the
motors or ankle axes, as the simulator's effect is) and may have one nonlinear parameter searched on a
grid (Stribeck velocity, delay, slack width, cogging period). ``parameters`` turns the fitted
coefficients into the simulator effect's parameters (docs/design.md vocabulary = the effect's ``cause``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ankle_rt.diagnosis.signals import CableChannel, MotorChannel

Channel = MotorChannel | CableChannel


@dataclass
class Design:
    """One candidate at one value of its nonlinear parameter: extra columns, and the left side when the
    candidate changes it (a delay shifts the torque)."""

    X: np.ndarray
    y: np.ndarray | None = None


class Candidate:
    cause: str = ""
    channel: str = "motor"
    nonlinear: str | None = None     # name of the grid-searched parameter
    integer: bool = False            # the nonlinear parameter is an integer (refined on the grid only)

    def applies(self, ch: Channel) -> bool:
        return True

    def grid(self, ch: Channel) -> list[float]:
        return [0.0]

    def design(self, ch: Channel, nl: float) -> Design:
        raise NotImplementedError

    def parameters(self, coef: np.ndarray, cov: np.ndarray, nl: float, nl_sd: float,
                   ch: Channel, base_coef: np.ndarray) -> dict[str, tuple[float, float]]:
        """Effect parameters as {name: (value, standard deviation)} from the candidate's coefficients
        ``coef`` (covariance ``cov``) and the baseline's coefficients of the same extended fit."""
        raise NotImplementedError


def _sd(cov: np.ndarray, i: int) -> float:
    return float(np.sqrt(max(cov[i, i], 0.0)))


class Stribeck(Candidate):
    cause = "stribeck"
    nonlinear = "stribeck_velocity"

    def grid(self, ch):
        v99 = float(np.percentile(np.abs(ch.vel), 99))
        return list(np.geomspace(2.0 * ch.v_eps, max(0.3 * v99, 4.0 * ch.v_eps), 18))

    def design(self, ch, nl):
        return Design(ch.filt(np.exp(-(ch.vel / nl) ** 2) * ch.sign)[:, None])

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return {"static_excess": (float(coef[0]), _sd(cov, 0)), "stribeck_velocity": (nl, nl_sd)}


class AsymmetricFriction(Candidate):
    cause = "asymmetric_friction"

    def design(self, ch, nl):
        return Design(np.column_stack([ch.filt(np.abs(ch.sign)), ch.filt(np.abs(ch.vel))]))

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return {"coulomb_asymmetry": (float(coef[0]), _sd(cov, 0)),
                "viscous_asymmetry": (float(coef[1]), _sd(cov, 1))}


class LoadDependentFriction(Candidate):
    cause = "load_dependent_friction"

    def applies(self, ch):
        return bool(np.any(ch.tc))

    def design(self, ch, nl):
        return Design(ch.filt(np.abs(ch.tc) * ch.sign)[:, None])

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return {"coefficient": (float(coef[0]), _sd(cov, 0))}


class Cogging(Candidate):
    cause = "cogging"
    nonlinear = "periods_per_rev"
    integer = True

    def grid(self, ch):
        # up to where the ripple n |v| / 2 pi leaves the filter's pass band for slow-to-medium motion, in
        # steps small enough that the ripple's phase drifts < pi/2 over the travel (every integer on a
        # rotary axis; a linear axis in metres has large n and coarser steps), at most MAX_COGGING_POINTS
        # A ripple is told from a slow position dependence (a spring, a preload: not cogging) only when the
        # travel spans at least MIN_COGGING_PERIODS of it.
        v_slow = float(np.percentile(np.abs(ch.vel), 25)) or 1.0
        span = max(float(np.ptp(ch.pos)), 1e-12)
        step = max(1, int(0.5 * np.pi / span))
        n_min = step * max(1, math.ceil(2.0 * np.pi * MIN_COGGING_PERIODS / span / step))
        n_max = min(max(n_min + 8 * step, int(2.0 * np.pi * 25.0 / v_slow)), n_min + step * MAX_COGGING_POINTS)
        return [float(n) for n in range(n_min, n_max + 1, step)]

    def local_grid(self, ch, best: float) -> list[float]:
        """Every integer between the coarse grid's neighbours of ``best``."""
        grid = self.grid(ch)
        step = int(grid[1] - grid[0]) if len(grid) > 1 else 1
        return [float(n) for n in range(max(int(grid[0]), int(best) - step + 1), int(best) + step)] if step > 1 else []

    def design(self, ch, nl):
        ang = nl * ch.pos
        both = ch.sm.smooth(np.hstack([np.sin(ang), np.cos(ang)]))[ch.rows]   # one filter pass for both
        return Design(np.column_stack([both[:, :ch.m].T.ravel(), both[:, ch.m:].T.ravel()]))

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        s, c = float(coef[0]), float(coef[1])
        amp = float(np.hypot(s, c))
        g = np.array([s, c]) / max(amp, 1e-300)
        amp_sd = float(np.sqrt(max(g @ cov[:2, :2] @ g, 0.0)))
        return {"amplitude": (amp, amp_sd), "periods_per_rev": (nl, 0.0),
                "phase": (float(np.arctan2(c, s)), amp_sd / max(amp, 1e-300))}


class Delay(Candidate):
    cause = "delay"
    nonlinear = "delay"

    def grid(self, ch):
        return list(np.arange(0.25e-3, 25.01e-3, 0.5e-3))

    def design(self, ch, nl):
        return Design(np.zeros((len(ch.target()), 0)), ch.target(nl))

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return {"delay": (nl, nl_sd)}


class Backlash(Candidate):
    cause = "backlash"
    channel = "cable"
    nonlinear = "half_width"

    def grid(self, ch):
        return list(np.geomspace(1e-5, 2e-3, 28))

    def design(self, ch, nl):
        b = nl / ch.geometry.levers
        clipped = np.clip(ch.phi, -b, b)
        return Design(ch.per_column(ch.sm.smooth(clipped)))

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return {"half_width": (nl, nl_sd)}


class HardeningStiffness(Candidate):
    cause = "stiffness_nonlinear"
    channel = "cable"

    def design(self, ch, nl):
        # nominal K per axis: both axes scale with the one cable stiffness k, so one shared coefficient
        # (k_true / k_nominal) / s_h^2 fits both, whatever k is
        return Design(ch.filt(ch.geometry.K * ch.geometry.levers ** 2 * ch.phi ** 3)[:, None])

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        # the extended fit's own K (coefficients of phi) gives k_true / k_nominal
        ratio = float(np.mean(ch.geometry.K / base_coef[[0, 3]]))
        c, sd = float(coef[0]) * ratio, _sd(cov, 0) * ratio
        if c <= 0.0:
            return {"hardening_stretch": (float("inf"), float("inf"))}
        s = c ** -0.5
        return {"hardening_stretch": (s, 0.5 * s * sd / c)}


MOTOR_CANDIDATES: tuple[Candidate, ...] = (Stribeck(), AsymmetricFriction(), LoadDependentFriction(),
                                           Cogging(), Delay())
CABLE_CANDIDATES: tuple[Candidate, ...] = (Backlash(), HardeningStiffness())

MAX_COGGING_POINTS = 300
MIN_COGGING_PERIODS = 2.0
DELAY_LAGS_S = (0.001, 0.002, 0.004, 0.007, 0.011, 0.016, 0.022)


def catch_all_motor(ch: MotorChannel) -> np.ndarray:
    """Generic columns for the motor channel: a torque FIR (latency, dynamics), a torque-constant
    nonlinearity, velocity and cable-torque shapes, slow position dependence (spring, preload, slow
    harmonics) and an offset. No
    low-speed shapes beyond the named Stribeck block: near zero speed the residual carries the
    friction-transition error of any velocity estimate, which must not read as an unnamed effect."""
    now = ch.torque()
    cols = [ch.torque(lag) - now for lag in DELAY_LAGS_S]
    tau = ch.tau / max(float(np.max(np.abs(ch.tau))), 1e-12)
    v99 = max(float(np.percentile(np.abs(ch.vel), 99)), 1e-12)
    v = ch.vel / v99
    raw = [tau * np.abs(tau), tau ** 3, v * np.abs(v), v ** 3, np.abs(v), np.abs(ch.sign)]
    if np.any(ch.tc):
        tcs = ch.tc / max(float(np.max(np.abs(ch.tc))), 1e-12)
        raw += [tcs, np.abs(tcs), tcs * np.abs(tcs), np.abs(tcs) * ch.sign]
    span = max(float(np.ptp(ch.pos)), 1e-12)
    p = (ch.pos - ch.pos.mean(axis=0)) / span
    raw += [p, p * np.abs(p)]
    for n in (1, 2, 3):
        raw += [np.sin(2 * np.pi * n * ch.pos / span), np.cos(2 * np.pi * n * ch.pos / span)]
    raw.append(np.ones_like(ch.pos))
    cols += [ch.filt(r) for r in raw]
    return np.column_stack(cols)


def catch_all_cable(ch: CableChannel) -> np.ndarray:
    """Generic columns for the cable channel: even and odd stretch shapes, rate-dependent terms, and
    soft dead zones (per axis)."""
    scale = np.maximum(np.percentile(np.abs(ch.phi), 99, axis=0), 1e-12)
    p = ch.phi / scale
    d = ch.L_dphi / np.maximum(np.percentile(np.abs(ch.L_dphi), 99, axis=0), 1e-12)
    raw = [p * np.abs(p), p ** 3, p ** 5, np.tanh(4 * p), np.tanh(d / 0.05), d * np.abs(d), p * np.abs(d),
           np.clip(p, -0.1, 0.1), np.clip(p, -0.3, 0.3)]
    return np.hstack([ch.per_column(ch.sm.smooth(r)) for r in raw])
