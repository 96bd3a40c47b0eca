"""Motor-side PD control, the paper's eq. 11: ``u = kp (theta_m_ref - theta_m) - kd dtheta_m``.

The motor reference comes from the ankle reference through the rigid kinematics,
``theta_m_ref = R theta_ref``; the derivative acts on the filtered motor velocity, not on the error,
so a reference step does not kick the command. Optional friction feed-forward is added.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ankle_rt.control.friction import FrictionFeedForward
from ankle_rt.control.gains import RampedGainController
from ankle_rt.elementwise import Value
from ankle_rt.estimation import Estimate
from ankle_rt.kinematics import Kinematics


class MotorPD(RampedGainController):
    columns = ("R",)

    def __init__(self, kin: Kinematics, ref: np.ndarray, *, kp: float, kd: float, dt: float,
                 ramp_s: float = 0.0, soft_start_s: float = 0.0, friction: FrictionFeedForward | None = None,
                 margin_cfg: Mapping[str, Any] | None = None):
        """``ref``: rad [DP, IE], read every update. ``kp`` N m/rad, ``kd`` N m s/rad, per motor.
        ``margin_cfg``: the config whose plant every gain set (and every point of a ramp) must keep
        the required gain margin on (GainError naming the gain); None: not checked."""
        super().__init__({"kp": kp, "kd": kd}, dt=dt, ramp_s=ramp_s, soft_start_s=soft_start_s, friction=friction,
                         margin_cfg=margin_cfg)
        self.R = kin.R.ravel().tolist()
        self.ref = ref

    def law(self, est: Estimate, ref_dp: Value, ref_ie: Value) -> tuple[Value, Value]:
        g = self.gains
        g.advance()
        kp, kd = g.values
        s = g.scale
        R = self.R
        v1, v2 = est.mv1, est.mv2
        ff = self.friction
        return (s * (kp * (R[0] * ref_dp + R[1] * ref_ie - est.mp1) - kd * v1 + ff.torque(v1)),
                s * (kp * (R[2] * ref_dp + R[3] * ref_ie - est.mp2) - kd * v2 + ff.torque(v2)))
