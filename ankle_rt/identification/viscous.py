"""Viscous friction (the paper's section 3.2): a PI velocity loop holds 3, 5 and 8 rad/s in both
directions; at constant speed the motor torque is all friction, |tau| = kc + kv |v| per direction.

Offline, the steady parts are found from the encoder alone: a plateau is a stretch of at least
``min_plateau_s`` where the speed averaged over ``window_s`` stays within ``tolerance`` of itself
half a window earlier and later. Its speed is the angle travelled over its duration and its torque
the mean input over the same rows (each row's input acts until the next row). Plateaus are grouped
into speed levels per direction; the k-th visit of every level forms repeat k, each repeat gets its
own affine fit, and the results are mean +- SD over repeats (with one repeat: the regression's
standard errors instead).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ankle_rt.estimation import Estimate
from ankle_rt.identification.friction import AffineFit, fit_affine, fit_through_origin
from ankle_rt.identification.runner import LEAD_S
from ankle_rt.identification.signals import IdentificationError, centred_velocity, motor_channel, runs
from ankle_rt.identification.stats import Measured, measured
from ankle_rt.interchange import Recording


class VelocityHoldExperiment:
    """CycleController: PI velocity loop on ``est.motor_vel`` holding each speed of ``speeds`` (rad/s)
    for ``hold_s``, CCW then CW, the whole sweep ``repeats`` times. Torque clamped to ``max_torque``
    (N m) with conditional integration (no wind-up). Gains in N m s/rad and N m/rad."""

    def __init__(self, motor: int = 1, speeds: tuple[float, ...] = (3.0, 5.0, 8.0), hold_s: float = 2.0,
                 repeats: int = 2, kp: float = 2.0, ki: float = 20.0, max_torque: float = 3.0):
        self.i = motor - 1
        self.targets = tuple(d * s for s in speeds for d in (1.0, -1.0))
        self.hold_s, self.repeats = hold_s, repeats
        self.kp, self.ki, self.max_torque = kp, ki, max_torque
        self.t0 = self.t_last = 0.0
        self.integral = 0.0

    @property
    def duration_s(self) -> float:
        return LEAD_S + self.repeats * len(self.targets) * self.hold_s

    def target(self, t: float) -> float:
        """rad/s: the speed the loop holds at time ``t`` (s since reset)."""
        k = int((t - LEAD_S) // self.hold_s)
        if t < LEAD_S or k >= self.repeats * len(self.targets):
            return 0.0
        return self.targets[k % len(self.targets)]

    def reset(self, est: Estimate) -> None:
        self.t0 = self.t_last = est.t
        self.integral = 0.0

    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        out_torque[0] = out_torque[1] = 0.0
        h, self.t_last = est.t - self.t_last, est.t
        target = self.target(est.t - self.t0)
        if target == 0.0:
            self.integral = 0.0
            return
        err = target - est.motor_vel[self.i]
        tau = self.kp * err + self.integral
        if -self.max_torque < tau < self.max_torque:
            self.integral += self.ki * err * h
        out_torque[self.i] = min(self.max_torque, max(-self.max_torque, tau))


@dataclass(frozen=True)
class Plateau:
    start: int        # row indices [start, stop)
    stop: int
    speed: float      # rad/s, signed
    torque: float     # N m, signed mean input


@dataclass(frozen=True)
class ViscousResult:
    kc_pos: Measured  # N m, Coulomb part for positive (CCW) speed
    kc_neg: Measured  # N m, for negative (CW) speed
    kv_pos: Measured  # N m s/rad
    kv_neg: Measured
    fit_pos: AffineFit   # all CCW plateaus together
    fit_neg: AffineFit
    kv_origin: float     # N m s/rad, the paper's through-origin fit over both directions
    plateaus: tuple[Plateau, ...]

    @property
    def kc(self) -> float:
        """N m, symmetric Coulomb friction (mean of the two directions)."""
        return 0.5 * (self.kc_pos.mean + self.kc_neg.mean)

    @property
    def kv(self) -> float:
        """N m s/rad, symmetric viscous coefficient."""
        return 0.5 * (self.kv_pos.mean + self.kv_neg.mean)


def find_plateaus(t: np.ndarray, pos: np.ndarray, tau: np.ndarray, *, window_s: float = 0.2,
                  tolerance: float = 0.005, min_speed: float = 0.3, min_plateau_s: float = 0.5) -> list[Plateau]:
    """Constant-speed stretches (module docstring); ``tolerance`` is relative to the speed."""
    dt = float(np.median(np.diff(t)))
    half = max(1, int(round(window_s / (2 * dt))))
    v = centred_velocity(t, pos, window_s / 2)
    ahead, behind = np.roll(v, -half), np.roll(v, half)
    tol = tolerance * np.abs(v) + 0.01
    steady = (np.abs(v) > min_speed) & (np.abs(ahead - v) < tol) & (np.abs(behind - v) < tol)
    steady[:half] = steady[-half:] = False
    out = []
    for a, b in runs(steady):
        a, b = a + half, b - half            # keep only rows whose whole window was steady
        if (b - a) * dt < min_plateau_s:
            continue
        out.append(Plateau(a, b, float((pos[b] - pos[a]) / (t[b] - t[a])), float(np.mean(tau[a:b]))))
    return out


def _levels(plateaus: list[Plateau]) -> list[list[Plateau]]:
    """Group plateaus of one direction into speed levels (within 10 % of each other), time order kept."""
    levels: list[list[Plateau]] = []
    for p in sorted(plateaus, key=lambda p: abs(p.speed)):
        if levels and abs(p.speed) < 1.1 * abs(levels[-1][0].speed):
            levels[-1].append(p)
        else:
            levels.append([p])
    return [sorted(level, key=lambda p: p.start) for level in levels]


def _direction_fit(plateaus: list[Plateau], name: str, source: str) -> tuple[Measured, Measured, AffineFit]:
    levels = _levels(plateaus)
    if len(levels) < 2:
        raise IdentificationError(f"{source}: need steady speeds at two or more levels {name}, found "
                                  f"{len(levels)} ({len(plateaus)} plateaus)")
    pooled = fit_affine(np.array([p.speed for p in plateaus]), np.array([p.torque for p in plateaus]))
    repeats = min(len(level) for level in levels)
    if repeats < 2:
        note = "SD is the regression standard error (one repeat)"
        return (Measured(pooled.kc, pooled.kc_se, (pooled.kc,), note),
                Measured(pooled.kv, pooled.kv_se, (pooled.kv,), note), pooled)
    fits = [fit_affine(np.array([lv[r].speed for lv in levels]), np.array([lv[r].torque for lv in levels]))
            for r in range(repeats)]
    return measured(f.kc for f in fits), measured(f.kv for f in fits), pooled


def estimate_viscous(rec: Recording, motor: int = 1, kt: float | None = None, **plateau_options: float) -> ViscousResult:
    """kc and kv per direction from the steady parts of ``rec`` (see the module docstring)."""
    t, pos, tau = motor_channel(rec, motor, kt)
    plateaus = find_plateaus(t, pos, tau, **plateau_options)
    ccw = [p for p in plateaus if p.speed > 0]
    cw = [p for p in plateaus if p.speed < 0]
    kc_pos, kv_pos, fit_pos = _direction_fit(ccw, "in the positive (CCW) direction", rec.source)
    kc_neg, kv_neg, fit_neg = _direction_fit(cw, "in the negative (CW) direction", rec.source)
    speeds = np.array([p.speed for p in plateaus])
    torques = np.array([p.torque for p in plateaus])
    return ViscousResult(kc_pos, kc_neg, kv_pos, kv_neg, fit_pos, fit_neg,
                         fit_through_origin(speeds, torques), tuple(plateaus))
