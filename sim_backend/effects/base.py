"""Effect interface and registry.

An effect changes the plant through up to three hooks, all in SI units at the gearbox output:

- ``motor_torque(th1, th2, w1, w2, tc1, tc2)``: torques (N m) that *resist* each motor, like friction.
  ``th`` are motor angles (rad), ``w`` motor rates (rad/s) and ``tc`` the cable torques each motor
  feels (N m, the motor-side image R^-T tau_j of the joint torque; its size is the cable tension
  times the pulley radius); it is worked out only for an effect that sets ``needs_cable_torque = True``
  and is zero otherwise. Evaluated at every integration substep.
- ``cable_torque(phi_dp, phi_ie, dphi_dp, dphi_ie)``: a correction (N m) added to the linear joint
  torque K (phi + beta phi') from the cable stretch phi (rad, ankle coordinates). The strain gauges
  measure it and the motors feel its R^-T image. Evaluated at every substep.
- ``command(tau1, tau2)``: transforms the motor torque command (N m) once per control tick, before it
  is held for the tick (actuation delay, torque-constant changes).

An effect whose hooks use only arithmetic and :mod:`ankle_rt.elementwise` declares
``elementwise = True``: :meth:`Effect.stack` then makes one instance whose numbers are arrays over a
batch of plants, and the batch simulator calls each hook once for all of them. Any other effect
still runs in a batch, called plant by plant (correct, slower).

An effect overrides only the hooks it needs; the model collects the overridden ones once, so an
unused hook costs nothing per step. Parameters are validated with the config schema machinery, so a
bad effect entry names its key like any other config error.
"""

from __future__ import annotations

from typing import Any, ClassVar, Sequence

from ankle_rt.config import ConfigError, Field, Section, validate
from ankle_rt.kinematics import Kinematics
from ankle_rt.params import PlantParams
from ankle_rt.elementwise import stack

#: the type of an optional number in a PARAMS field (written null, or left out, for "as motor 1's")
OPTIONAL_FLOAT = (float, type(None))

EFFECTS: dict[str, type["Effect"]] = {}


def register_effect(name: str):
    """Class decorator: make an effect available to the config under ``name``."""

    def deco(cls: type["Effect"]) -> type["Effect"]:
        cls.name = name
        EFFECTS[name] = cls
        return cls

    return deco


class Effect:
    name: ClassVar[str] = ""
    PARAMS: ClassVar[Section] = Section({})
    #: the vocabulary word of docs/design.md this effect stands for (used by the diagnosis)
    cause: ClassVar[str] = "unknown"
    #: integration substeps per control tick this effect needs to stay accurate; the model raises
    #: its substeps to the largest minimum of its effects (cable-side laws act on the stiff cable modes)
    min_substeps: ClassVar[int] = 1
    #: the hooks work on numpy arrays over a batch as well as on floats (see the module docstring)
    elementwise: ClassVar[bool] = False

    def __init__(self, params: dict[str, Any], plant: PlantParams, dt: float):
        """``params`` are validated already; ``dt`` is the control period (s)."""
        self.params = params
        self.plant = plant
        self.dt = dt

    def motor_torque(self, th1: float, th2: float, w1: float, w2: float,
                     tc1: float, tc2: float) -> tuple[float, float]:
        raise NotImplementedError

    def cable_torque(self, phi_dp: float, phi_ie: float, dphi_dp: float, dphi_ie: float) -> tuple[float, float]:
        raise NotImplementedError

    def command(self, tau1: float, tau2: float) -> tuple[float, float]:
        raise NotImplementedError

    def reset(self) -> None:
        """Forget internal state (delay lines); called when the plant is reset."""

    @classmethod
    def stack(cls, effects: Sequence["Effect"]) -> "Effect":
        """One instance standing for ``effects`` (same class, one per plant of a batch): every number
        becomes an array over the batch (``params`` and ``plant``, descriptive only, are the first
        plant's). Raises ValueError when another attribute differs between plants (the batch then
        calls them plant by plant). Only for ``elementwise`` effects; stateful ones override this to
        lay out their state per plant."""
        return stack(effects, shared=("params", "plant"))

    @classmethod
    def uses(cls, hook: str) -> bool:
        return getattr(cls, hook) is not getattr(Effect, hook)


#: ``per`` of an effect on the cables' stretch: each ankle axis's stretch, or each cable's own
PER_AXIS_OR_CABLE = Field(str, "where the law acts: each ankle axis, or each cable", default="axis",
                          choices=("axis", "cable"))


class CableStretchEffect(Effect):
    """An effect whose law acts on the cables' stretch, per ankle axis or per cable (``per``): the
    transmission's numbers and the per-cable mapping, written once."""

    def __init__(self, params: dict[str, Any], plant: PlantParams, dt: float):
        super().__init__(params, plant, dt)
        kin = Kinematics.from_params(plant.transmission)    # numbers only kept: a batch stacks them
        self.per_cable = params["per"] == "cable"
        self.k_dp, self.k_ie = float(kin.K[0, 0]), float(kin.K[1, 1])   # N m/rad, the cables at the ankle
        self.a_dp, self.a_ie = float(kin.R[0, 0]), float(kin.R[0, 1])   # R = [[a_dp, a_ie], [a_dp, -a_ie]]

    def cable_law(self, stretch):
        """The law on one cable's stretch r (R phi)_i (motor rad), for ``per: cable``."""
        raise NotImplementedError

    def per_cable_terms(self, phi_dp, phi_ie):
        """``cable_law`` on each cable, mapped back to the axes: (R^T g)_a / (R^T R)_aa, which is phi
        itself for a law g(x) = x."""
        a0, a1 = self.a_dp, self.a_ie
        g1 = self.cable_law(a0 * phi_dp + a1 * phi_ie)
        g2 = self.cable_law(a0 * phi_dp - a1 * phi_ie)
        return (g1 + g2) / (2.0 * a0), (g1 - g2) / (2.0 * a1)


def build_effects(entries: list[dict], plant: PlantParams, dt: float, source: str = "config") -> list[Effect]:
    """Instantiate ``sim.effects`` entries, validating each one's parameters against its schema."""
    effects = []
    for i, entry in enumerate(entries):
        name = entry.get("type")
        if name not in EFFECTS:
            raise ConfigError(f"unknown effect {name!r} (known: {', '.join(sorted(EFFECTS))})",
                              source, f"sim.effects.{i}.type")
        cls = EFFECTS[name]
        body = {k: v for k, v in entry.items() if k != "type"}
        params = validate(body, cls.PARAMS, lambda _p: source, ("sim", "effects", str(i)))
        try:
            effects.append(cls(params, plant, dt))
        except ConfigError as e:          # a constraint between the effect's own keys, named in its entry
            raise ConfigError(e.message, source, ".".join(filter(None, ("sim.effects", str(i), e.key)))) from None
    return effects
