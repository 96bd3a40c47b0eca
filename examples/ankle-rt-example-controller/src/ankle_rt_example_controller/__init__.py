"""An ankle-rt controller plugin: ankle impedance with a stiffness that rises with the load.

``tau_ankle = K (1 + s |tau_j|) (theta_ref - theta) - B dtheta`` per ankle axis, with the measured
joint torque ``tau_j`` (tared strain gauges, N m), mapped to the motors by ``tau_m = R^-T tau_ankle``.
Parameters (``controller.params``): ``stiffness`` [DP, IE] N m/rad, ``stiffening`` 1/(N m),
``damping`` [DP, IE] N m s/rad.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from ankle_rt.control.base import Controller, ControllerContext
from ankle_rt.estimation import Estimate

__all__ = ["LoadStiffening"]


def _pair(params: Mapping[str, Any], key: str) -> tuple[float, float]:
    value = params.get(key)
    if not (isinstance(value, list) and len(value) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0
                    for v in value)):
        raise ValueError(f"controller.params.{key}: expected [DP, IE], two finite numbers >= 0, got {value!r}")
    return float(value[0]), float(value[1])


class LoadStiffening(Controller):
    """Ankle impedance whose stiffness grows with the measured joint torque (see the module docstring)."""

    PARAMS = ("stiffness", "stiffening", "damping")

    def __init__(self, context: ControllerContext):
        super().__init__(context)
        p = context.params
        unknown = sorted(set(p) - set(self.PARAMS))
        if unknown:
            raise ValueError(f"controller.params.{unknown[0]}: unknown key (expected one of: {', '.join(self.PARAMS)})")
        self.k_dp, self.k_ie = _pair(p, "stiffness")
        self.b_dp, self.b_ie = _pair(p, "damping")
        s = p.get("stiffening", 0.0)
        if not (isinstance(s, (int, float)) and not isinstance(s, bool) and 0 <= s < math.inf):
            raise ValueError(f"controller.params.stiffening: expected a finite number >= 0, got {s!r}")
        self.stiffening = float(s)
        self.RiT = context.kin.R_inv_T.ravel().tolist()   # plain floats: no array temporaries per cycle
        self.ref = context.ref

    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        ref, pos, vel, tj = self.ref, est.ankle_pos, est.ankle_vel, est.sg_torque
        s = self.stiffening
        t0 = self.k_dp * (1.0 + s * abs(tj.item(0))) * (ref.item(0) - pos.item(0)) - self.b_dp * vel.item(0)
        t1 = self.k_ie * (1.0 + s * abs(tj.item(1))) * (ref.item(1) - pos.item(1)) - self.b_ie * vel.item(1)
        r = self.RiT
        out_torque[0] = r[0] * t0 + r[1] * t1
        out_torque[1] = r[2] * t0 + r[3] * t1
