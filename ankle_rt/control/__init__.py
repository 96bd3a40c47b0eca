"""Controllers of the control cycle.

Every controller implements :class:`CycleController`: ``reset(est)`` when the amplifiers are
activated, then ``update(est, out_torque)`` once per cycle, writing the two motor torques (N m,
gearbox output) into ``out_torque[0:2]``. The loop converts them to current set values with the
torque constant and lets the safety layer clamp them. Identification experiments plug their own
excitation in through the same protocol.

The controller the config selects (``controller.type``) is built by :func:`build_controller` from
its name (:mod:`ankle_rt.controller_registry`): the built-ins, motor-side PD (:mod:`.pd`) or ankle impedance
(:mod:`.impedance`), each with optional friction feed-forward (:mod:`.friction`), bumpless gain
changes and a soft start (:mod:`.gains`); or an installed plugin, a :class:`.base.Controller`
subclass registered under the entry-point group ``ankle_rt.controllers``. The safety layer sits
after every one of them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from ankle_rt.estimation import Estimate

if TYPE_CHECKING:
    from ankle_rt.config import Config
    from ankle_rt.control.base import ControllerContext
    from ankle_rt.kinematics import Kinematics


@runtime_checkable
class CycleController(Protocol):
    def reset(self, est: Estimate) -> None:
        """Called on activation with the current estimate (soft start, integrators, ...)."""

    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        """Write motor torques (N m, gearbox output) into ``out_torque[0:2]``. No allocation."""


def build_controller(cfg: "Config", kin: "Kinematics", ref: np.ndarray) -> CycleController:
    """The controller ``controller.type`` names, tracking the ankle reference ``ref`` (rad [DP, IE],
    a preallocated array the loop refreshes every cycle before calling ``update``). A bad plugin or
    bad ``controller.params`` raise ConfigError naming the key."""
    from ankle_rt.config import ConfigError
    from ankle_rt.control.base import ControllerContext
    from ankle_rt.controller_registry import ControllerNotFound, load_controller_factory

    name = cfg["controller"]["type"]
    source = getattr(cfg, "source", "")
    try:
        factory = load_controller_factory(name)
    except ControllerNotFound as exc:
        raise ConfigError(str(exc), source, "controller.type") from None
    try:
        controller = factory(ControllerContext.from_config(cfg, kin, ref))
    except ConfigError:
        raise
    except (ValueError, TypeError, KeyError) as exc:
        raise ConfigError(f"controller {name!r}: {exc}", source, "controller.params") from None
    except (Exception, SystemExit) as exc:   # a plugin's own error (even sys.exit) while building: a message
        raise ConfigError(f"controller {name!r} failed to build: {type(exc).__name__}: {exc}", source,
                          "controller.type") from None
    if not isinstance(controller, CycleController):
        raise ConfigError(f"controller {name!r} built a {type(controller).__name__}, which has no "
                          "reset(est) and update(est, out_torque)", source, "controller.type")
    return controller


def _no_params(ctx: "ControllerContext", name: str, where: str) -> None:
    """Built-ins take their settings from their own sections: plugin parameters would be ignored."""
    if ctx.params:
        raise ValueError(f"the built-in controller {name!r} takes no params (its gains are in {where}); "
                         f"got {', '.join(sorted(ctx.params))}")


def pd_controller(ctx: "ControllerContext") -> CycleController:
    """The built-in ``pd``: motor-side PD on the ``controller.pd_gains`` gain set, refused (naming the
    gain) when it keeps less than the required gain margin."""
    from ankle_rt.config import ConfigError
    from ankle_rt.control.gains import GainError
    from ankle_rt.control.pd import MotorPD

    _no_params(ctx, "pd", "controller.step_gains / validation_gains")
    c = ctx.cfg["controller"]
    section = c["pd_gains"] + "_gains"
    gains = c[section]
    try:
        return MotorPD(ctx.kin, ctx.ref, kp=gains["kp"], kd=gains["kd"], dt=ctx.dt, ramp_s=c["gain_ramp_s"],
                       soft_start_s=c["soft_start_s"], friction=ctx.friction, margin_cfg=ctx.cfg)
    except GainError as exc:
        raise ConfigError(str(exc), getattr(ctx.cfg, "source", None), f"controller.{section}.{exc.gain}") from None


def impedance_controller(ctx: "ControllerContext") -> CycleController:
    """The built-in ``impedance``: ankle stiffness and damping, ``controller.impedance``."""
    from ankle_rt.control.impedance import ImpedanceController

    _no_params(ctx, "impedance", "controller.impedance")
    return ImpedanceController.from_config(ctx.cfg, ctx.kin, ctx.ref, friction=ctx.friction)


def gait_phase_controller(ctx: "ControllerContext") -> CycleController:
    """The built-in ``gait_phase``: finite-state impedance over the stride, ``controller.gait_phase``."""
    from ankle_rt.control.gait_phase import GaitPhaseController

    _no_params(ctx, "gait_phase", "controller.gait_phase")
    return GaitPhaseController.from_config(ctx.cfg, ctx.kin, ctx.ref, friction=ctx.friction)
