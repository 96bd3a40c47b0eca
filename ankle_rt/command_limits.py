"""The limits a command must respect, one check each, for both places that enforce them: the
service protocol refuses a request line beyond them (:mod:`ankle_rt.service.protocol`) and the
daemon refuses the same command from any caller (:meth:`ankle_rt.daemon.Daemon.set_gains`,
``set_reference``). Numpy-free and below both layers (the ``ctl`` client imports it too).

- Gains: each run-time gain (``GAIN_FIELDS``) within [0, its ``controller.gain_limits`` maximum]; the
  joint-torque loop's within its config ceiling (``TORQUE_LOOP_MAX_GAINS``; the daemon also requires
  the loop's stability margin, :func:`ankle_rt.analysis.gain_set_margin_db`).
- References: |dp| and |ie| within the ankle range (``limits.ankle_range_deg``).
"""

from __future__ import annotations

import math
from typing import Mapping

GAIN_FIELDS: dict[str, str] = {
    "kp": "N m/rad, motor-side PD position gain",
    "kd": "N m s/rad, motor-side PD velocity gain",
    "stiffness_dp": "N m/rad, ankle impedance stiffness in DP",
    "stiffness_ie": "N m/rad, ankle impedance stiffness in IE",
    "damping_dp": "N m s/rad, ankle impedance damping in DP",
    "damping_ie": "N m s/rad, ankle impedance damping in IE",
    "kp_dp": "N m per N m, joint-torque loop proportional gain in DP",
    "kp_ie": "N m per N m, joint-torque loop proportional gain in IE",
    "ki_dp": "1/s, joint-torque loop integral gain in DP",
    "ki_ie": "1/s, joint-torque loop integral gain in IE",
    "torque_rate_dp": "s, joint-torque loop gain on the measured torque's rate in DP",
    "torque_rate_ie": "s, joint-torque loop gain on the measured torque's rate in IE",
}

# Plausible ceilings of the torque loop's gains (controller.torque_loop's schema bounds too): far beyond
# what the loop's margins allow (docs/daemon.md), so a typo or a non-finite value is refused.
MAX_TORQUE_KP, MAX_TORQUE_KI, MAX_TORQUE_RATE = 100.0, 1000.0, 1.0
TORQUE_LOOP_MAX_GAINS = {"kp_dp": MAX_TORQUE_KP, "kp_ie": MAX_TORQUE_KP, "ki_dp": MAX_TORQUE_KI, "ki_ie": MAX_TORQUE_KI,
                         "torque_rate_dp": MAX_TORQUE_RATE, "torque_rate_ie": MAX_TORQUE_RATE}
DEFAULT_MAX_GAINS = {"kp": 500.0, "kd": 10.0, "stiffness_dp": 200.0, "stiffness_ie": 200.0, "damping_dp": 5.0,
                     "damping_ie": 5.0, **TORQUE_LOOP_MAX_GAINS}
"""= the defaults of controller.gain_limits (tested), for limits made without a config."""


def gain_maxima(gain_limits: Mapping[str, float]) -> dict[str, float]:
    """The largest value of each GAIN_FIELDS name, from a config's ``controller.gain_limits``
    (``stiffness`` and ``damping`` bound both axes) and TORQUE_LOOP_MAX_GAINS."""
    return {name: float(TORQUE_LOOP_MAX_GAINS[name] if name in TORQUE_LOOP_MAX_GAINS else gain_limits[name.split("_")[0]])
            for name in GAIN_FIELDS}


def gain_problem(name: str, value: object, maxima: Mapping[str, float]) -> str | None:
    """Why ``value`` is refused for the gain ``name`` (not a finite number, negative, above its
    maximum), None when it is allowed. A name without a maximum (a plugin's gain) is bounded only
    below."""
    doc = f"; {GAIN_FIELDS[name]}" if name in GAIN_FIELDS else ""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return f"must be a finite number{f' ({GAIN_FIELDS[name]})' if doc else ''}, got {value!r}"
    if value < 0.0:
        return f"must be >= 0{f' ({GAIN_FIELDS[name]})' if doc else ''}, got {value:g}"
    limit = maxima.get(name, math.inf)
    if value > limit:
        where = "its controller.torque_loop ceiling" if name in TORQUE_LOOP_MAX_GAINS else "controller.gain_limits"
        return f"must be <= {limit:g} ({where}{doc}), got {value:g}"
    return None


def reference_problem(value: float, limit_rad: float) -> str | None:
    """Why the reference angle ``value`` rad is refused (beyond +/- ``limit_rad``, the ankle range;
    NaN too), None when it is allowed."""
    if abs(value) <= limit_rad:
        return None
    return (f"{value:.4g} rad is outside the ankle range +/-{limit_rad:.4g} rad "
            f"({math.degrees(limit_rad):.3g} deg)")
