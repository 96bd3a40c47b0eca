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

Everything is computed in plain floats and written into the preallocated :class:`Estimate`: nothing
is allocated per cycle. The same code runs on arrays over a batch (:mod:`ankle_rt.sweep.cycle`).
"""

from __future__ import annotations

import math
from operator import attrgetter
from typing import Sequence

import numpy as np

from ankle_rt.backend import SensorFrame
from ankle_rt.elementwise import Value, all_true, select, stack
from ankle_rt.kinematics import Kinematics


class _Pair:
    """A (2,) array of two of an :class:`Estimate`'s plain values, refreshed in place when read."""

    def __init__(self, index: int, first: str, second: str):
        self.index, self.first, self.second = index, first, second

    def __get__(self, est: "Estimate | None", owner: type) -> "np.ndarray | _Pair":
        if est is None:
            return self
        out = est._arrays[self.index]
        out[0] = getattr(est, self.first)
        out[1] = getattr(est, self.second)
        return out


class Estimate:
    """The estimated state of one cycle, preallocated once and filled in place.

    Plain values (SI, motor side at the gearbox output), floats for one device and arrays over the
    batch in the batched daemon cycle (:mod:`ankle_rt.elementwise`): what the element-wise cycle
    pieces read.
        t                  s, sample time of the sensor frame
        mp1, mp2           rad, encoder angles of motor 1 and 2
        mv1, mv2           rad/s, motor velocities: backward difference + first-order low-pass
        dp, ie             rad, ankle angles theta = R^-1 theta_m - K^-1 tau_j
        dp_vel, ie_vel     rad/s, R^-1 motor velocity (rigid-cable rate; cable stretch rate neglected)
        sg_dp, sg_ie       N m, tared strain-gauge torques
        joint_dp, joint_ie rad, joint encoders, NaN if the device has none
        tared              True once the strain-gauge offset is known

    The same values as (2,) arrays for controllers written on arrays (plugins, identification):
    ``motor_pos``, ``motor_vel``, ``ankle_pos`` [DP, IE], ``ankle_vel``, ``sg_torque``, ``joint_pos``
    (refreshed in place when read: no allocation, read-only views of the values above).
    """

    __slots__ = ("t", "mp1", "mp2", "mv1", "mv2", "dp", "ie", "dp_vel", "ie_vel", "sg_dp", "sg_ie",
                 "joint_dp", "joint_ie", "tared", "_arrays")

    def __init__(self) -> None:
        self.t = 0.0
        self.mp1 = self.mp2 = self.mv1 = self.mv2 = 0.0
        self.dp = self.ie = self.dp_vel = self.ie_vel = self.sg_dp = self.sg_ie = 0.0
        self.joint_dp = self.joint_ie = math.nan
        self.tared = False
        self._arrays = [np.zeros(2) for _ in range(6)]

    motor_pos = _Pair(0, "mp1", "mp2")
    motor_vel = _Pair(1, "mv1", "mv2")
    ankle_pos = _Pair(2, "dp", "ie")
    ankle_vel = _Pair(3, "dp_vel", "ie_vel")
    sg_torque = _Pair(4, "sg_dp", "sg_ie")
    joint_pos = _Pair(5, "joint_dp", "joint_ie")


class EstimateView:
    """What a controller plugin is handed instead of the daemon's :class:`Estimate`: every value read
    through to it, none writable (AttributeError naming the value). A plugin runs between the sensor
    checks and the strain-gauge cross-check of the same cycle, which must see the sensors' values, as
    the log must; a plugin's ``est.sg_dp = filtered`` would have replaced them. No allocation per read."""

    __slots__ = ("_est",)

    def __init__(self, est: Estimate):
        object.__setattr__(self, "_est", est)

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError(f"the estimate is read-only for controllers ({name!r}): the safety checks and the "
                             f"log read it after the controller; keep a filtered value in the controller")


for _name in (*(n for n in Estimate.__slots__ if n != "_arrays"), *(n for n, v in vars(Estimate).items()
                                                                       if isinstance(v, _Pair))):
    setattr(EstimateView, _name, property(attrgetter(f"_est.{_name}")))
del _name


class Estimator:
    """Fills an :class:`Estimate` from each sensor sample (see the module docstring).

    Written element-wise (:mod:`ankle_rt.elementwise`): :meth:`estimate` runs on floats for one
    device and, on a :meth:`stack`, on arrays over a batch of devices sampled at the same times."""

    def __init__(self, kin: Kinematics, dt: float, velocity_cutoff_hz: float, tare_samples: int):
        """``dt`` s is the nominal period (used for the filter constant); ``tare_samples`` >= 1
        (else ValueError)."""
        if not tare_samples >= 1:
            raise ValueError(f"tare_samples must be >= 1, got {tare_samples!r}")
        self.Ri = list(kin.R_inv.ravel().tolist())
        self.Ki0, self.Ki1 = float(kin.K_inv[0, 0]), float(kin.K_inv[1, 1])
        self.dt = dt
        self.alpha = 1.0 - math.exp(-2.0 * math.pi * velocity_cutoff_hz * dt)
        self.tare_samples = tare_samples
        self.reset()

    @classmethod
    def stack(cls, estimators: Sequence["Estimator"]) -> "Estimator":
        """One estimator standing for ``estimators`` (one per device of a batch), numbers as arrays
        but the last sample time (the batch's devices are sampled together)."""
        return stack(estimators, shared=("_t",), columns=("Ri", "offset"))

    def reset(self) -> None:
        """Forget the filter state and the tare (the next samples are averaged again)."""
        self._t = math.nan
        self._p1 = self._p2 = 0.0
        self._v1 = self._v2 = 0.0
        self._n = 0
        self.taring = True          # some device still averages its tare
        self._sum0 = self._sum1 = 0.0
        self.offset = [0.0, 0.0]    # N m [DP, IE], the tare

    def update(self, frame: SensorFrame, est: Estimate) -> None:
        """Estimate from ``frame`` into ``est`` (no allocation)."""
        v = frame.values
        self.estimate(frame.t, v[0], v[1], v[2], v[3], v[4], v[5], est)

    def estimate(self, t: float, p1: Value, p2: Value, s0: Value, s1: Value, j0: Value, j1: Value,
                 est: Estimate) -> None:
        """Estimate into ``est`` from one sample: time ``t`` s (one for the whole batch), motor angles
        rad, raw strain-gauge torques N m [DP, IE], joint encoders rad (NaN: none). Element-wise."""
        h = t - self._t
        if h > 0.0:          # NaN on the first sample; a repeated (stale) sample keeps the velocity
            a = self.alpha
            self._v1 += a * ((p1 - self._p1) / h - self._v1)
            self._v2 += a * ((p2 - self._p2) / h - self._v2)
        self._t, self._p1, self._p2 = t, p1, p2

        if self.taring:
            n = self._n
            adding = n < self.tare_samples
            self._sum0 = self._sum0 + select(adding, s0, 0.0)
            self._sum1 = self._sum1 + select(adding, s1, 0.0)
            n = self._n = n + select(adding, 1, 0)
            self.offset[0] = self._sum0 / n
            self.offset[1] = self._sum1 / n
            est.tared = tared = n >= self.tare_samples
            self.taring = not all_true(tared)
        s0 -= self.offset[0]
        s1 -= self.offset[1]

        r0, r1, r2, r3 = self.Ri
        v1, v2 = self._v1, self._v2
        est.t = t
        est.mp1, est.mp2, est.mv1, est.mv2 = p1, p2, v1, v2
        est.sg_dp, est.sg_ie = s0, s1
        est.dp = r0 * p1 + r1 * p2 - self.Ki0 * s0
        est.ie = r2 * p1 + r3 * p2 - self.Ki1 * s1
        est.dp_vel = r0 * v1 + r1 * v2
        est.ie_vel = r2 * v1 + r3 * v2
        est.joint_dp, est.joint_ie = j0, j1
