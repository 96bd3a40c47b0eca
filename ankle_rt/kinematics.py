"""Differential cable kinematics of the paper's eq. 1-2 and the cable stiffness seen at the ankle.

theta_m = R theta, with R = (1/r) [[R_DP, R_IE], [R_DP, -R_IE]]. Motor angles are at the gearbox
output. Torques map with the transpose: ankle torque tau = R^T tau_m for a rigid transmission.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ankle_rt.params import TransmissionParams


def ankle_stiffness(p: TransmissionParams) -> tuple[float, float]:
    """N m/rad [DP, IE]: the cables' stiffness seen at the ankle, 2 k R_DP^2 and k R_IE^2."""
    return 2.0 * p.cable_stiffness * p.lever_dp ** 2, p.cable_stiffness * p.lever_ie ** 2


@dataclass(frozen=True)
class Kinematics:
    """Motor <-> ankle maps for one transmission geometry."""

    R: np.ndarray        # theta_m = R theta
    R_inv: np.ndarray    # theta = R_inv theta_m
    R_inv_T: np.ndarray  # motor torque that balances an ankle torque: tau_m = R_inv_T tau_ankle
    K: np.ndarray        # N m/rad, ankle stiffness diag(2 k R_DP^2, k R_IE^2)
    K_inv: np.ndarray

    def __post_init__(self) -> None:
        """The maps are read-only: one Kinematics is shared by the daemon and every controller it
        builds (a plugin's in-place ``*=`` on its matrices must not change the next controller's)."""
        for matrix in (self.R, self.R_inv, self.R_inv_T, self.K, self.K_inv):
            matrix.flags.writeable = False

    @classmethod
    def from_params(cls, p: TransmissionParams) -> "Kinematics":
        R = motor_ratio(p)
        R_inv = np.linalg.inv(R)
        K = np.diag(ankle_stiffness(p))
        return cls(R=R, R_inv=R_inv, R_inv_T=R_inv.T.copy(), K=K, K_inv=np.linalg.inv(K))

    def motor_from_ankle(self, theta: np.ndarray) -> np.ndarray:
        """rad (or rad/s): motor angles for rigid cables."""
        return self.R @ theta

    def ankle_from_motor(self, theta_m: np.ndarray) -> np.ndarray:
        """rad (or rad/s): ankle angles for rigid cables."""
        return self.R_inv @ theta_m

    def motor_torque_for_ankle_torque(self, tau_ankle: np.ndarray) -> np.ndarray:
        """N m: motor torques whose cable forces produce ``tau_ankle`` at the ankle."""
        return self.R_inv_T @ tau_ankle

    def ankle_torque_from_motor_torque(self, tau_m: np.ndarray) -> np.ndarray:
        """N m: the ankle torque that motor torques ``tau_m`` produce through rigid cables."""
        return self.R.T @ tau_m

    def stretch(self, theta: np.ndarray, theta_m: np.ndarray) -> np.ndarray:
        """rad: cable stretch in ankle coordinates, phi = R^-1 theta_m - theta."""
        return self.R_inv @ theta_m - theta

    def ankle_from_motor_and_torque(self, theta_m: np.ndarray, tau_j: np.ndarray) -> np.ndarray:
        """rad: ankle angles from motor angles and the measured joint torque, theta = R^-1 theta_m - K^-1 tau_j."""
        return self.R_inv @ theta_m - self.K_inv @ tau_j


def motor_ratio(p: TransmissionParams) -> np.ndarray:
    """R (theta_m = R theta) alone: what needs no inversion (the safety layer's gauge check builds
    from it even for parameters whose stiffness matrix would be singular)."""
    return np.array([[p.lever_dp, p.lever_ie], [p.lever_dp, -p.lever_ie]]) / p.pulley_radius
