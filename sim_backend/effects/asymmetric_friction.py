"""Direction-dependent Coulomb and viscous friction (the paper's eq. 8)."""

from __future__ import annotations

from ankle_rt.config import Field, Section
from sim_backend.effects.base import Effect, register_effect
from ankle_rt.elementwise import tanh


@register_effect("asymmetric_friction")
class AsymmetricFriction(Effect):
    """Makes the baseline friction differ between directions: kc+/- = kc +/- coulomb_asymmetry and
    D+/- = D +/- viscous_asymmetry. Added resisting torque (N m) on each motor:
    ``coulomb_asymmetry * |tanh(w / v_eps)| + viscous_asymmetry * |w|``."""

    PARAMS = Section({
        "coulomb_asymmetry": Field(float, "N m, (kc+ - kc-) / 2"),
        "viscous_asymmetry": Field(float, "N m s/rad, (D+ - D-) / 2", default=0.0),
    })
    cause = "asymmetric_friction"
    elementwise = True

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        self.dc = params["coulomb_asymmetry"]
        self.dv = params["viscous_asymmetry"]
        self.inv_ve = 1.0 / plant.actuator.friction_smoothing_velocity

    def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
        dc, dv, ive = self.dc, self.dv, self.inv_ve
        return (dc * abs(tanh(w1 * ive)) + dv * abs(w1),
                dc * abs(tanh(w2 * ive)) + dv * abs(w2))
