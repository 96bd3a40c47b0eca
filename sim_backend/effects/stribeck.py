"""Stribeck friction: extra friction at low sliding speed, decaying to the Coulomb level."""

from __future__ import annotations

from ankle_rt.config import Section, non_negative, positive
from sim_backend.effects.base import Effect, register_effect
from ankle_rt.elementwise import exp, tanh


@register_effect("stribeck")
class StribeckFriction(Effect):
    """Resisting torque ``static_excess * exp(-(w / stribeck_velocity)^2) * tanh(w / v_eps)`` on each
    motor (N m), on top of the baseline Coulomb + viscous friction. At rest the breakaway torque is
    kc + static_excess; ``v_eps`` is the baseline's smoothing velocity (actuator.friction_smoothing_velocity)."""

    PARAMS = Section({
        "static_excess": non_negative("N m, breakaway torque above the Coulomb level (fs - kc)"),
        "stribeck_velocity": positive("rad/s at the gearbox output, decay speed of the excess"),
    })
    cause = "stribeck"
    elementwise = True

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        self.excess = params["static_excess"]
        self.inv_vs = 1.0 / params["stribeck_velocity"]
        self.inv_ve = 1.0 / plant.actuator.friction_smoothing_velocity

    def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
        a, ivs, ive = self.excess, self.inv_vs, self.inv_ve
        u1, u2 = w1 * ivs, w2 * ivs
        return (a * exp(-u1 * u1) * tanh(w1 * ive),
                a * exp(-u2 * u2) * tanh(w2 * ive))
