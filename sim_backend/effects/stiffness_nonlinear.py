"""Nonlinear (hardening) cable stiffness."""

from __future__ import annotations

from ankle_rt.config import Section, positive
from ankle_rt.kinematics import Kinematics
from sim_backend.effects.base import Effect, register_effect


@register_effect("stiffness_nonlinear")
class HardeningStiffness(Effect):
    """Cable force ``k s (1 + (s / hardening_stretch)^2)`` for a stretch s (m): the secant stiffness
    doubles at s = hardening_stretch. With s = R_axis phi per axis the correction to the linear joint
    torque is ``K_axis R_axis^2 phi^3 / hardening_stretch^2`` (N m)."""

    PARAMS = Section({
        "hardening_stretch": positive("m of cable stretch at which the secant stiffness has doubled"),
    })
    cause = "stiffness_nonlinear"
    elementwise = True
    min_substeps = 4  # within 0.5 % RMS joint torque of RK4 at dt/40 (tests/test_effects.py)

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        tr = plant.transmission
        K, s2 = Kinematics.from_params(tr).K, params["hardening_stretch"] ** 2
        self.c_dp = float(K[0, 0]) * tr.lever_dp ** 2 / s2
        self.c_ie = float(K[1, 1]) * tr.lever_ie ** 2 / s2

    def cable_torque(self, phi_dp, phi_ie, dphi_dp, dphi_ie):
        return self.c_dp * phi_dp ** 3, self.c_ie * phi_ie ** 3
