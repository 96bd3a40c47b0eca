"""Ankle impedance control: a stiffness, damping and equilibrium angle per ankle axis.

``tau_ankle = Ks (theta_0 - theta) - Bs dtheta`` uses the *estimated* ankle angles
``theta = R^-1 theta_m - K^-1 tau_j`` (so the cables' series compliance is measured, not added to the
commanded compliance) and the rigid-cable ankle rate ``R^-1 dtheta_m``. The motor torques that
produce it through the cables are ``tau_m = R^-T tau_ankle``. The equilibrium ``theta_0`` is the
loop's ankle reference. Optional friction feed-forward is added per motor.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ankle_rt.control.friction import FrictionFeedForward
from ankle_rt.control.gains import RampedGainController
from ankle_rt.estimation import Estimate
from ankle_rt.kinematics import Kinematics


class ImpedanceController(RampedGainController):
    def __init__(self, kin: Kinematics, ref: np.ndarray, gains: Mapping[str, float], *, dt: float,
                 ramp_s: float = 0.0, soft_start_s: float = 0.0, friction: FrictionFeedForward | None = None):
        """``gains``: stiffness_dp/ie (N m/rad), damping_dp/ie (N m s/rad). ``ref``: rad [DP, IE]."""
        super().__init__({k: gains[k] for k in ("stiffness_dp", "stiffness_ie", "damping_dp", "damping_ie")},
                         dt=dt, ramp_s=ramp_s, soft_start_s=soft_start_s, friction=friction)
        self.RiT = kin.R_inv_T.ravel().tolist()
        self.ref = ref

    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        g = self.gains
        g.advance()
        k0, k1, b0, b1 = g.values
        s = g.scale
        ref, pos, vel = self.ref, est.ankle_pos, est.ankle_vel
        t0 = k0 * (ref.item(0) - pos.item(0)) - b0 * vel.item(0)
        t1 = k1 * (ref.item(1) - pos.item(1)) - b1 * vel.item(1)
        RiT = self.RiT
        ff = self.friction
        out_torque[0] = s * (RiT[0] * t0 + RiT[1] * t1 + ff.torque(est.motor_vel.item(0)))
        out_torque[1] = s * (RiT[2] * t0 + RiT[3] * t1 + ff.torque(est.motor_vel.item(1)))
