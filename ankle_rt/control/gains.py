"""Bumpless gain changes and the soft start.

:class:`GainRamp` holds a controller's gains as plain floats. A new target set is reached by a
linear ramp over ``ramp_s`` (each gain moves by a fixed step per cycle), so a gain change never
makes the command jump. The soft start is a separate output scale that rises linearly from 0 to 1
over ``soft_start_s`` after each activation.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Mapping, Protocol, Sequence

from ankle_rt.control.base import BatchableController
from ankle_rt.control.friction import FrictionFeedForward
from ankle_rt.elementwise import all_true, minimum, select, stack
from ankle_rt.gain_margin import gain_set_refusal, ramp_refusal

if TYPE_CHECKING:
    import numpy as np

    from ankle_rt.estimation import Estimate


class GainError(ValueError):
    """A gain change was refused; ``gain`` names the gain (the command reply's field)."""

    def __init__(self, gain: str, message: str):
        self.gain = gain
        super().__init__(message)


class GainRamp:
    """Named non-negative gains with linear ramps to new targets, plus the soft-start scale.

    The soft start is element-wise (:mod:`ankle_rt.elementwise`; a :meth:`stack` over a batch of
    devices starts each where it is activated); gain ramps (run-time changes) are for one device."""

    def __init__(self, gains: Mapping[str, float], *, dt: float, ramp_s: float, soft_start_s: float):
        self.names = tuple(gains)
        self.values = [float(gains[n]) for n in self.names]
        self.targets = list(self.values)
        self.steps = [0.0] * len(self.values)
        self.cycles_per_ramp = max(1, round(ramp_s / dt))
        self.soft_step = 1.0 if soft_start_s <= 0.0 else min(1.0, dt / soft_start_s)
        self.scale = 1.0
        self.soft_starting = False   # some device's scale is still below 1
        self.ramping = False

    @classmethod
    def stack(cls, ramps: Sequence["GainRamp"]) -> "GainRamp":
        """One gain set standing for ``ramps`` (one per device of a batch): numbers as arrays."""
        return stack(ramps, columns=("values", "targets", "steps"))

    def set_targets(self, **gains: float) -> None:
        """Ramp the named gains to new values. Raises GainError naming an unknown or bad gain."""
        self.check(**gains)
        for name, value in gains.items():
            i = self.names.index(name)
            self.targets[i] = float(value)
            self.steps[i] = (self.targets[i] - self.values[i]) / self.cycles_per_ramp
        self.ramping = True

    def check(self, **gains: float) -> None:
        """Raise GainError naming an unknown gain or one that is not a finite number >= 0."""
        for name, value in gains.items():
            if name not in self.names:
                raise GainError(name, f"unknown gain {name!r} (expected one of: {', '.join(self.names)})")
            if not (isinstance(value, (int, float)) and value >= 0.0 and value < float("inf")):
                raise GainError(name, f"gain {name!r} must be a finite number >= 0, got {value!r}")

    def start(self, where: bool | np.ndarray = True) -> None:
        """Begin the soft start (for a batch: where ``where`` holds): the output scale restarts from
        zero and reaches 1 by steps of ``soft_step`` from the next :meth:`advance` on."""
        self.scale = select(where, 0.0, self.scale)
        self.soft_starting = True

    def advance(self) -> None:
        """One cycle of ramping (call once per update)."""
        if self.soft_starting:
            scale = self.scale = minimum(self.scale + self.soft_step, 1.0)
            self.soft_starting = not all_true(scale >= 1.0)
        if not self.ramping:
            return
        values, targets, steps = self.values, self.targets, self.steps
        moving = False
        for i in range(len(values)):
            s = steps[i]
            if s != 0.0:
                v = values[i] + s
                if (s > 0.0 and v >= targets[i]) or (s < 0.0 and v <= targets[i]):
                    v = targets[i]
                    steps[i] = 0.0
                else:
                    moving = True
                values[i] = v
        self.ramping = moving

    def as_dict(self) -> dict[str, float]:
        """Current gains (for status replies; allocates, not for the cycle)."""
        return dict(zip(self.names, self.values))


class RampedGainController(BatchableController):
    """What the config's controllers share: gains that ramp (bumpless changes, soft start on each
    activation), an optional friction feed-forward (off when none is given), and gain changes
    checked before they start: inside ``limits`` and, with ``margin_cfg``, keeping the required gain
    margin (the feed-forward's viscous slope counted) at every checked point of the ramp (:func:`ankle_rt.gain_margin.ramp_refusal`). Batchable."""

    shared = ("ref", "limits", "margin_cfg")

    def __init__(self, gains: Mapping[str, float], *, dt: float, ramp_s: float, soft_start_s: float,
                 friction: FrictionFeedForward | None, limits: "GainLimits | None" = None,
                 margin_cfg: Mapping[str, Any] | None = None):
        """``limits``: gain sets outside them are refused; ``margin_cfg``: the config whose plant every
        gain set must keep the required gain margin on (None: not checked)."""
        self.friction = friction or FrictionFeedForward(0.0, 0.0, 1.0, enabled=False)
        if limits is not None:
            raise_refusal(limits.check(gains))
        if margin_cfg is not None:
            raise_refusal(gain_set_refusal(margin_cfg, gains, self.friction.viscous_slope))
        self.gains = GainRamp(gains, dt=dt, ramp_s=ramp_s, soft_start_s=soft_start_s)
        self.limits = limits
        self.margin_cfg = margin_cfg

    def start(self, est: "Estimate", where: "bool | np.ndarray" = True) -> None:
        self.gains.start(where)

    def check_gains(self, **gains: float) -> None:
        """Raise GainError naming the gain unless the ramp to ``gains`` stays stable: the target inside
        the limits and, at every checked point of the ramp from the present gains, the required
        gain margin. Slow with the margin (~0.1-0.5 s): the daemon runs it off the loop thread.
        Refused while a ramp runs (its path would then no longer be the one checked)."""
        self.gains.check(**gains)
        values = dict(zip(self.gains.names, self.gains.values))
        targets = dict(zip(self.gains.names, self.gains.targets))
        targets.update({k: v for k, v in gains.items() if k in targets})
        if self.limits is not None:
            raise_refusal(self.limits.check(targets))
        if self.margin_cfg is not None:
            if self.gains.ramping:
                name = next(iter(gains), "cmd")
                raise GainError(name, "busy: the previous gain ramp is still running (controller.gain_ramp_s)")
            raise_refusal(ramp_refusal(self.margin_cfg, values, targets, self.friction.viscous_slope))

    def set_gains(self, **gains: float) -> None:
        """Ramp to new gains (names as at construction) without a jump in the command, after
        :meth:`check_gains` (else GainError)."""
        self.check_gains(**gains)
        self.apply_gains(**gains)

    def apply_gains(self, **gains: float) -> None:
        """Ramp to gains :meth:`check_gains` accepted (the daemon's second half of a checked change)."""
        self.gains.set_targets(**gains)


class GainLimits(Protocol):
    """A controller's stable set of gains (e.g. the torque loop's :class:`ImpedanceLimits`)."""

    def check(self, gains: Mapping[str, float]) -> tuple[str, str] | None:
        """(gain, reason) for a gain set outside the limits; None inside."""


def raise_refusal(bad: tuple[str, str] | None) -> None:
    """GainError from a (gain, reason) refusal; nothing for None."""
    if bad is not None:
        raise GainError(*bad)
