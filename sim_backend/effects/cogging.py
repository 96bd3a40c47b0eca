"""Cogging: torque ripple periodic in the motor angle."""

from __future__ import annotations

import math

from ankle_rt.config import Field, Section, non_negative
from sim_backend.effects.base import Effect, register_effect


@register_effect("cogging")
class Cogging(Effect):
    """Resisting torque ``amplitude * sin(periods_per_rev * theta_m + phase)`` (N m) on each motor,
    ``theta_m`` the motor angle at the gearbox output (rad). Rotor cogging seen through the gearbox
    has gear_ratio times the rotor's periods; gear-mesh ripple at the output has fewer."""

    PARAMS = Section({
        "amplitude": non_negative("N m"),
        "periods_per_rev": Field(int, "ripple periods per output revolution", low=1),
        "phase": Field(float, "rad", default=0.0),
    })
    cause = "cogging"

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        self.a = params["amplitude"]
        self.n = float(params["periods_per_rev"])
        self.phase = params["phase"]

    def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
        a, n, p = self.a, self.n, self.phase
        return a * math.sin(n * th1 + p), a * math.sin(n * th2 + p)
