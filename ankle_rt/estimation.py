"""State estimation for the control cycle: motor velocity, strain-gauge tare and ankle angles.

- Motor velocity (rad/s, gearbox output): backward difference of the quantised encoder angles over
  the sample-time step, then a first-order low-pass at ``estimation.velocity_cutoff_hz``
  (discretised exactly: ``v += a (v_raw - v)``, ``a = 1 - exp(-2 pi fc dt)``). One encoder count per
  1 ms cycle is 0.054 rad/s of raw velocity; the low-pass turns that staircase into a usable signal
  for the derivative gain at a phase lag of ``atan(f / fc)``.
- Strain-gauge tare: the mean of the first ``estimation.tare_samples`` samples, taken while the
  amplifiers are still off (foot unloaded), is subtracted from every later sample.
- Ankle angles from the motors and the cable stretch: ``theta = R^-1 theta_m - K^-1 tau_j`` with the
  tared strain-gauge torques (the paper's eq. 10 solved for theta).

Everything is computed in plain floats and written into the preallocated :class:`Estimate` arrays:
nothing is allocated per cycle.
"""

from __future__ import annotations

import math

import numpy as np

from ankle_rt.backend import SensorFrame
from ankle_rt.kinematics import Kinematics


class Estimate:
    """The estimated state of one cycle, preallocated once and filled in place.

    Attributes (SI, motor side at the gearbox output):
        t          s, sample time of the sensor frame
        motor_pos  rad (2,), encoder angles
        motor_vel  rad/s (2,), backward difference + first-order low-pass (see module docstring)
        ankle_pos  rad (2,) [DP, IE], theta = R^-1 theta_m - K^-1 tau_j
        ankle_vel  rad/s (2,) [DP, IE], R^-1 motor_vel (rigid-cable rate; cable stretch rate neglected)
        sg_torque  N m (2,) [DP, IE], tared strain-gauge torques
        joint_pos  rad (2,) [DP, IE] from joint encoders, NaN if the device has none
        tared      True once the strain-gauge offset is known
    """

    __slots__ = ("t", "motor_pos", "motor_vel", "ankle_pos", "ankle_vel", "sg_torque", "joint_pos", "tared")

    def __init__(self) -> None:
        self.t = 0.0
        self.motor_pos = np.zeros(2)
        self.motor_vel = np.zeros(2)
        self.ankle_pos = np.zeros(2)
        self.ankle_vel = np.zeros(2)
        self.sg_torque = np.zeros(2)
        self.joint_pos = np.full(2, np.nan)
        self.tared = False


class Estimator:
    """Fills an :class:`Estimate` from each :class:`SensorFrame` (see the module docstring)."""

    def __init__(self, kin: Kinematics, dt: float, velocity_cutoff_hz: float, tare_samples: int):
        """``dt`` s is the nominal period (used for the filter constant); ``tare_samples`` >= 1."""
        self.Ri = tuple(kin.R_inv.ravel().tolist())
        self.Ki0, self.Ki1 = float(kin.K_inv[0, 0]), float(kin.K_inv[1, 1])
        self.dt = dt
        self.alpha = 1.0 - math.exp(-2.0 * math.pi * velocity_cutoff_hz * dt)
        self.tare_samples = tare_samples
        self.reset()

    def reset(self) -> None:
        """Forget the filter state and the tare (the next samples are averaged again)."""
        self._t = math.nan
        self._p1 = self._p2 = 0.0
        self._v1 = self._v2 = 0.0
        self._n = 0
        self._sum0 = self._sum1 = 0.0
        self.offset = [0.0, 0.0]   # N m [DP, IE], the tare

    def update(self, frame: SensorFrame, est: Estimate) -> None:
        """Estimate from ``frame`` into ``est`` (no allocation)."""
        t = frame.t
        mp, sg = frame.motor_pos, frame.sg_torque
        p1, p2, s0, s1 = mp.item(0), mp.item(1), sg.item(0), sg.item(1)
        h = t - self._t
        if h > 0.0:          # NaN on the first sample; a repeated (stale) sample keeps the velocity
            a = self.alpha
            self._v1 += a * ((p1 - self._p1) / h - self._v1)
            self._v2 += a * ((p2 - self._p2) / h - self._v2)
        self._t, self._p1, self._p2 = t, p1, p2

        n = self._n
        if n < self.tare_samples:
            self._sum0 += s0
            self._sum1 += s1
            n += 1
            self._n = n
            self.offset[0] = self._sum0 / n
            self.offset[1] = self._sum1 / n
            est.tared = n >= self.tare_samples
        s0 -= self.offset[0]
        s1 -= self.offset[1]

        r0, r1, r2, r3 = self.Ri
        v1, v2 = self._v1, self._v2
        est.t = t
        a = est.motor_pos
        a[0] = p1
        a[1] = p2
        a = est.motor_vel
        a[0] = v1
        a[1] = v2
        a = est.sg_torque
        a[0] = s0
        a[1] = s1
        a = est.ankle_pos
        a[0] = r0 * p1 + r1 * p2 - self.Ki0 * s0
        a[1] = r2 * p1 + r3 * p2 - self.Ki1 * s1
        a = est.ankle_vel
        a[0] = r0 * v1 + r1 * v2
        a[1] = r2 * v1 + r3 * v2
        a, j = est.joint_pos, frame.ankle_pos
        a[0] = j[0]
        a[1] = j[1]
