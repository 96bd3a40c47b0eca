"""The joint-torque loop's lag elements [DP, IE]: a low-frequency boost (s + wz) / (s + wz / boost) on the
loop's P and rate terms, gain ``lag_boost_dp`` / ``_ie`` at DC and 1 well above ``lag_hz_dp`` / ``_ie``
(so the cable modes see kp), each one first-order section (b0, b1, b2, a1, a2) with b2 = a2 = 0. One
:class:`Lag` serves the daemon's loop (ankle_rt.control.torque_loop) and the sampled linear model
(ankle_rt.analysis), so the margin check counts exactly the filter the loop runs. Between its pole and
zero it acts as an integral (kp wz / s), so the loop's Routh limit on ``ki`` applies to it too: the
margin check decides what boost a set may have (docs/daemon.md, "Fifth pass"). A leaf module."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

from ankle_rt.notch import AXES, IDENTITY_SECTION


def lag_on(f_zero: float, boost: float) -> bool:
    """Whether a lag of zero ``f_zero`` (Hz) and DC gain ``boost`` does anything (0 Hz or boost 1: off)."""
    return f_zero > 0.0 and boost != 1.0


def lag_section(f_zero: float, boost: float, dt: float) -> tuple[float, float, float, float, float]:
    """(b0, b1, b2, a1, a2) of (s + wz) / (s + wz / boost), wz = 2 pi ``f_zero``: gain ``boost`` at DC, 1
    far above f_zero; sampled over ``dt`` by Tustin prewarped at f_zero. ``f_zero`` 0 or ``boost`` 1:
    the identity (no lag)."""
    if not lag_on(f_zero, boost):
        return IDENTITY_SECTION
    if f_zero >= 0.5 / dt:
        raise ValueError(f"lag_hz {f_zero:g} is not below the loop's Nyquist frequency {0.5 / dt:g} Hz")
    wz = 2.0 * math.pi * f_zero
    c = wz / math.tan(wz * dt / 2.0)
    wp = wz / boost
    a0 = c + wp
    return ((c + wz) / a0, (wz - c) / a0, 0.0, (wp - c) / a0, 0.0)


@dataclass(frozen=True)
class Lag:
    """The lag elements [DP, IE] on the torque loop's P and rate terms as the loop runs them."""

    hz: tuple[float, float]        # the zero's frequency (the boost is 1 above it); 0: none
    boost: tuple[float, float]     # gain at DC (>= 1; 1: none)

    @classmethod
    def from_config(cls, torque_loop: Mapping[str, Any]) -> "Lag":
        """From ``controller.torque_loop`` (``lag_hz_dp`` / ``_ie``, ``lag_boost_dp`` / ``_ie``)."""
        pair = lambda key: tuple(float(torque_loop[f"{key}_{a}"]) for a in AXES)  # noqa: E731
        return cls(hz=pair("lag_hz"), boost=pair("lag_boost"))

    @property
    def on(self) -> tuple[bool, bool]:
        """Per axis [DP, IE]: whether its lag does anything."""
        return lag_on(self.hz[0], self.boost[0]), lag_on(self.hz[1], self.boost[1])

    def sections(self, dt: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """The lag of each axis [DP, IE] as a section over ``dt`` (:func:`lag_section`)."""
        return tuple(lag_section(self.hz[a], self.boost[a], dt) for a in (0, 1))
