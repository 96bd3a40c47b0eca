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

import math
from typing import TYPE_CHECKING, Mapping

import numpy as np

from ankle_rt.control.friction import FrictionFeedForward
from ankle_rt.control.gains import GainError, RampedGainController
from ankle_rt.control.torque_loop import ImpedanceLimits, JointTorqueLoop, TorqueLoopGains, correction_room
from ankle_rt.config_schema import IMPEDANCE_GAINS, LOOP_GAINS
from ankle_rt.elementwise import Value, any_true, minimum, select
from ankle_rt.estimation import Estimate
from ankle_rt.joint_blend import blended_angle, crossover_alpha, law_crossover_hz
from ankle_rt.kinematics import Kinematics
from ankle_rt.lead import law_damping
from ankle_rt.loop_setup import (ReflectedActuator, has_joint_encoders, rate_from_encoders, torque_feedback,
                                 uses_joint_encoders)

if TYPE_CHECKING:
    from ankle_rt.config import Config


RUNTIME_LOOP_GAINS = LOOP_GAINS[:6]    # kp, ki, torque_rate [DP, IE]: the torque loop's gains set_gains ramps


class ImpedanceController(RampedGainController):
    def __init__(self, kin: Kinematics, ref: np.ndarray, gains: Mapping[str, float], *, dt: float,
                 ramp_s: float = 0.0, soft_start_s: float = 0.0, friction: FrictionFeedForward | None = None,
                 torque_loop: JointTorqueLoop | None = None, limits: ImpedanceLimits | None = None,
                 joint_encoders: bool = False, joint_crossover_hz: float = 0.0, margin_cfg: Mapping | None = None):
        """``gains``: stiffness_dp/ie (N m/rad), damping_dp/ie (N m s/rad). ``ref``: rad [DP, IE].
        ``torque_loop``: closes the joint-torque loop on the strain gauges; None: open loop.
        ``joint_encoders``: the stiffness acts on the joint encoders' angles (else the estimated ones), below
        ``joint_crossover_hz`` (above it on the estimate: :mod:`ankle_rt.joint_blend`; 0: at every frequency).
        ``limits``: gains outside them are refused (GainError), here and in :meth:`set_gains`.
        ``margin_cfg``: the config whose plant and torque-loop gains every gain set (and every point of
        a ramp) must keep the required gain margin with (:func:`gain_set_refusal`); None: not checked."""
        ramped = {k: gains[k] for k in IMPEDANCE_GAINS}
        if torque_loop is not None:   # the loop's gains ramp too (set_gains), from the configured ones
            g = torque_loop.gains
            ramped.update(zip(RUNTIME_LOOP_GAINS, (*g.kp, *g.ki, *g.torque_rate)))
        super().__init__(ramped, dt=dt, ramp_s=ramp_s, soft_start_s=soft_start_s, friction=friction,
                         limits=limits, margin_cfg=margin_cfg)
        self.RiT = kin.R_inv_T.ravel().tolist()
        self.ref = ref
        self.torque_loop = torque_loop
        self.joint_encoders = joint_encoders
        self.joint_alpha = crossover_alpha(law_crossover_hz(joint_crossover_hz, torque_loop is not None), dt)
        self.jl0 = self.jl1 = 0.0      # rad [DP, IE]: the joint encoders' low-passed lead over the estimate
        self.lead0, self.lead1 = torque_loop.lag_s if torque_loop is not None else (0.0, 0.0)
        # the cable at the ankle the law's damping is scaled for (ankle_rt.lead); open loop: none
        self.cable0, self.cable1 = ((float(kin.K[0, 0]), float(kin.K[1, 1])) if torque_loop is not None
                                    else (math.inf, math.inf))

    @classmethod
    def from_config(cls, cfg: "Config", kin: Kinematics, ref: np.ndarray,
                    friction: FrictionFeedForward | None) -> "ImpedanceController":
        """``controller.impedance`` with the joint-torque loop when :func:`torque_feedback` says so
        (its limits enforced, the feed-forward's viscous terms left out). Raises ConfigError naming
        a gain outside the limits."""
        from ankle_rt.config import ConfigError

        c = cfg["controller"]
        joint = uses_joint_encoders(cfg)
        if joint and not has_joint_encoders(cfg):
            raise ConfigError("angle_source joint_encoders needs joint encoders (joint_encoders.counts_per_rev)",
                              getattr(cfg, "source", None), "controller.impedance.angle_source")
        loop, limits, friction = actuation_from_config(cfg, friction)
        try:
            return cls(kin, ref, c["impedance"], dt=1.0 / c["rate_hz"], ramp_s=c["gain_ramp_s"],
                       soft_start_s=c["soft_start_s"], friction=friction, torque_loop=loop, limits=limits,
                       joint_encoders=joint, joint_crossover_hz=c["impedance"]["joint_crossover_hz"], margin_cfg=cfg)
        except GainError as exc:
            section = "torque_loop" if exc.gain in c["torque_loop"] else "impedance"
            raise ConfigError(str(exc), getattr(cfg, "source", None), f"controller.{section}.{exc.gain}") from None

    columns = ("RiT",)

    def batch_key(self) -> tuple[tuple[str, bool], ...]:
        return (("controller.impedance.torque_feedback", self.torque_loop is not None),)

    def start(self, est: Estimate, where: bool | np.ndarray = True) -> None:
        super().start(est, where)
        # the law starts on the joint encoders' angle (what angles() gave the hold)
        self.jl0 = select(where, est.joint_dp - est.dp, self.jl0)
        self.jl1 = select(where, est.joint_ie - est.ie, self.jl1)
        if self.torque_loop is not None:
            st0, st1 = self.stretch_torques(est)
            self.torque_loop.reset_state(est.sg_dp, est.sg_ie, est.dp_vel, est.ie_vel, where, st0, st1)

    def stretch_torques(self, est: Estimate) -> tuple[Value, Value]:
        """N m [DP, IE]: the cables' stretch K (R^-1 theta_m - theta_joint) on the configured cable, what the
        loop's rate terms differentiate with ``torque_rate_source: encoders``; 0 without that source."""
        if self.torque_loop is None or self.torque_loop.encoder_rate is False:
            return 0.0, 0.0
        return (est.sg_dp + self.cable0 * (est.dp - est.joint_dp), est.sg_ie + self.cable1 * (est.ie - est.joint_ie))

    def law(self, est: Estimate, ref_dp: Value, ref_ie: Value) -> tuple[Value, Value]:
        g = self.gains
        ramping = g.ramping
        g.advance()
        v = g.values
        k0, k1, b0, b1 = v[0], v[1], v[2], v[3]
        loop = self.torque_loop
        if ramping and loop is not None:      # the loop's gains ramp too, and the lead on its lag with them
            loop.set_gains(v[4], v[5], v[6], v[7], v[8], v[9])
            self.lead0, self.lead1 = loop.lag_s
        a0, a1 = self.law_angles(est)
        return self.actuate(est, k0 * (ref_dp - a0) - b0 * est.dp_vel, k1 * (ref_ie - a1) - b1 * est.ie_vel,
                            k0, k1, b0, b1)

    def angles(self, est: Estimate) -> tuple[Value, Value]:
        """The joint encoders' angles when ``joint_encoders`` (angle_source), else the estimate: where the
        law holds the ankle at rest (its fast part, above the crossover, on the estimate: :meth:`law_angles`)."""
        joint = self.joint_encoders
        return select(joint, est.joint_dp, est.dp), select(joint, est.joint_ie, est.ie)

    def law_angles(self, est: Estimate) -> tuple[Value, Value]:
        """The law's angles this cycle (advances the crossover's state): with ``joint_encoders``, theirs below
        the crossover and the estimate above (:func:`ankle_rt.joint_blend.blended_angle`), else the estimate."""
        joint = self.joint_encoders
        if joint is False:
            return est.dp, est.ie
        a0, self.jl0 = blended_angle(est.dp, est.joint_dp, self.jl0, self.joint_alpha)
        a1, self.jl1 = blended_angle(est.ie, est.joint_ie, self.jl1, self.joint_alpha)
        return select(joint, a0, est.dp), select(joint, a1, est.ie)

    def actuate(self, est: Estimate, t0: Value, t1: Value, k0: Value, k1: Value, b0: Value, b1: Value
                ) -> tuple[Value, Value]:
        """Motor torques (N m) rendering the desired joint torques ``t0``, ``t1`` (N m [DP, IE]) of a
        law with stiffness ``k0``, ``k1`` (N m/rad) and damping ``b0``, ``b1`` (N m s/rad): under the
        loop the law's damping becomes :func:`ankle_rt.lead.law_damping`'s (it leads the loop's lag on
        the spring torque and makes up for the cable's share of the motor's motion, so the ankle renders
        ``b0``, ``b1``), the joint-torque loop if closed, R^-T, the friction
        feed-forward (its direction also from the loop's error where ``friction_ff.error_band`` says
        so), times the soft-start scale (advanced by the law). Element-wise; every controller on this
        actuation (impedance, gait phase) calls it once per cycle."""
        t0 = t0 - (law_damping(k0, b0, self.lead0, self.cable0) - b0) * est.dp_vel
        t1 = t1 - (law_damping(k1, b1, self.lead1, self.cable1) - b1) * est.ie_vel
        s = self.gains.scale
        j0, j1 = est.sg_dp, est.sg_ie
        loop = self.torque_loop
        e0 = e1 = 0.0
        if loop is not None:
            d0, d1 = t0, t1
            st0, st1 = self.stretch_torques(est)
            t0, t1 = loop.update(t0, t1, j0, j1, est.dp_vel, est.ie_vel, s >= 1.0, st0, st1)
            e0, e1 = d0 - loop.f0, d1 - loop.f1     # the loop's error, for the feed-forward's direction
        RiT = self.RiT
        ff = self.friction
        f1 = ff.torque(est.mv1, RiT[0] * j0 + RiT[1] * j1, RiT[0] * e0 + RiT[1] * e1)
        f2 = ff.torque(est.mv2, RiT[2] * j0 + RiT[3] * j1, RiT[2] * e0 + RiT[3] * e1)
        m1, m2 = RiT[0] * t0 + RiT[1] * t1 + f1, RiT[2] * t0 + RiT[3] * t1 + f2
        if loop is not None:   # the desired torque first: the corrections get what the peak current leaves
            c0, c1, limit = loop.c0, loop.c1, loop.motor_limit
            room = minimum(correction_room(m1, RiT[0] * c0 + RiT[1] * c1, limit),
                           correction_room(m2, RiT[2] * c0 + RiT[3] * c1, limit))
            if any_true(room < 1.0):
                t0, t1 = loop.fit(room)
                m1, m2 = RiT[0] * t0 + RiT[1] * t1 + f1, RiT[2] * t0 + RiT[3] * t1 + f2
        return s * m1, s * m2


def actuation_from_config(cfg: "Config", friction: FrictionFeedForward | None
                          ) -> tuple[JointTorqueLoop | None, ImpedanceLimits | None, FrictionFeedForward | None]:
    """The impedance actuation's pieces from ``cfg``: the joint-torque loop and its stable set when
    :func:`torque_feedback` says so (the feed-forward's viscous terms then left out), else None, None
    and ``friction`` as given. Raises ConfigError naming ``torque_rate_source`` for a rate on joint encoders
    the device does not have (every controller on this actuation: impedance, gait phase)."""
    from ankle_rt.config import ConfigError

    if not torque_feedback(cfg):
        return None, None, friction
    if rate_from_encoders(cfg["controller"]["torque_loop"]) and not has_joint_encoders(cfg):
        raise ConfigError("torque_rate_source encoders needs joint encoders (joint_encoders.counts_per_rev on the "
                          "serial bridge; the simulator has them, the CANopen backend does not): without them include "
                          "config/torque-loop-gauges.yaml after sim.yaml, as hw-*.yaml do",
                          getattr(cfg, "source", None), "controller.torque_loop.torque_rate_source")
    c = cfg["controller"]
    loop = JointTorqueLoop(TorqueLoopGains.from_config(c["torque_loop"], cfg["transmission"]["cable_stiffness"]),
                           1.0 / c["rate_hz"], ReflectedActuator.from_config(cfg),
                           cfg["actuator"]["torque_constant"] * cfg["amplifier"]["current_limit_peak"])
    return loop, ImpedanceLimits.from_config(cfg), friction.without_viscous() if friction is not None else None
