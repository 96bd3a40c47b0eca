"""Friction effects on the motor side."""

from __future__ import annotations

from ankle_rt.config import Section, positive, non_negative
from sim_backend.effects.base import Effect, register_effect
from ankle_rt.elementwise import tanh


@register_effect("coulomb")
class CoulombFriction(Effect):
    """The baseline Coulomb friction kc tanh(w / v_eps) of each motor (the paper's tau_F).

    The viscous part D is linear and lives in the model's linear part, so it is integrated exactly."""

    PARAMS = Section({
        "coulomb": non_negative("N m, kc"),
        "smoothing_velocity": positive("rad/s, v_eps of the tanh"),
    })
    cause = "none"
    elementwise = True

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        self.kc = params["coulomb"]
        self.inv_v = 1.0 / params["smoothing_velocity"]

    def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
        kc, iv = self.kc, self.inv_v
        return kc * tanh(w1 * iv), kc * tanh(w2 * iv)
