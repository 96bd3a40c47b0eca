"""Transmission backlash / cable slack: a dead zone in the cable stretch."""

from __future__ import annotations

from ankle_rt.config import Field, Section, non_negative
from ankle_rt.kinematics import Kinematics
from sim_backend.effects.base import Effect, register_effect
from ankle_rt.elementwise import clip


@register_effect("backlash")
class Backlash(Effect):
    """Slack of ``half_width`` metres of cable each way. ``per: axis`` (default): the cables carry no
    stiffness force until the stretch of an ankle axis exceeds half_width / R_axis (rad), i.e. the
    spring term becomes K dz(phi) with dz the dead-zone function; the correction to the linear joint
    torque is ``-K clip(phi, -b, b)`` per axis (the damping term beta K phi' is kept). ``per: cable``:
    the dead zone acts on each cable's own stretch r (R phi)_i (m), ``-K_a (R^T clip(R phi, -b/r,
    b/r))_a / (R^T R)_aa`` per axis a, which equals ``-K phi`` inside both dead zones."""

    PARAMS = Section({
        "half_width": non_negative("m of cable length, dead zone +/- half_width"),
        "per": Field(str, "where the dead zone acts: each ankle axis, or each cable", default="axis",
                     choices=("axis", "cable")),
    })
    cause = "backlash"
    elementwise = True
    min_substeps = 4  # within 0.5 % RMS joint torque of RK4 at dt/40 (tests/test_effects.py)

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        tr = plant.transmission
        kin = Kinematics.from_params(tr)
        self.k_dp, self.k_ie = float(kin.K[0, 0]), float(kin.K[1, 1])
        self.per_cable = params["per"] == "cable"
        self.b_dp = params["half_width"] / tr.lever_dp
        self.b_ie = params["half_width"] / tr.lever_ie
        self.b_cable = params["half_width"] / tr.pulley_radius          # motor rad
        self.a_dp, self.a_ie = float(kin.R[0, 0]), float(kin.R[0, 1])   # R = [[a_dp, a_ie], [a_dp, -a_ie]]

    def cable_torque(self, phi_dp, phi_ie, dphi_dp, dphi_ie):
        if self.per_cable:
            b, a0, a1 = self.b_cable, self.a_dp, self.a_ie
            c1 = clip(a0 * phi_dp + a1 * phi_ie, -b, b)
            c2 = clip(a0 * phi_dp - a1 * phi_ie, -b, b)
            return -self.k_dp * (c1 + c2) / (2.0 * a0), -self.k_ie * (c1 - c2) / (2.0 * a1)
        b0, b1 = self.b_dp, self.b_ie
        return -self.k_dp * clip(phi_dp, -b0, b0), -self.k_ie * clip(phi_ie, -b1, b1)
