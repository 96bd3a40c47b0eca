"""Stiction (the paper's section 3.1): sawtooth torque ramps CW and CCW; the breakaway torque is where
the encoder shows the motor starting to move. Gives kc+ (CCW, positive velocity) and kc- (CW).

Breakaway detection: the first time t1 the windowed encoder speed exceeds ``onset_speed`` (well above
the creep of a smoothed friction law, well below the ramp's final speed). The friction torque there is
the applied torque minus what accelerates the rotor and the viscous part:
``kc = tau(t1) - J w'(t1) - D w(t1)``, with w and w' from a quadratic fit of the encoder angle over
+-``fit_half_window_s`` around t1 (no differentiation of the quantised signal). J and D come from the
inertia experiment when available, else from the config; the correction is small
(J w' ~ 0.02-0.04 N m at 0.25-0.5 N m/s ramps), so a 30 % error in J moves kc by ~0.01 N m.
Without it a speed threshold reads the ramp late and overestimates kc by 5-15 %.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ankle_rt.estimation import Estimate
from ankle_rt.identification.runner import LEAD_S
from ankle_rt.identification.signals import (IdentificationError, centred_velocity, input_column,
                                            motor_channel, runs)
from ankle_rt.identification.stats import Measured, measured
from ankle_rt.interchange import Recording


class StictionExperiment:
    """CycleController: torque ramps at ``ramp_rate`` (N m/s) from zero, alternating CCW (+) and CW (-),
    ``repeats`` per direction. A ramp stops (torque zero) once the motor turns faster than
    ``stop_speed`` (rad/s) or reaches ``max_torque``; the motor then coasts to rest for ``rest_s``."""

    def __init__(self, motor: int = 1, ramp_rate: float = 0.25, max_torque: float = 0.8,
                 rest_s: float = 0.6, repeats: int = 3, stop_speed: float = 1.0):
        self.i = motor - 1
        self.ramp_rate, self.ramp_s = ramp_rate, max_torque / ramp_rate
        self.period_s = self.ramp_s + rest_s
        self.teeth = 2 * repeats
        self.stop_speed = stop_speed
        self.t0 = 0.0
        self.stopped_tooth = -1

    @property
    def duration_s(self) -> float:
        return LEAD_S + self.teeth * self.period_s

    def reset(self, est: Estimate) -> None:
        self.t0 = est.t
        self.stopped_tooth = -1

    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        out_torque[0] = out_torque[1] = 0.0
        phase = est.t - self.t0 - LEAD_S
        if phase < 0.0:
            return
        tooth = int(phase // self.period_s)
        within = phase - tooth * self.period_s
        if tooth >= self.teeth or within >= self.ramp_s or tooth == self.stopped_tooth:
            return
        direction = 1.0 if tooth % 2 == 0 else -1.0
        if direction * est.motor_vel[self.i] > self.stop_speed:
            self.stopped_tooth = tooth
            return
        out_torque[self.i] = direction * self.ramp_rate * within


@dataclass(frozen=True)
class Breakaway:
    t: float          # s, breakaway time (speed crosses the onset speed)
    torque: float     # N m, signed friction torque there (applied minus inertial and viscous)
    direction: int    # +1 CCW, -1 CW
    start: int        # row index where the ramp starts
    stop: int         # row index after the ramp


@dataclass(frozen=True)
class StictionResult:
    kc_pos: Measured  # N m, breakaway torque magnitude for positive (CCW) motion
    kc_neg: Measured  # N m, for negative (CW) motion
    events: tuple[Breakaway, ...]
    skipped: tuple[str, ...]  # why some ramps gave no value


def estimate_stiction(rec: Recording, motor: int = 1, kt: float | None = None, *, inertia: float,
                      damping: float, onset_speed: float = 0.05, half_window_s: float = 0.01,
                      fit_half_window_s: float = 0.04) -> StictionResult:
    """Breakaway friction torques of every torque ramp in ``rec`` (ramps: runs of input of one sign
    above 1 % of its largest magnitude, starting from rest). ``inertia`` kg m^2 and ``damping`` N m s/rad correct the torque for
    the rotor's acceleration (module docstring); ``onset_speed`` rad/s."""
    t, pos, tau = motor_channel(rec, motor, kt)
    vel = centred_velocity(t, pos, half_window_s)
    col = input_column(rec, motor)
    w = max(2, int(round(fit_half_window_s / rec.dt)))
    events, skipped = [], []
    floor = 0.01 * float(np.max(np.abs(tau))) if len(tau) else 0.0   # set-value noise is not a ramp
    for sign in (1, -1):
        for a, b in runs(sign * tau > floor):
            if b - a < 10:
                continue
            end = min(len(t), b + int(0.2 / rec.dt))   # the motor may still be accelerating at the cut
            v = sign * vel[a:end]
            if abs(vel[a]) > onset_speed:
                skipped.append(f"ramp at t = {t[a]:.3f} s does not start from rest")
                continue
            above = np.flatnonzero(v > onset_speed)
            if above.size == 0:
                skipped.append(f"ramp at t = {t[a]:.3f} s: the motor did not break away "
                               f"(max |{col}| = {np.max(np.abs(tau[a:b])):.3g})")
                continue
            k = a + int(above[0])
            lo, hi = max(a, k - w), min(len(t), k + w + 1)
            c2, c1, _ = np.polyfit(t[lo:hi] - t[k], pos[lo:hi], 2)
            friction = tau[k] - inertia * 2.0 * c2 - damping * c1
            events.append(Breakaway(float(t[k]), float(friction), sign, a, b))
    events.sort(key=lambda e: e.t)
    pos_vals = [e.torque for e in events if e.direction > 0]
    neg_vals = [-e.torque for e in events if e.direction < 0]
    if not pos_vals or not neg_vals:
        missing = "CCW (positive)" if not pos_vals else "CW (negative)"
        raise IdentificationError(f"{rec.source}: column {col!r}: no {missing} torque ramp with a breakaway "
                                  f"found ({len(events)} breakaways; {'; '.join(skipped) or 'no ramps'})")
    return StictionResult(measured(pos_vals), measured(neg_vals), tuple(events), tuple(skipped))
