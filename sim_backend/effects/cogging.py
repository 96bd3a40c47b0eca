"""Cogging: torque ripple periodic in the motor angle, with its own phase and amplitude per motor."""

from __future__ import annotations

import math

from ankle_rt.config import Field, Section, non_negative
from sim_backend.effects.base import OPTIONAL_FLOAT, Effect, register_effect


@register_effect("cogging")
class Cogging(Effect):
    """Resisting torque ``a_i sin(n theta_i + p_i) + h sin(2 n theta_i + q_i)`` (N m) on motor i,
    ``theta_i`` the motor angle at the gearbox output (rad), n = ``periods_per_rev``. Rotor cogging
    seen through the gearbox has gear_ratio times the rotor's periods; gear-mesh ripple at the output
    has fewer. Two motors never share a rotor position, so motor 2 may have its own phase and amplitude
    (``phase_2``, ``amplitude_2``; default: motor 1's); ``harmonic_amplitude`` adds the second harmonic
    real ripple carries."""

    PARAMS = Section({
        "amplitude": non_negative("N m, motor 1 (and motor 2 unless amplitude_2)"),
        "periods_per_rev": Field(int, "ripple periods per output revolution", low=1),
        "phase": Field(float, "rad, motor 1 (and motor 2 unless phase_2)", default=0.0),
        "amplitude_2": Field(OPTIONAL_FLOAT, "N m, motor 2 (default: amplitude)", default=None, low=0.0),
        "phase_2": Field(OPTIONAL_FLOAT, "rad, motor 2 (default: phase)", default=None),
        "harmonic_amplitude": non_negative("N m of the second harmonic (2 n periods per revolution)", default=0.0),
        "harmonic_phase": Field(float, "rad, second harmonic of motor 1", default=0.0),
        "harmonic_phase_2": Field(OPTIONAL_FLOAT, "rad, second harmonic of motor 2 (default: harmonic_phase)",
                                  default=None),
    })
    cause = "cogging"

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        self.n = float(params["periods_per_rev"])
        self.a1 = params["amplitude"]
        self.a2 = self.a1 if params["amplitude_2"] is None else params["amplitude_2"]
        self.p1 = params["phase"]
        self.p2 = self.p1 if params["phase_2"] is None else params["phase_2"]
        self.h = params["harmonic_amplitude"]
        self.q1 = params["harmonic_phase"]
        self.q2 = self.q1 if params["harmonic_phase_2"] is None else params["harmonic_phase_2"]

    def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
        n, h = self.n, self.h
        return (self.a1 * math.sin(n * th1 + self.p1) + h * math.sin(2.0 * n * th1 + self.q1),
                self.a2 * math.sin(n * th2 + self.p2) + h * math.sin(2.0 * n * th2 + self.q2))
