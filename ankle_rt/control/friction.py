"""Friction feed-forward: the identified friction of each motor, added to the controller's motor torque
so the loop does not have to build up an error to overcome it.

Per motor, with the filtered motor velocity ``v`` (rad/s) and the cable torque the motor feels ``tc``
(N m, ``R^-T`` of the measured joint torque):

    tau_ff = (s (kc + a exp(-(v / vs)^2) + mu |tc|) + dc |s|) g(v) + D v + dv |v|
    s = sat(sat(v / v_band) + sat(e / e_band))

- ``kc``, ``D``: Coulomb and viscous friction (``actuator.coulomb`` / ``actuator.damping``, or given);
- ``a``, ``vs``: Stribeck excess and velocity; ``dc``, ``dv``: direction asymmetry (kc+- = kc +- dc,
  D+- = D +- dv); ``mu``: load-dependent (Bowden-cable) friction per unit cable torque. These come from
  the friction effects (``stribeck``, ``asymmetric_friction``, ``load_dependent_friction``) of an
  identified model: what ``ankle-rt identify`` and ``ankle-rt diagnose --write-model`` write.
- ``sat(v / v_band)``: inside the standstill band ``|v| < v_band`` the direction-dependent
  terms fade linearly to zero, so velocity noise at standstill (one encoder count per cycle is
  0.054 rad/s) does not make the command chatter between +kc and -kc. At standstill the static
  friction is the torque loop's job (its integrator), not the feed-forward's guess of a direction,
- unless ``error_band`` e_band > 0 (0: the term is off): ``e`` is the joint-torque loop's error as
  the motor feels it (``R^-T`` (desired - filtered measured torque), N m), the direction the motor
  is about to move in; it breaks stiction before the motor moves and turns the compensation over
  at a reversal before the velocity does. Whatever the direction, ``|s| <= 1``: the magnitude is
  the model's at the measured speed, so the feed-forward never pushes with the motion by more than
  the friction the model states there.
- ``g(v) = exp(-(v / v_fade)^2)`` (``fade_velocity`` v_fade > 0; 1 when 0): the direction-dependent
  terms fade out with speed. Friction's equivalent damping 4 F / (pi v_amp) is what a slow, small
  motion of the wearer feels; a fast one (the held foot's mode after a torque step, walking) needs
  friction's damping more than the wearer needs it gone (docs/daemon.md, "Friction compensation").
- ``fraction`` (config) scales every term: below 1 the feed-forward stays below the friction of a
  device with that much less friction than the model states (passive there too).
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

from ankle_rt.elementwise import Value, clip, exp, stack

if TYPE_CHECKING:
    from ankle_rt.config import Config

FRICTION_EFFECTS = ("stribeck", "asymmetric_friction", "load_dependent_friction")
# where a feed-forward is held to the stated friction (check_not_beyond): both directions from within the
# standstill band to 10 rad/s, unloaded and at a cable torque beyond any the device carries
CHECK_VELOCITIES = tuple(s * 10.0 ** (k / 4.0) for s in (-1.0, 1.0) for k in range(-16, 5))
CHECK_CABLE_TORQUES = (0.0, 500.0)
# relative slack of check_carried's comparisons: a fraction computed as budget / stated friction (1.66 / 10)
# must fit the budget it was computed from despite the floating-point rounding (0.166 x 10 = 1.6600000000000001)
CARRIED_SLACK = 1e-9


class FrictionFeedForward:
    def __init__(self, coulomb: float, viscous: float, velocity_band: float, enabled: bool = True, *,
                 stribeck_excess: float = 0.0, stribeck_velocity: float = 1.0, coulomb_asymmetry: float = 0.0,
                 viscous_asymmetry: float = 0.0, load_coefficient: float = 0.0, fade_velocity: float = 0.0,
                 error_band: float = 0.0):
        """``coulomb``, ``stribeck_excess``, ``coulomb_asymmetry`` N m; ``viscous``, ``viscous_asymmetry``
        N m s/rad; ``velocity_band``, ``stribeck_velocity`` rad/s (> 0); ``load_coefficient`` 1;
        ``fade_velocity`` rad/s (0: no fade); ``error_band`` N m (0: the direction from the velocity only)."""
        self.kc = coulomb
        self.d = viscous
        self.inv_band = 1.0 / velocity_band
        self.enabled = enabled
        self.a = stribeck_excess
        self.inv_vs = 1.0 / stribeck_velocity
        self.dc = coulomb_asymmetry
        self.dv = viscous_asymmetry
        self.mu = load_coefficient
        self.inv_fade = 1.0 / fade_velocity if fade_velocity > 0.0 else 0.0
        self.inv_error_band = 1.0 / error_band if error_band > 0.0 else 0.0

    @classmethod
    def from_config(cls, cfg: "Config") -> "FrictionFeedForward":
        """``controller.friction_ff``. ``model: coulomb_viscous`` uses ``coulomb``/``viscous`` (default:
        the actuator's identified values); ``model: identified`` adds the friction effects of
        ``model_file`` (a config such as ``diagnose --write-model`` writes; empty: this config's own
        ``actuator`` and ``sim.effects``)."""
        f = cfg["controller"]["friction_ff"]
        a, effects, source = cfg["actuator"], (), getattr(cfg, "source", None)
        if f["model"] == "identified":
            a, effects, source = identified_model(cfg, f["model_file"])
        kc = a["coulomb"] if f["coulomb"] is None else f["coulomb"]
        d = a["damping"] if f["viscous"] is None else f["viscous"]
        out = cls(kc, d, f["velocity_band"], f["enabled"], fade_velocity=f["fade_velocity"],
                  error_band=f["error_band"], **effect_terms(effects, source)).scaled(f["fraction"])
        if out.enabled:
            out.check_not_beyond(cfg, "model_file" if f["model"] == "identified" and f["model_file"] else None)
            out.check_carried(cfg)
        return out

    def check_carried(self, cfg: "Config") -> None:
        """Raise ConfigError naming ``controller.friction_ff.fraction`` (with the largest that fits) unless
        the loop carries this feed-forward on a device without the friction it states. It pushes with the
        motion by whatever the device lacks (a negative friction: a relay of up to :meth:`most_torque`),
        and a config cannot know the device. Unloaded it may give at most ``actuator.torque_constant x
        safety.oscillation_rms_a`` per motor, a relay whose current the oscillation detector counts as no
        oscillation (stated 10 N m on the simulator's 0.28: OSCILLATION after 7 strides at 50 kg;
        30: at standstill); where someone walks, with its load term at the walking moment and counted
        twice, at most what each motor's peak current leaves beside its share of that moment and of the
        larger torque-loop clamp (stated 5 N m: 15 A in 233 cycles of 6 strides at 100 kg fast; 10:
        OSCILLATION). Twice: while a motor is back-driven it takes off the motor's torque and the loop's
        correction winds up to make that up, then it turns over with the velocity on top (counted once, a
        stated load coefficient of 0.5 at 75 kg on a device without it: 15 A in 2-5 cycles of 12 strides,
        the DP correction at its clamp at push-off)."""
        from ankle_rt.config import ConfigError
        from ankle_rt.config_schema import correction_shares, walked, walking_budget

        unloaded = self.most_torque()
        fraction = cfg["controller"]["friction_ff"]["fraction"]
        kt, rms = cfg["actuator"]["torque_constant"], cfg["safety"]["oscillation_rms_a"]
        stated = "fraction x the stated friction: actuator.coulomb or controller.friction_ff.coulomb, and the " \
                 "friction effects' static terms"
        bounds = []                              # (the largest fraction that fits, why), one per bound exceeded
        if unloaded > kt * rms * (1.0 + CARRIED_SLACK):
            bounds.append((fraction * kt * rms / unloaded,
                           f"the feed-forward's {unloaded:.3g} N m per motor ({stated}) pushes with the motion "
                           f"wherever the device has less, and a relay above {kt * rms:.3g} N m "
                           f"(actuator.torque_constant x safety.oscillation_rms_a) drives an oscillation"))
        if walked(cfg):
            share, walking, motor_peak, what = walking_budget(cfg)
            room = motor_peak - walking - correction_shares(cfg, share)
            # twice: while a motor is back-driven the feed-forward takes off its torque and the loop's
            # correction winds up to make that up; then it turns over with the velocity, on top (adv12)
            pushed = [2.0 * self.most_torque(w) for w in walking]
            if any(p - r > CARRIED_SLACK * motor_peak for p, r in zip(pushed, room)):
                bounds.append((fraction * max(0.0, min(r / p for p, r in zip(pushed, room))),
                               f"a motor at the peak current gives {motor_peak:.3g} N m, and {what}, the larger "
                               f"torque-loop clamp's share and twice the feed-forward's up to {max(pushed) / 2:.3g} "
                               f"N m ({stated}; its load term at that moment; twice: the loop's correction against "
                               f"it, then it turning over with the motion) must fit in it"))
        if not bounds:
            return
        most, why = min(bounds)                  # the tighter: the number named is accepted by both
        named = math.floor(most * 1000 * (1.0 + CARRIED_SLACK)) / 1000
        raise ConfigError(f"must be <= {named:g}: {why}, got {fraction:g}", getattr(cfg, "source", None),
                          "controller.friction_ff.fraction")

    def check_not_beyond(self, cfg: "Config", key: str | None) -> None:
        """Raise ConfigError unless this feed-forward cancels at most the friction the config states the
        device has (its ``actuator`` and the friction effects of its ``sim.effects``: the plant its gain
        margin is checked on), in either direction, at any velocity and cable torque: more is a negative
        friction, a force pushing with the motion, which drives a limit cycle no linear margin sees
        (docs/daemon.md, "Friction feed-forward"). Names ``controller.friction_ff.<key>``; None: the
        term that exceeds (coulomb or viscous)."""
        from ankle_rt.config import ConfigError

        a = cfg["actuator"]
        plant = FrictionFeedForward(a["coulomb"], a["damping"], 1.0 / self.inv_band,
                                    **effect_terms(cfg["sim"]["effects"], getattr(cfg, "source", None)))
        for part, name in ((FrictionFeedForward.without_viscous, "coulomb"), (FrictionFeedForward.viscous_only, "viscous")):
            ours, theirs = part(self), part(plant)
            excess = max(ours.torque(v, tc) * math.copysign(1.0, v) - theirs.torque(v, tc) * math.copysign(1.0, v)
                         for v in CHECK_VELOCITIES for tc in CHECK_CABLE_TORQUES)
            if excess > 1e-9 * (1.0 + abs(theirs.torque(1.0))):
                state = "actuator.coulomb and sim.effects" if name == "coulomb" else "actuator.damping"
                raise ConfigError(f"the feed-forward exceeds the friction the config states ({state}) by up to "
                                  f"{excess:.3g} N m (at speeds up to 10 rad/s): over-compensated friction pushes "
                                  f"with the motion and drives a limit cycle",
                                  getattr(cfg, "source", None), f"controller.friction_ff.{key or name}")

    def most_torque(self, cable_torque: float = 0.0) -> float:
        """N m: the largest torque of the direction-dependent terms at cable torque ``cable_torque`` N m,
        over every velocity and direction (0 when off): what the feed-forward pushes with the motion on a
        device that has none of the friction it states (config_schema.check_friction_feed_forward)."""
        if not self.enabled:
            return 0.0
        return self.kc + max(self.a, 0.0) + abs(self.dc) + self.mu * abs(cable_torque)

    @property
    def viscous_slope(self) -> float:
        """N m s/rad: the largest slope of the viscous terms (D + |dv|; 0 when off), a negative damping on
        the motor that the gain-margin model counts (ankle_rt.analysis.gain_set_margin_db)."""
        return self.d + abs(self.dv) if self.enabled else 0.0

    def scaled(self, fraction: float) -> "FrictionFeedForward":
        """A copy cancelling ``fraction`` of every friction term (the Stribeck velocity and the band kept):
        below 1 the feed-forward stays below a device's friction down to ``fraction`` of the model's."""
        out = copy.copy(self)
        for name in ("kc", "d", "a", "dc", "dv", "mu"):
            setattr(out, name, fraction * getattr(self, name))
        return out

    def without_viscous(self) -> "FrictionFeedForward":
        """A copy without the viscous terms (D, dv): under the joint-torque loop the motors' viscous
        friction is the damping the loop's integral relies on (ankle_rt.control.torque_loop)."""
        out = copy.copy(self)
        out.d = out.dv = 0.0
        return out

    def viscous_only(self) -> "FrictionFeedForward":
        """A copy with only the viscous terms (D, dv)."""
        out = copy.copy(self)
        out.kc = out.a = out.dc = out.mu = 0.0
        return out

    @classmethod
    def stack(cls, feed_forwards: Sequence["FrictionFeedForward"]) -> "FrictionFeedForward":
        """One feed-forward standing for ``feed_forwards`` (one per device of a batch, the batched
        daemon cycle): every term an array over the batch, a switched-off one all zero (so that
        :meth:`torque` gives 0 for it, as it does for one device); all switched off: one switched off."""
        if not any(f.enabled for f in feed_forwards):
            return feed_forwards[0]
        off = cls(0.0, 0.0, 1.0)
        return stack([f if f.enabled else off for f in feed_forwards])

    def torque(self, v: Value, tc: Value = 0.0, e: Value = 0.0) -> Value:
        """N m for motor velocity ``v`` rad/s, felt cable torque ``tc`` N m and the torque loop's error as
        this motor feels it ``e`` N m (0 without the loop); 0 when switched off. Element-wise
        (:mod:`ankle_rt.elementwise`): floats for one device, arrays for a :meth:`stack`."""
        if not self.enabled:
            return 0.0
        s = clip(clip(v * self.inv_band, -1.0, 1.0) + clip(e * self.inv_error_band, -1.0, 1.0), -1.0, 1.0)
        u, h = v * self.inv_vs, v * self.inv_fade
        sliding = self.kc + self.a * exp(-u * u) + self.mu * abs(tc)
        return (s * sliding + self.dc * abs(s)) * exp(-h * h) + self.d * v + self.dv * abs(v)


# the friction effects' parameters the feed-forward reads: name -> (keyword, must be > 0)
EFFECT_PARAMS = {
    "stribeck": {"static_excess": ("stribeck_excess", False), "stribeck_velocity": ("stribeck_velocity", True)},
    "asymmetric_friction": {"coulomb_asymmetry": ("coulomb_asymmetry", False),
                            "viscous_asymmetry": ("viscous_asymmetry", False)},
    "load_dependent_friction": {"coefficient": ("load_coefficient", False)},
}
OPTIONAL = {"viscous_asymmetry"}


def effect_terms(effects: Iterable[Mapping[str, Any]], source: str | None = None) -> dict[str, float]:
    """Keyword arguments of :class:`FrictionFeedForward` from ``sim.effects`` entries (the friction
    ones; other effects are not friction and are ignored). Raises ConfigError naming a missing or
    bad parameter (``sim.effects.N.key`` of ``source``)."""
    from ankle_rt.config import ConfigError

    out: dict[str, float] = {}
    for i, e in enumerate(effects):
        for key, (kw, positive) in EFFECT_PARAMS.get(e.get("type"), {}).items():
            where = f"sim.effects.{i}.{key}"
            if key not in e:
                if key in OPTIONAL:
                    continue
                raise ConfigError("missing (the friction feed-forward needs it)", source, where)
            value = e[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or (positive and value <= 0.0):
                raise ConfigError(f"expected a finite number{' > 0' if positive else ''}, got {value!r}", source, where)
            out[kw] = float(value)
    return out


def identified_model(cfg: "Config", model_file: str) -> tuple[Mapping[str, Any], list, str | None]:
    """(actuator section, sim.effects, source file) of the identified model: ``model_file`` (relative
    paths are relative to the config file) or, when empty, ``cfg`` itself. Raises ConfigError naming
    the key."""
    from ankle_rt.config import ConfigError, load_config

    if not model_file:
        return cfg["actuator"], list(cfg["sim"]["effects"]), getattr(cfg, "source", None)
    path = Path(model_file)
    if not path.is_absolute() and getattr(cfg, "source", "<memory>") != "<memory>":
        path = Path(cfg.source).parent / path
    try:
        model = load_config(path)
    except (OSError, ConfigError) as exc:
        raise ConfigError(f"cannot load the friction model: {exc}", getattr(cfg, "source", None),
                          "controller.friction_ff.model_file") from None
    return model["actuator"], list(model["sim"]["effects"]), str(path)
