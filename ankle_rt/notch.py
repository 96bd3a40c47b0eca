"""The joint-torque loop's band-stops [DP, IE], each one second-order section (b0, b1, b2, a1, a2): one
:class:`Notch` serves the daemon's loop (ankle_rt.control.torque_loop) and the sampled linear model
(ankle_rt.analysis), so the margin check counts exactly the filter the loop runs. The configured centres
(``notch_hz_dp`` / ``notch_hz_ie``, and a second band-stop's ``notch2_hz_dp`` / ``_ie``) are placed for the cable stiffness ``notch_cable_stiffness``; the
loop runs them where the configured cable (``transmission.cable_stiffness``) puts the cable modes they
sit on: x sqrt(k / notch_cable_stiffness), a mode of fixed inertias on a spring of stiffness k. A leaf
module: the model imports it without the control package."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

IDENTITY_SECTION = (1.0, 0.0, 0.0, 0.0, 0.0)   # (b0, b1, b2, a1, a2): passes its input through
AXES = ("dp", "ie")


def notch_section(f0: float, zeta: float, depth: float, dt: float) -> tuple[float, float, float, float, float]:
    """(b0, b1, b2, a1, a2) of the band-stop (s^2 + 2 depth zeta w s + w^2) / (s^2 + 2 zeta w s + w^2),
    w = 2 pi f0: gain ``depth`` at f0, 1 far from it; sampled over ``dt`` by Tustin prewarped at f0 (the
    notch stays where it is put). ``f0`` 0: the identity (no notch)."""
    if f0 <= 0.0:
        return IDENTITY_SECTION
    if f0 >= 0.5 / dt:
        raise ValueError(f"notch_hz {f0:g} is not below the loop's Nyquist frequency {0.5 / dt:g} Hz")
    w = 2.0 * math.pi * f0
    c = w / math.tan(w * dt / 2.0)
    n1, d1 = 2.0 * depth * zeta * w * c, 2.0 * zeta * w * c
    a0 = c * c + d1 + w * w
    return ((c * c + n1 + w * w) / a0, 2.0 * (w * w - c * c) / a0, (c * c - n1 + w * w) / a0,
            2.0 * (w * w - c * c) / a0, (c * c - d1 + w * w) / a0)


def cable_scale(torque_loop: Mapping[str, Any], cable_stiffness: float) -> float:
    """How far the cable modes moved from where the notches were placed: sqrt(``cable_stiffness`` /
    ``notch_cable_stiffness``), both N/m (exactly 1 when they are equal)."""
    return math.sqrt(float(cable_stiffness) / float(torque_loop["notch_cable_stiffness"]))


# the band-stops' key prefixes in controller.torque_loop, in the order the loop runs them: the free foot's
# cable mode, then the loop's own high-frequency mode (the cable mode the loop's rate term moves up)
PREFIXES = ("notch", "notch2")


@dataclass(frozen=True)
class Notch:
    """The band-stops [DP, IE] of one key prefix on the torque loop's P and rate terms as the loop runs them."""

    hz: tuple[float, float]        # centres on the configured cable; 0: none
    zeta: tuple[float, float]      # widths (the denominator's damping ratio)
    depth: tuple[float, float]     # gains at the centres

    @classmethod
    def from_config(cls, torque_loop: Mapping[str, Any], cable_stiffness: float, prefix: str = "notch") -> "Notch":
        """From ``controller.torque_loop``'s ``<prefix>_hz_dp`` ... keys on a cable of ``cable_stiffness`` N/m
        (``transmission.cable_stiffness``): the configured centres moved by :func:`cable_scale`."""
        pair = lambda key: tuple(float(torque_loop[f"{prefix}_{key}_{a}"]) for a in AXES)  # noqa: E731
        scale = cable_scale(torque_loop, cable_stiffness)
        return cls(hz=tuple(f * scale for f in pair("hz")), zeta=pair("zeta"), depth=pair("depth"))

    @classmethod
    def all_from_config(cls, torque_loop: Mapping[str, Any], cable_stiffness: float) -> tuple["Notch", ...]:
        """Every prefix's band-stops (PREFIXES), in the order the loop runs them."""
        return tuple(cls.from_config(torque_loop, cable_stiffness, prefix) for prefix in PREFIXES)

    def sections(self, dt: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """The notch of each axis [DP, IE] as a second-order section over ``dt`` (:func:`notch_section`)."""
        return tuple(notch_section(self.hz[a], self.zeta[a], self.depth[a], dt) for a in (0, 1))
