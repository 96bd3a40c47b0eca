"""Load-dependent (Bowden cable / capstan) friction: friction that grows with the cable tension."""

from __future__ import annotations

from ankle_rt.config import Section, non_negative
from sim_backend.effects.base import Effect, register_effect
from ankle_rt.elementwise import tanh


@register_effect("load_dependent_friction")
class LoadDependentFriction(Effect):
    """A Bowden cable sliding in its sheath loses a fraction of the tension (capstan law
    F_loss = F (1 - exp(-mu * wrap angle)) ~ coefficient * F). At the motor this is a resisting torque
    ``coefficient * |tc| * tanh(w / v_eps)`` (N m), with ``tc`` the cable torque the motor feels."""

    PARAMS = Section({
        "coefficient": non_negative("dimensionless, friction torque per unit cable torque"),
    })
    cause = "load_dependent_friction"
    elementwise = True
    min_substeps = 4  # within 0.5 % RMS joint torque of RK4 at dt/40 (tests/test_effects.py)
    needs_cable_torque = True

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        self.mu = params["coefficient"]
        self.inv_ve = 1.0 / plant.actuator.friction_smoothing_velocity

    def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
        mu, ive = self.mu, self.inv_ve
        return mu * abs(tc1) * tanh(w1 * ive), mu * abs(tc2) * tanh(w2 * ive)
