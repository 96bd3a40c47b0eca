"""The compliant model's linear part as second-order matrices and a state-space system (paper eq. 6).

Generalised coordinates q = [theta_DP, theta_IE, theta_1, theta_2] (ankle, then motors at the gearbox
output). The linear part is  Mq q'' + Dq q' + Kq q = f, where f holds the generalised forces that
are not linear in the state: disturbance torques at the ankle, motor torques, friction, the
non-linear remainder of gravity and any effect. The simulator integrates this part exactly and adds
f; the analysis linearises at rest with the same matrices, so both always agree.

State x = [q, q'] (8), input f (4): rows 0-1 act on the ankle, rows 2-3 on the motors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ankle_rt.kinematics import Kinematics
from ankle_rt.params import PlantParams

N_Q = 4
N_X = 8


@dataclass(frozen=True)
class LinearModel:
    Mq: np.ndarray      # 4x4 mass matrix
    Dq: np.ndarray      # 4x4 damping (viscous motor friction + beta * cable stiffness)
    Kq: np.ndarray      # 4x4 stiffness (cables + linearised gravity)
    A: np.ndarray       # 8x8
    B: np.ndarray       # 8x4, generalised-force input
    kin: Kinematics
    cable_Kq: np.ndarray  # 4x4, the cable part of Kq alone (joint torque = -cable_Kq[0:2] @ q)

    @classmethod
    def from_params(cls, p: PlantParams, *, cables: bool = True, gravity: bool = True) -> "LinearModel":
        """Build the linear part. ``cables=False`` models the motors off the cables (the paper's
        section 3); the transmission form (reciprocal or the paper's eq. 4) comes from ``p``."""
        kin = Kinematics.from_params(p.transmission)
        K, Ri, RiT = kin.K, kin.R_inv, kin.R_inv_T
        cable = np.zeros((N_Q, N_Q))
        if cables:
            # Ankle rows: tau_j = K (R^-1 theta_m - theta).
            cable[0:2, 0:2] = K
            cable[0:2, 2:4] = -K @ Ri
            if p.transmission.form == "reciprocal":
                # Motor rows: the motors feel R^-T tau_j (energy-consistent).
                cable[2:4, 0:2] = -RiT @ K
                cable[2:4, 2:4] = RiT @ K @ Ri
            else:
                # The paper's eq. 4: k r^2 (theta_m - R theta), not the transpose of the ankle rows.
                kr2 = p.transmission.cable_stiffness * p.transmission.pulley_radius ** 2
                cable[2:4, 0:2] = -kr2 * kin.R
                cable[2:4, 2:4] = kr2 * np.eye(2)
        Mq = np.diag([p.foot.inertia_dp, p.foot.inertia_ie, p.actuator.inertia, p.actuator.inertia])
        Kq = cable.copy()
        if gravity:
            Kq[0, 0] += p.foot.gravity_gain
        Dq = p.transmission.stiffness_proportional_damping * cable
        Dq[2, 2] += p.actuator.damping
        Dq[3, 3] += p.actuator.damping
        Mi = np.linalg.inv(Mq)
        A = np.zeros((N_X, N_X))
        A[0:4, 4:8] = np.eye(N_Q)
        A[4:8, 0:4] = -Mi @ Kq
        A[4:8, 4:8] = -Mi @ Dq
        B = np.zeros((N_X, N_Q))
        B[4:8, :] = Mi
        return cls(Mq=Mq, Dq=Dq, Kq=Kq, A=A, B=B, kin=kin, cable_Kq=cable)

    def joint_torque_rows(self, beta: float) -> np.ndarray:
        """2x8 output matrix: tau_j = K (phi + beta phi') from the state (paper eq. 10 with damping)."""
        C = np.zeros((2, N_X))
        C[:, 0:4] = -self.cable_Kq[0:2]
        C[:, 4:8] = -beta * self.cable_Kq[0:2]
        return C
