"""Controllers of the control cycle.

Every controller implements :class:`CycleController`: ``reset(est)`` when the amplifiers are
activated, then ``update(est, out_torque)`` once per cycle, writing the two motor torques (N m,
gearbox output) into ``out_torque[0:2]``. The loop converts them to current set values with the
torque constant and lets the safety layer clamp them. Identification experiments plug their own
excitation in through the same protocol.

The controllers the config selects (``controller.type``) are built by :func:`build_controller`:
motor-side PD (:mod:`.pd`) or ankle impedance (:mod:`.impedance`), each with optional friction
feed-forward (:mod:`.friction`), bumpless gain changes and a soft start (:mod:`.gains`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from ankle_rt.estimation import Estimate

if TYPE_CHECKING:
    from ankle_rt.config import Config
    from ankle_rt.kinematics import Kinematics


@runtime_checkable
class CycleController(Protocol):
    def reset(self, est: Estimate) -> None:
        """Called on activation with the current estimate (soft start, integrators, ...)."""

    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        """Write motor torques (N m, gearbox output) into ``out_torque[0:2]``. No allocation."""


def build_controller(cfg: "Config", kin: "Kinematics", ref: np.ndarray) -> CycleController:
    """The controller ``controller.type`` names, tracking the ankle reference ``ref`` (rad [DP, IE],
    a preallocated array the loop refreshes every cycle before calling ``update``)."""
    from ankle_rt.control.friction import FrictionFeedForward
    from ankle_rt.control.impedance import ImpedanceController
    from ankle_rt.control.pd import MotorPD

    c = cfg["controller"]
    dt = 1.0 / c["rate_hz"]
    ff = FrictionFeedForward.from_config(cfg)
    if c["type"] == "impedance":
        return ImpedanceController.from_config(cfg, kin, ref, friction=ff)
    gains = c[c["pd_gains"] + "_gains"]
    return MotorPD(kin, ref, kp=gains["kp"], kd=gains["kd"], dt=dt, ramp_s=c["gain_ramp_s"],
                   soft_start_s=c["soft_start_s"], friction=ff)
