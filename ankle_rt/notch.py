"""The joint-torque loop's band-stop as one second-order section (b0, b1, b2, a1, a2): shared by the
daemon's loop (ankle_rt.control.torque_loop) and the sampled linear model (ankle_rt.analysis), so the
margin check counts exactly the filter the loop runs. A leaf module: the model imports it without the
control package."""

from __future__ import annotations

import math
from typing import Any, Mapping

IDENTITY_SECTION = (1.0, 0.0, 0.0, 0.0, 0.0)   # (b0, b1, b2, a1, a2): passes its input through


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


def config_notch_sections(torque_loop: Mapping[str, Any], dt: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The notch of each axis [DP, IE] of ``controller.torque_loop`` over ``dt``."""
    return tuple(notch_section(float(torque_loop[f"notch_hz_{a}"]), float(torque_loop[f"notch_zeta_{a}"]),
                               float(torque_loop[f"notch_depth_{a}"]), dt) for a in ("dp", "ie"))
