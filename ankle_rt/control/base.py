"""The base class of controllers, built-in and plugged in (see :mod:`ankle_rt.controller_registry`).

A controller is one step of the fixed-rate cycle::

    backend.read -> estimate -> reference -> controller.update -> safety -> backend.write

**Inputs**, every cycle: the :class:`~ankle_rt.estimation.Estimate` ``est`` (SI, motor side at the
gearbox output: ``t`` s; ``motor_pos`` rad, ``motor_vel`` rad/s (2,); ``ankle_pos`` rad,
``ankle_vel`` rad/s [DP, IE]; ``sg_torque`` N m [DP, IE], tared; ``joint_pos`` rad [DP, IE] or NaN
without joint encoders; the same values as plain floats: ``est.mp1``, ``est.dp``, ``est.sg_dp``, ...,
cheaper to read) and the ankle reference ``context.ref`` (rad [DP, IE]; the loop refreshes
this array in place before each ``update``: keep the reference to the array, not its values).

**Output**: the two motor torques, N m at the gearbox output, written into ``out_torque[0:2]``.

**Limits**: the safety layer always sits after the controller, whatever it is. Torques are divided
by ``context.torque_constant``; a current beyond ``amplifier.current_limit_peak`` is clamped to it
(``context.torque_limit`` N m per motor), the I^2 t budget faults OVERCURRENT, a NaN or inf faults
OUTPUT_INVALID, and the ankle range (``context.ankle_limit`` rad), sensor checks and deadlines fault
as for any controller. ``update`` is called only while ACTIVE; in every other state the set values
are zero. An exception raised by ``update`` ends the run, and the daemon goes safe (amplifiers off);
one raised by ``reset`` refuses the activation (nothing is enabled). A :class:`Controller`'s output
is ramped in by the daemon over ``controller.soft_start_s`` after each activation. The kinematics'
matrices and ``context.ref`` are read-only (shared with the daemon and the next controller).

**Real time**: ``update`` runs at ``controller.rate_hz`` (1 kHz) inside the loop: allocate nothing
(prefer plain floats and preallocated arrays), never block, no I/O.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from ankle_rt.control.friction import FrictionFeedForward
from ankle_rt.elementwise import Value, stack
from ankle_rt.estimation import Estimate
from ankle_rt.kinematics import Kinematics

if TYPE_CHECKING:
    from ankle_rt.config import Config


@dataclass(frozen=True)
class ControllerContext:
    """What a controller is built from, once, before the run (not per cycle).

    ``params`` is the config's free-form ``controller.params`` mapping (the plugin validates it and
    raises ValueError naming the key on bad input). The limits are those the safety layer enforces.
    """

    cfg: "Config"               # the whole validated configuration, read-only (ankle_rt.readonly)
    params: dict[str, Any]      # controller.params (the controller's own copy)
    kin: Kinematics             # R (theta_m = R theta), R_inv, R_inv_T (tau_m = R^-T tau_ankle), K (N m/rad)
    ref: np.ndarray             # rad (2,) [DP, IE], refreshed in place every cycle; a read-only view
    dt: float                   # s, the control period
    torque_constant: float      # N m/A at the gearbox output
    torque_limit: float         # N m per motor: torque_constant * current_limit_peak (clamped beyond)
    ankle_limit: float          # rad, |DP| and |IE| beyond this fault ANKLE_RANGE
    friction: FrictionFeedForward = field(repr=False)   # the config's identified friction feed-forward

    @classmethod
    def from_config(cls, cfg: "Config", kin: Kinematics, ref: np.ndarray) -> "ControllerContext":
        import copy
        import math

        from ankle_rt.readonly import read_only

        c, kt = cfg["controller"], cfg["actuator"]["torque_constant"]
        view = ref.view()   # the reference generator's rate limit starts from ref: controllers only read it
        view.flags.writeable = False
        return cls(cfg=read_only(cfg), params=copy.deepcopy(dict(c["params"])), kin=kin, ref=view, dt=1.0 / c["rate_hz"],
                   torque_constant=kt, torque_limit=kt * cfg["amplifier"]["current_limit_peak"],
                   ankle_limit=math.radians(cfg["limits"]["ankle_range_deg"]),
                   friction=FrictionFeedForward.from_config(cfg))


class Controller(abc.ABC):
    """Subclass this for a controller plugin; register the class under the entry-point group
    ``ankle_rt.controllers`` (see the module docstring for the cycle's inputs, output and limits).

    The daemon builds it with ``cls(context)``. Optional: ``set_gains(**gains)`` (the ``ctl gains``
    command; raise ValueError for an unknown or bad gain) and a ``gains`` object with ``as_dict()``
    (shown by ``ctl status``).
    """

    def __init__(self, context: ControllerContext):
        self.context = context

    def reset(self, est: Estimate) -> None:
        """Called on each activation, with the current estimate (restart integrators, soft start)."""

    @abc.abstractmethod
    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        """Write the motor torques (N m, gearbox output) into ``out_torque[0:2]``. No allocation. A plugin's
        ``est`` is read-only (:class:`~ankle_rt.estimation.EstimateView`): the checks after it read it."""


class BatchableController(abc.ABC):
    """A controller written once, element-wise (:mod:`ankle_rt.elementwise`), that the daemon runs on
    floats and the batched daemon cycle (:mod:`ankle_rt.sweep.cycle`) runs on arrays over a batch of
    devices with no code of its own for it. A subclass provides:

    - ``law(est, ref_dp, ref_ie) -> (torque_1, torque_2)``: the motor torques (N m, gearbox output)
      of one cycle from the :class:`~ankle_rt.estimation.Estimate`'s plain values (``est.dp``,
      ``est.mv1``, ``est.sg_dp``, ...) and the ankle reference (rad); it advances the controller's
      own state (filters, integrators, soft start) by one cycle. Element-wise: plain arithmetic,
      ``abs``, comparisons and :mod:`ankle_rt.elementwise` (``select`` instead of ``if`` on a value,
      ``clip``, ``exp``, ...); a plain ``if`` only on a flag that :func:`~ankle_rt.elementwise.stack`
      keeps a bool (the same on every device).
    - ``start(est, where=True)``: activation (soft start, state reset), for a batch only where
      ``where`` (bool per device) holds.
    - ``ref``: the ankle reference array (rad [DP, IE]) the daemon refreshes in place every cycle.
    - optionally ``shared``: names of descriptive attributes taken from the first device on
      :meth:`stack` (the reference array, limits); ``columns``: names of list attributes holding
      numbers (a matrix's entries), each stacked into arrays; and :meth:`batch_key`.

    :meth:`stack` turns one object per device into one object whose numbers are arrays over the
    batch (sub-objects with their own ``stack``, such as the friction feed-forward or the torque
    loop, stacked by it). The daemon calls the :class:`~ankle_rt.control.CycleController` methods
    defined here: :meth:`reset` and :meth:`update`.
    """

    shared: tuple[str, ...] = ("ref",)
    columns: tuple[str, ...] = ()

    @abc.abstractmethod
    def law(self, est: Estimate, ref_dp: Value, ref_ie: Value) -> tuple[Value, Value]:
        """Motor torques (N m) of this cycle. Element-wise; no allocation for floats."""

    @abc.abstractmethod
    def start(self, est: Estimate, where: bool | np.ndarray = True) -> None:
        """On activation (for a batch: where ``where`` holds)."""

    @classmethod
    def stack(cls, controllers: Sequence["BatchableController"]) -> "BatchableController":
        """One controller standing for ``controllers`` (one per device of a batch, same class and
        :meth:`batch_key`); ValueError for a non-numeric attribute that differs."""
        return stack(controllers, shared=cls.shared, columns=cls.columns)

    def angles(self, est: Estimate) -> tuple[Value, Value]:
        """rad [DP, IE]: the ankle angles the law compares the reference with (here the estimate
        through the cables). Element-wise. Where the daemon and the batch hold "where the ankle is"
        (hold here, activation), so that a hold commands no torque step."""
        return est.dp, est.ie

    def batch_key(self) -> tuple[tuple[str, Any], ...]:
        """(config key, value) pairs that must be equal for controllers to run in one batch (their
        structure, e.g. whether a loop is closed); the batch names the first key that differs."""
        return ()

    def reset(self, est: Estimate) -> None:
        self.start(est)

    def update(self, est: Estimate, out_torque: np.ndarray) -> None:
        ref = self.ref
        out_torque[0], out_torque[1] = self.law(est, ref.item(0), ref.item(1))
