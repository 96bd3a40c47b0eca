"""Stribeck friction: extra friction at low sliding speed, decaying to the Coulomb level."""

from __future__ import annotations

from ankle_rt.config import Section, non_negative, positive
from sim_backend.effects.base import Effect, register_effect
from ankle_rt.elementwise import exp, tanh


@register_effect("stribeck")
class StribeckFriction(Effect):
    """Resisting torque ``static_excess * exp(-|w / stribeck_velocity|^exponent) * tanh(w / v_eps)`` on
    each motor (N m), on top of the baseline Coulomb + viscous friction. At rest the breakaway torque is
    kc + static_excess; ``v_eps`` is the baseline's smoothing velocity (actuator.friction_smoothing_velocity).
    The shape exponent is 2 (Gaussian) by default; measured Stribeck curves take 0.5-2 (1: exponential)."""

    PARAMS = Section({
        "static_excess": non_negative("N m, breakaway torque above the Coulomb level (fs - kc)"),
        "stribeck_velocity": positive("rad/s at the gearbox output, decay speed of the excess"),
        "exponent": positive("shape of the decay (2 Gaussian, 1 exponential)", default=2.0),
    })
    cause = "stribeck"
    elementwise = True

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        self.excess = params["static_excess"]
        self.inv_vs = 1.0 / params["stribeck_velocity"]
        self.inv_ve = 1.0 / plant.actuator.friction_smoothing_velocity
        self.e = params["exponent"]

    def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
        a, ivs, ive, e = self.excess, self.inv_vs, self.inv_ve, self.e
        return (a * exp(-abs(w1 * ivs) ** e) * tanh(w1 * ive),
                a * exp(-abs(w2 * ivs) ** e) * tanh(w2 * ive))
