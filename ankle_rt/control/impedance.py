"""Ankle impedance control: a stiffness, damping and equilibrium angle per ankle axis.

``tau_ankle = Ks (theta_0 - theta) - Bs dtheta`` uses the *estimated* ankle angles
``theta = R^-1 theta_m - K^-1 tau_j`` (so the cables' series compliance is measured, not added to the
commanded compliance) and the rigid-cable ankle rate ``R^-1 dtheta_m``. The equilibrium ``theta_0``
is the loop's ankle reference.

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
from ankle_rt.control.torque_loop import ImpedanceLimits, JointTorqueLoop, TorqueLoopGains, torque_feedback
from ankle_rt.estimation import Estimate
from ankle_rt.kinematics import Kinematics

if TYPE_CHECKING:
    from ankle_rt.config import Config


class ImpedanceController(RampedGainController):
    def __init__(self, kin: Kinematics, ref: np.ndarray, gains: Mapping[str, float], *, dt: float,
                 ramp_s: float = 0.0, soft_start_s: float = 0.0, friction: FrictionFeedForward | None = None,
                 torque_loop: JointTorqueLoop | None = None, limits: ImpedanceLimits | None = None):
        """``gains``: stiffness_dp/ie (N m/rad), damping_dp/ie (N m s/rad). ``ref``: rad [DP, IE].
        ``torque_loop``: closes the joint-torque loop on the strain gauges; None: open loop.
        ``limits``: gains outside them are refused (GainError), here and in :meth:`set_gains`."""
        if limits is not None:
            self._check(limits, gains)
        super().__init__({k: gains[k] for k in ("stiffness_dp", "stiffness_ie", "damping_dp", "damping_ie")},
                         dt=dt, ramp_s=ramp_s, soft_start_s=soft_start_s, friction=friction)
        self.RiT = kin.R_inv_T.ravel().tolist()
        self.ref = ref
        self.torque_loop = torque_loop
        self.limits = limits

    @classmethod
    def from_config(cls, cfg: "Config", kin: Kinematics, ref: np.ndarray,
                    friction: FrictionFeedForward | None) -> "ImpedanceController":
        """``controller.impedance`` with the joint-torque loop when :func:`torque_feedback` says so
        (its limits enforced, the feed-forward's viscous terms left out). Raises ConfigError naming
        a gain outside the limits."""
        from ankle_rt.config import ConfigError

        c = cfg["controller"]
        dt = 1.0 / c["rate_hz"]
        loop = limits = None
        if torque_feedback(cfg):
            loop = JointTorqueLoop(TorqueLoopGains.from_config(c["torque_loop"]), dt)
            limits = ImpedanceLimits.from_config(cfg)
            friction = friction.without_viscous() if friction is not None else None
        try:
            return cls(kin, ref, c["impedance"], dt=dt, ramp_s=c["gain_ramp_s"], soft_start_s=c["soft_start_s"],
                       friction=friction, torque_loop=loop, limits=limits)
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

    def reset(self, est: Estimate) -> None:
        super().reset(est)
        if self.torque_loop is not None:
            self.torque_loop.reset_state(est.sg_torque.item(0), est.sg_torque.item(1))

    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        g = self.gains
        g.advance()
        k0, k1, b0, b1 = g.values
        ref, pos, vel = self.ref, est.ankle_pos, est.ankle_vel
        self.actuate(k0 * (ref.item(0) - pos.item(0)) - b0 * vel.item(0),
                     k1 * (ref.item(1) - pos.item(1)) - b1 * vel.item(1), est, out_torque)

    def actuate(self, t0: float, t1: float, est: Estimate, out_torque: np.ndarray) -> None:
        """Desired joint torques (N m) to motor torques: through the joint-torque loop if closed,
        mapped with R^-T, plus the friction feed-forward, times the soft-start scale."""
        s = self.gains.scale
        sg = est.sg_torque
        j0, j1 = sg.item(0), sg.item(1)
        loop = self.torque_loop
        if loop is not None:
            t0, t1 = loop.update(t0, t1, j0, j1, s >= 1.0)
        RiT = self.RiT
        ff = self.friction
        out_torque[0] = s * (RiT[0] * t0 + RiT[1] * t1
                             + ff.torque(est.motor_vel.item(0), RiT[0] * j0 + RiT[1] * j1))
        out_torque[1] = s * (RiT[2] * t0 + RiT[3] * t1
                             + ff.torque(est.motor_vel.item(1), RiT[2] * j0 + RiT[3] * j1))
