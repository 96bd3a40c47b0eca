"""Nonlinear (hardening) cable stiffness."""

from __future__ import annotations

from ankle_rt.config import Field, Section, non_negative, positive
from ankle_rt.elementwise import clip
from sim_backend.effects.base import PER_AXIS_OR_CABLE, CableStretchEffect, register_effect


@register_effect("stiffness_nonlinear")
class HardeningStiffness(CableStretchEffect):
    """Cable force ``k s (1 + (|s| / hardening_stretch)^(exponent - 1))`` for a stretch s (m): the secant
    stiffness doubles at s = hardening_stretch; exponent 3 (default) is the cubic law, 2 the stiffening
    k (1 + |s| / s0). With s = R_axis phi per axis the correction to the linear joint torque is
    ``K_axis phi (R_axis |phi| / hardening_stretch)^(exponent - 1)`` (N m). A cable with slack stiffens
    on its taut stretch: with ``slack`` (m) the law acts on z = phi - clip(phi, +/- slack / R_axis) (beside a
    ``backlash`` of that half-width); ``per: cable`` puts it on each cable's own stretch r (R phi)_i,
    mapped back to the axes as backlash's per-cable form is."""

    PARAMS = Section({
        "hardening_stretch": positive("m of cable stretch at which the secant stiffness has doubled"),
        "exponent": Field(float, "power of the force law (3: cubic, 2: k s (1 + |s| / s0))", default=3.0,
                          low=1.5, high=6.0),
        "slack": non_negative("m of cable: the law acts on the stretch beyond +/- slack", default=0.0),
        "per": PER_AXIS_OR_CABLE,
    })
    cause = "stiffness_nonlinear"
    elementwise = True
    min_substeps = 4  # within 0.5 % RMS joint torque of RK4 at dt/40 (tests/test_effects.py)

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        tr = plant.transmission
        s, slack = params["hardening_stretch"], params["slack"]
        self.p = params["exponent"] - 1.0
        # per axis: the stretch in rad of the axis; per cable: in motor rad of each cable (R phi)_i
        levers = (tr.pulley_radius, tr.pulley_radius) if self.per_cable else (tr.lever_dp, tr.lever_ie)
        self.c_dp = self.k_dp * (levers[0] / s) ** self.p
        self.c_ie = self.k_ie * (levers[1] / s) ** self.p
        self.b_dp, self.b_ie = slack / levers[0], slack / levers[1]

    def _law(self, x, b):
        z = x - clip(x, -b, b)
        return z * abs(z) ** self.p

    def cable_law(self, stretch):
        return self._law(stretch, self.b_dp)   # per cable both slacks are in motor rad: b_dp == b_ie

    def cable_torque(self, phi_dp, phi_ie, dphi_dp, dphi_ie):
        if self.per_cable:
            g_dp, g_ie = self.per_cable_terms(phi_dp, phi_ie)
            return self.c_dp * g_dp, self.c_ie * g_ie
        return self.c_dp * self._law(phi_dp, self.b_dp), self.c_ie * self._law(phi_ie, self.b_ie)
