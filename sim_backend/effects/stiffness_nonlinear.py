"""Nonlinear (hardening) cable stiffness."""

from __future__ import annotations

from ankle_rt.config import Field, Section, positive
from ankle_rt.kinematics import Kinematics
from sim_backend.effects.base import Effect, register_effect


@register_effect("stiffness_nonlinear")
class HardeningStiffness(Effect):
    """Cable force ``k s (1 + (|s| / hardening_stretch)^(exponent - 1))`` for a stretch s (m): the secant
    stiffness doubles at s = hardening_stretch; exponent 3 (default) is the cubic law, 2 the stiffening
    k (1 + |s| / s0). With s = R_axis phi per axis the correction to the linear joint torque is
    ``K_axis phi (R_axis |phi| / hardening_stretch)^(exponent - 1)`` (N m)."""

    PARAMS = Section({
        "hardening_stretch": positive("m of cable stretch at which the secant stiffness has doubled"),
        "exponent": Field(float, "power of the force law (3: cubic, 2: k s (1 + |s| / s0))", default=3.0,
                          low=1.5, high=6.0),
    })
    cause = "stiffness_nonlinear"
    elementwise = True
    min_substeps = 4  # within 0.5 % RMS joint torque of RK4 at dt/40 (tests/test_effects.py)

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        tr = plant.transmission
        K, s = Kinematics.from_params(tr).K, params["hardening_stretch"]
        self.p = params["exponent"] - 1.0
        self.c_dp = float(K[0, 0]) * (tr.lever_dp / s) ** self.p
        self.c_ie = float(K[1, 1]) * (tr.lever_ie / s) ** self.p

    def cable_torque(self, phi_dp, phi_ie, dphi_dp, dphi_ie):
        p = self.p
        return self.c_dp * phi_dp * abs(phi_dp) ** p, self.c_ie * phi_ie * abs(phi_ie) ** p
