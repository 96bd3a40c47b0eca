"""Ankle impedance control: a stiffness, damping and equilibrium angle per ankle axis.

``tau_ankle = Ks (theta_0 - theta) - Bs dtheta`` uses the joint encoders' angles where the device has
them (``controller.impedance.angle_source``; cable slack and backlash hide from anything else), else
the *estimated* ankle angles ``theta = R^-1 theta_m - K^-1 tau_j`` (so the cables' series compliance
is measured, not added to the commanded compliance), and the rigid-cable ankle rate ``R^-1
dtheta_m``. The equilibrium ``theta_0`` is the loop's ankle reference.

With a :class:`~ankle_rt.control.torque_loop.JointTorqueLoop` (the default when strain gauges are
configured) ``tau_ankle`` is the *desired joint torque*: the loop drives the strain-gauge torque to
it, so friction and reflected inertia between motor and ankle leave the rendered impedance. Without
one (open loop) ``tau_ankle`` is sent as is. Either way the motor torques are ``tau_m = R^-T u`` plus
the per-motor friction feed-forward, which sees the cable torque each motor feels (``R^-T tau_sg``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Mapping

import numpy as np

from ankle_rt.control.friction import FrictionFeedForward
from ankle_rt.control.gains import GainError, RampedGainController
from ankle_rt.control.torque_loop import (ImpedanceLimits, JointTorqueLoop, ReflectedActuator, TorqueLoopGains,
                                         torque_feedback, uses_joint_encoders)
from ankle_rt.elementwise import Value, select
from ankle_rt.estimation import Estimate
from ankle_rt.kinematics import Kinematics

if TYPE_CHECKING:
    from ankle_rt.config import Config


class ImpedanceController(RampedGainController):
    def __init__(self, kin: Kinematics, ref: np.ndarray, gains: Mapping[str, float], *, dt: float,
                 ramp_s: float = 0.0, soft_start_s: float = 0.0, friction: FrictionFeedForward | None = None,
                 torque_loop: JointTorqueLoop | None = None, limits: ImpedanceLimits | None = None,
                 joint_encoders: bool = False):
        """``gains``: stiffness_dp/ie (N m/rad), damping_dp/ie (N m s/rad). ``ref``: rad [DP, IE].
        ``torque_loop``: closes the joint-torque loop on the strain gauges; None: open loop.
        ``joint_encoders``: the stiffness acts on the joint encoders' angles (else the estimated ones).
        ``limits``: gains outside them are refused (GainError), here and in :meth:`set_gains`."""
        if limits is not None:
            self._check(limits, gains)
        super().__init__({k: gains[k] for k in ("stiffness_dp", "stiffness_ie", "damping_dp", "damping_ie")},
                         dt=dt, ramp_s=ramp_s, soft_start_s=soft_start_s, friction=friction)
        self.RiT = kin.R_inv_T.ravel().tolist()
        self.ref = ref
        self.torque_loop = torque_loop
        self.limits = limits
        self.joint_encoders = joint_encoders
        self.lead0, self.lead1 = torque_loop.lag_s if torque_loop is not None else (0.0, 0.0)

    @classmethod
    def from_config(cls, cfg: "Config", kin: Kinematics, ref: np.ndarray,
                    friction: FrictionFeedForward | None) -> "ImpedanceController":
        """``controller.impedance`` with the joint-torque loop when :func:`torque_feedback` says so
        (its limits enforced, the feed-forward's viscous terms left out). Raises ConfigError naming
        a gain outside the limits."""
        from ankle_rt.config import ConfigError

        c = cfg["controller"]
        joint = uses_joint_encoders(cfg)
        if joint and cfg["backend"] != "sim" and cfg["joint_encoders"]["counts_per_rev"] is None:
            raise ConfigError("angle_source joint_encoders needs joint encoders (joint_encoders.counts_per_rev)",
                              getattr(cfg, "source", None), "controller.impedance.angle_source")
        loop, limits, friction = actuation_from_config(cfg, friction)
        try:
            return cls(kin, ref, c["impedance"], dt=1.0 / c["rate_hz"], ramp_s=c["gain_ramp_s"],
                       soft_start_s=c["soft_start_s"], friction=friction, torque_loop=loop, limits=limits,
                       joint_encoders=joint)
        except GainError as exc:
            raise ConfigError(str(exc), getattr(cfg, "source", None), f"controller.impedance.{exc.gain}") from None

    @staticmethod
    def _check(limits: ImpedanceLimits, gains: Mapping[str, float]) -> None:
        bad = limits.check(gains)
        if bad is not None:
            raise GainError(*bad)

    def set_gains(self, **gains: float) -> None:
        """Ramp to new gains; with limits, the resulting set must lie inside them (else GainError)."""
        if self.limits is not None:
            targets = dict(zip(self.gains.names, self.gains.targets))
            targets.update({k: v for k, v in gains.items() if k in targets})
            self._check(self.limits, targets)
        super().set_gains(**gains)

    shared = ("ref", "limits")
    columns = ("RiT",)

    def batch_key(self) -> tuple[tuple[str, bool], ...]:
        return (("controller.impedance.torque_feedback", self.torque_loop is not None),)

    def start(self, est: Estimate, where: bool | np.ndarray = True) -> None:
        super().start(est, where)
        if self.torque_loop is not None:
            self.torque_loop.reset_state(est.sg_dp, est.sg_ie, where)

    def law(self, est: Estimate, ref_dp: Value, ref_ie: Value) -> tuple[Value, Value]:
        g = self.gains
        g.advance()
        k0, k1, b0, b1 = g.values
        joint = self.joint_encoders
        return self.actuate(est, k0 * (ref_dp - select(joint, est.joint_dp, est.dp)) - b0 * est.dp_vel,
                            k1 * (ref_ie - select(joint, est.joint_ie, est.ie)) - b1 * est.ie_vel, k0, k1)

    def actuate(self, est: Estimate, t0: Value, t1: Value, k0: Value, k1: Value) -> tuple[Value, Value]:
        """Motor torques (N m) rendering the desired joint torques ``t0``, ``t1`` (N m [DP, IE]) of a
        law with stiffness ``k0``, ``k1`` (N m/rad): the loop's lag on the spring torque (lag_s) led by
        K lag_s of damping (JointTorqueLoop.lag_s, counted by ImpedanceLimits), the joint-torque loop
        if closed, R^-T, the friction feed-forward, times the soft-start scale (advanced by the law).
        Element-wise; every controller on this actuation (impedance, gait phase) calls it once per cycle."""
        t0 = t0 - k0 * self.lead0 * est.dp_vel
        t1 = t1 - k1 * self.lead1 * est.ie_vel
        s = self.gains.scale
        j0, j1 = est.sg_dp, est.sg_ie
        loop = self.torque_loop
        if loop is not None:
            t0, t1 = loop.update(t0, t1, j0, j1, est.dp_vel, est.ie_vel, s >= 1.0)
        RiT = self.RiT
        ff = self.friction
        return (s * (RiT[0] * t0 + RiT[1] * t1 + ff.torque(est.mv1, RiT[0] * j0 + RiT[1] * j1)),
                s * (RiT[2] * t0 + RiT[3] * t1 + ff.torque(est.mv2, RiT[2] * j0 + RiT[3] * j1)))


def actuation_from_config(cfg: "Config", friction: FrictionFeedForward | None
                          ) -> tuple[JointTorqueLoop | None, ImpedanceLimits | None, FrictionFeedForward | None]:
    """The impedance actuation's pieces from ``cfg``: the joint-torque loop and its stable set when
    :func:`torque_feedback` says so (the feed-forward's viscous terms then left out), else None, None
    and ``friction`` as given."""
    if not torque_feedback(cfg):
        return None, None, friction
    c = cfg["controller"]
    loop = JointTorqueLoop(TorqueLoopGains.from_config(c["torque_loop"]), 1.0 / c["rate_hz"],
                           ReflectedActuator.from_config(cfg))
    return loop, ImpedanceLimits.from_config(cfg), friction.without_viscous() if friction is not None else None
