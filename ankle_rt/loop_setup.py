"""What the impedance controller's loop is made of, read from the config: whether it closes the
joint-torque loop (:func:`torque_feedback`), which ankle angle its law uses
(:func:`uses_joint_encoders`) and the motor side seen at the ankle (:class:`ReflectedActuator`).
Outside :mod:`ankle_rt.control` so the config loader and :mod:`ankle_rt.analysis` (the loop's linear
model) use them without an import circle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping


def torque_feedback(cfg: Mapping[str, Any]) -> bool:
    """Whether the impedance controller closes the joint-torque loop: ``controller.impedance.
    torque_feedback`` on/off, or auto = when strain gauges are configured (the simulator's always
    are; on hardware ``strain_gauges.matrix`` is given)."""
    mode = cfg["controller"]["impedance"]["torque_feedback"]
    if mode != "auto":
        return mode == "on"
    return cfg["backend"] == "sim" or cfg["strain_gauges"]["matrix"] is not None


def uses_joint_encoders(cfg: Mapping[str, Any]) -> bool:
    """Whether the impedance law takes the ankle angle from joint encoders: ``controller.impedance.
    angle_source`` joint_encoders/estimated, or auto = when joint encoders are configured (the
    simulator's always are: the true joint angle; on hardware ``joint_encoders.counts_per_rev``)."""
    mode = cfg["controller"]["impedance"]["angle_source"]
    if mode != "auto":
        return mode == "joint_encoders"
    return has_joint_encoders(cfg)


def has_joint_encoders(cfg: Mapping[str, Any]) -> bool:
    """Whether the device reads its ankle angles: the simulator always does (the true joint angles, quantised),
    the serial bridge with ``joint_encoders.counts_per_rev``; the CANopen backend reads none."""
    backend = cfg["backend"]
    return backend == "sim" or (backend != "canopen" and cfg["joint_encoders"]["counts_per_rev"] is not None)


def reads_joint_encoders(cfg: Mapping[str, Any]) -> bool:
    """Whether the configured controller acts on the joint encoders: the impedance law's angle
    (:func:`uses_joint_encoders`) or the joint-torque loop's rate (``torque_rate_source: encoders``) of the
    impedance or gait-phase controller; what the safety layer cross-checks them for (the motor PD and a
    plugin leave them to the range check)."""
    c = cfg["controller"]
    if c["type"] not in ("impedance", "gait_phase") or not has_joint_encoders(cfg):
        return False
    return (c["type"] == "impedance" and uses_joint_encoders(cfg)) or (torque_feedback(cfg) and
                                                                        rate_from_encoders(c["torque_loop"]))


SIM_JOINT_COUNTS_PER_REV = 2 ** 19   # the simulator's joint encoders unless configured: the bench's (19 bit, 12 urad)


def joint_encoder_counts(cfg: Mapping[str, Any]) -> int:
    """Counts per revolution of the joint encoders: ``joint_encoders.counts_per_rev``, unset the bench's 19 bit
    (what the simulated plant reads; whether the device has any: :func:`has_joint_encoders`)."""
    return cfg["joint_encoders"]["counts_per_rev"] or SIM_JOINT_COUNTS_PER_REV


def rate_from_encoders(torque_loop: Mapping[str, Any]) -> bool:
    """Whether the joint-torque loop (``controller.torque_loop``) differentiates the cables' stretch torque in
    its rate terms (motor and joint encoders, ``torque_rate_source: encoders``) rather than the strain gauges'."""
    return torque_loop["torque_rate_source"] == "encoders"


@dataclass(frozen=True)
class ReflectedActuator:
    """The motor side seen at the ankle, per axis [DP, IE]: the diagonal of R^T J R, R^T D R and the
    Coulomb friction kc (|R| column norm): what the observer's nominal inertia and the tank's credit
    are built from."""

    inertia: tuple[float, float]     # kg m^2
    viscous: tuple[float, float]     # N m s/rad
    coulomb: tuple[float, float]     # N m

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> "ReflectedActuator":
        from ankle_rt.kinematics import Kinematics
        from ankle_rt.params import TransmissionParams

        kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
        col = [float(kin.R[0, a] ** 2 + kin.R[1, a] ** 2) for a in (0, 1)]
        a = cfg["actuator"]
        return cls(inertia=(a["inertia"] * col[0], a["inertia"] * col[1]),
                   viscous=(a["damping"] * col[0], a["damping"] * col[1]),
                   coulomb=(a["coulomb"] * math.sqrt(col[0]), a["coulomb"] * math.sqrt(col[1])))
