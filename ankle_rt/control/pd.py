"""Motor-side PD control, the paper's eq. 11: ``u = kp (theta_m_ref - theta_m) - kd dtheta_m``.

The motor reference comes from the ankle reference through the rigid kinematics,
``theta_m_ref = R theta_ref``; the derivative acts on the filtered motor velocity, not on the error,
so a reference step does not kick the command. Optional friction feed-forward is added.
"""

from __future__ import annotations

import numpy as np

from ankle_rt.control.friction import FrictionFeedForward
from ankle_rt.control.gains import RampedGainController
from ankle_rt.estimation import Estimate
from ankle_rt.kinematics import Kinematics


class MotorPD(RampedGainController):
    def __init__(self, kin: Kinematics, ref: np.ndarray, *, kp: float, kd: float, dt: float,
                 ramp_s: float = 0.0, soft_start_s: float = 0.0, friction: FrictionFeedForward | None = None):
        """``ref``: rad [DP, IE], read every update. ``kp`` N m/rad, ``kd`` N m s/rad, per motor."""
        super().__init__({"kp": kp, "kd": kd}, dt=dt, ramp_s=ramp_s, soft_start_s=soft_start_s, friction=friction)
        self.R = kin.R.ravel().tolist()
        self.ref = ref

    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        g = self.gains
        g.advance()
        kp, kd = g.values
        s = g.scale
        R = self.R
        ref, pos, vel = self.ref, est.motor_pos, est.motor_vel
        r0, r1 = ref.item(0), ref.item(1)
        v1, v2 = vel.item(0), vel.item(1)
        ff = self.friction
        out_torque[0] = s * (kp * (R[0] * r0 + R[1] * r1 - pos.item(0)) - kd * v1 + ff.torque(v1))
        out_torque[1] = s * (kp * (R[2] * r0 + R[3] * r1 - pos.item(1)) - kd * v2 + ff.torque(v2))
