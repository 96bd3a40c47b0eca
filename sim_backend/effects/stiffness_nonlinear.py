"""Nonlinear (hardening) cable stiffness."""

from __future__ import annotations

from ankle_rt.config import Field, Section, non_negative, positive
from ankle_rt.kinematics import Kinematics
from sim_backend.effects.base import Effect, register_effect
from ankle_rt.elementwise import clip


@register_effect("stiffness_nonlinear")
class HardeningStiffness(Effect):
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
        "per": Field(str, "where the stretch is taken: each ankle axis, or each cable", default="axis",
                     choices=("axis", "cable")),
    })
    cause = "stiffness_nonlinear"
    elementwise = True
    min_substeps = 4  # within 0.5 % RMS joint torque of RK4 at dt/40 (tests/test_effects.py)

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        tr = plant.transmission
        kin = Kinematics.from_params(tr)
        K, s, slack = kin.K, params["hardening_stretch"], params["slack"]
        self.p = params["exponent"] - 1.0
        self.per_cable = params["per"] == "cable"
        # per axis: the stretch in rad of the axis; per cable: in motor rad of each cable (R phi)_i
        levers = (tr.pulley_radius, tr.pulley_radius) if self.per_cable else (tr.lever_dp, tr.lever_ie)
        self.c_dp = float(K[0, 0]) * (levers[0] / s) ** self.p
        self.c_ie = float(K[1, 1]) * (levers[1] / s) ** self.p
        self.b_dp, self.b_ie = slack / levers[0], slack / levers[1]
        self.a_dp, self.a_ie = float(kin.R[0, 0]), float(kin.R[0, 1])   # R = [[a_dp, a_ie], [a_dp, -a_ie]]

    def _law(self, x, b):
        z = x - clip(x, -b, b)
        return z * abs(z) ** self.p

    def cable_torque(self, phi_dp, phi_ie, dphi_dp, dphi_ie):
        if self.per_cable:
            a0, a1 = self.a_dp, self.a_ie
            g1 = self._law(a0 * phi_dp + a1 * phi_ie, self.b_dp)
            g2 = self._law(a0 * phi_dp - a1 * phi_ie, self.b_dp)
            return self.c_dp * (g1 + g2) / (2.0 * a0), self.c_ie * (g1 - g2) / (2.0 * a1)
        return self.c_dp * self._law(phi_dp, self.b_dp), self.c_ie * self._law(phi_ie, self.b_ie)
