"""Run-time oscillation detector: the last line behind the gain-margin checks (ankle_rt.gain_margin).

A loop that has lost its margin (a gain set the linear model did not foresee, a plant beyond the
checked range) oscillates near the 77-98 Hz cable modes or in the ~80 Hz limit cycle of a hot
joint-torque loop; with the current clamp it can do so for tens of seconds under every other limit.
Per motor, the set value (A) goes through a two-pole high-pass at ``band_hz`` (20 Hz: walking and
commanded motion, < 10 Hz, are attenuated 4x and more) and its mean square through a first-order
low-pass of ``energy_tau_s``; when either motor's band RMS stays above ``rms_limit_a`` for
``hold_s`` the detector fires. A step load excites the band only briefly (its energy decays with
the band's and the averager's time constants, ~0.1 s for a 15 A step), so only a sustained
oscillation lasts the hold.

Written element-wise (:mod:`ankle_rt.elementwise`): plain floats per cycle for the daemon (no
allocation), arrays over a batch of devices for the batched cycle.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

from ankle_rt.elementwise import Value, select, stack

if TYPE_CHECKING:
    import numpy as np

BAND_HZ = 20.0          # high-pass corner of the watched band
ENERGY_TAU_S = 0.02     # s, averaging of the band's mean square


def _lowpass_gain(a: float, freq_hz: float, dt: float) -> complex:
    """The detector's first-order low-pass step ``a`` as a transfer function at ``freq_hz``."""
    w = 2.0 * math.pi * freq_hz * dt
    return a / (1.0 - (1.0 - a) * complex(math.cos(w), -math.sin(w)))


def band_floor(freq_hz: float, dt: float, band_hz: float = BAND_HZ, energy_tau_s: float = ENERGY_TAU_S) -> float:
    """The least band RMS the detector shows, in steady state at the period ``dt`` s, for a sine of
    unit RMS at ``freq_hz``: the two high-pass stages' gain G, less the ripple the energy average
    leaves at twice the frequency (the band's mean square is G^2 (1 - cos 2wt) / 2 per unit amplitude^2,
    averaged by a low-pass L: never below G^2 (1 - |L(2w)|)). A sustained oscillation at that frequency
    trips every limit below this times its RMS."""
    a = 1.0 - math.exp(-2.0 * math.pi * band_hz * dt)
    stage = 1.0 - _lowpass_gain(a, freq_hz, dt)
    ripple = abs(_lowpass_gain(1.0 - math.exp(-dt / energy_tau_s), 2.0 * freq_hz, dt))
    return abs(stage * stage) * math.sqrt(1.0 - ripple)


class OscillationDetector:
    """Sustained high-frequency oscillation of the two current set values (see the module docstring)."""

    def __init__(self, dt: float, rms_limit_a: float, hold_s: float, *, band_hz: float = BAND_HZ,
                 energy_tau_s: float = ENERGY_TAU_S):
        self.dt = dt
        self.a = 1.0 - math.exp(-2.0 * math.pi * band_hz * dt)   # low-pass step of each high-pass stage
        self.b = 1.0 - math.exp(-dt / energy_tau_s)
        self.limit2 = rms_limit_a * rms_limit_a                    # A^2
        self.hold = hold_s
        self.reset()

    @classmethod
    def stack(cls, detectors: Sequence["OscillationDetector"]) -> "OscillationDetector":
        """One detector standing for ``detectors`` (one per device of a batch): numbers as arrays."""
        return stack(detectors, shared=("dt",))

    def reset(self, where: bool | np.ndarray = True) -> None:
        """Forget the past (on activation: the set values restart from zero); for a batch, only where
        ``where`` (bool per device) holds."""
        # the two high-pass stages' low-pass states and the band mean square (A^2), per motor; the
        # time (s) the band RMS has been above the limit
        for name in ("l0", "l1", "m0", "m1", "e0", "e1", "above"):
            setattr(self, name, select(where, 0.0, getattr(self, name, 0.0)))

    def update(self, i0: Value, i1: Value) -> Value:
        """Feed one cycle's set values (A); True (per device) once an oscillation has lasted ``hold_s``."""
        a, b = self.a, self.b
        self.l0 = l0 = self.l0 + a * (i0 - self.l0)
        self.l1 = l1 = self.l1 + a * (i1 - self.l1)
        h0, h1 = i0 - l0, i1 - l1                      # first high-pass stage
        self.m0 = m0 = self.m0 + a * (h0 - self.m0)
        self.m1 = m1 = self.m1 + a * (h1 - self.m1)
        g0, g1 = h0 - m0, h1 - m1                      # second stage
        self.e0 = e0 = self.e0 + b * (g0 * g0 - self.e0)
        self.e1 = e1 = self.e1 + b * (g1 * g1 - self.e1)
        self.above = above = select(self.band_above(), self.above + self.dt, 0.0)
        return above >= self.hold

    def band_above(self) -> Value:
        """True (per device) while either motor's band RMS is above the limit (no hold): the
        safety layer names a fault OSCILLATION rather than a sensor's when it coincides with this."""
        return (self.e0 > self.limit2) | (self.e1 > self.limit2)
