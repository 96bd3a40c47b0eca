"""Direction-dependent Coulomb and viscous friction (the paper's eq. 8), its own size per motor."""

from __future__ import annotations

from ankle_rt.config import Field, Section
from sim_backend.effects.base import OPTIONAL_FLOAT, Effect, register_effect
from ankle_rt.elementwise import tanh


@register_effect("asymmetric_friction")
class AsymmetricFriction(Effect):
    """Makes the baseline friction differ between directions: kc+/- = kc +/- coulomb_asymmetry and
    D+/- = D +/- viscous_asymmetry. Added resisting torque (N m) on each motor:
    ``coulomb_asymmetry * |tanh(w / v_eps)| + viscous_asymmetry * |w|``. Two motors never share their
    friction: motor 2 may have its own (``coulomb_asymmetry_2``, ``viscous_asymmetry_2``; default motor 1's)."""

    PARAMS = Section({
        "coulomb_asymmetry": Field(float, "N m, (kc+ - kc-) / 2"),
        "viscous_asymmetry": Field(float, "N m s/rad, (D+ - D-) / 2", default=0.0),
        "coulomb_asymmetry_2": Field(OPTIONAL_FLOAT, "N m, motor 2 (default: coulomb_asymmetry)", default=None),
        "viscous_asymmetry_2": Field(OPTIONAL_FLOAT, "N m s/rad, motor 2 (default: viscous_asymmetry)", default=None),
    })
    cause = "asymmetric_friction"
    elementwise = True

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        self.dc = params["coulomb_asymmetry"]
        self.dv = params["viscous_asymmetry"]
        self.dc2 = self.dc if params["coulomb_asymmetry_2"] is None else params["coulomb_asymmetry_2"]
        self.dv2 = self.dv if params["viscous_asymmetry_2"] is None else params["viscous_asymmetry_2"]
        self.inv_ve = 1.0 / plant.actuator.friction_smoothing_velocity

    def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
        ive = self.inv_ve
        return (self.dc * abs(tanh(w1 * ive)) + self.dv * abs(w1),
                self.dc2 * abs(tanh(w2 * ive)) + self.dv2 * abs(w2))
