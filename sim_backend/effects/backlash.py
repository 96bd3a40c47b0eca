"""Transmission backlash / cable slack: a dead zone in the cable stretch."""

from __future__ import annotations

from ankle_rt.config import ConfigError, Field, Section, non_negative
from ankle_rt.elementwise import clip
from sim_backend.effects.base import OPTIONAL_FLOAT, PER_AXIS_OR_CABLE, CableStretchEffect, register_effect


@register_effect("backlash")
class Backlash(CableStretchEffect):
    """Slack of ``half_width`` metres of cable each way. ``per: axis`` (default): the cables carry no
    stiffness force until the stretch of an ankle axis exceeds half_width / R_axis (rad), i.e. the
    spring term becomes K dz(phi) with dz the dead-zone function; the correction to the linear joint
    torque is ``-K clip(phi, -b, b)`` per axis (the damping term beta K phi' is kept). ``per: cable``:
    the dead zone acts on each cable's own stretch r (R phi)_i (m), ``-K_a (R^T clip(R phi, -b/r,
    b/r))_a / (R^T R)_aa`` per axis a, which equals ``-K phi`` inside both dead zones. ``half_width_ie``
    (``per: axis`` only) gives the IE axis a dead zone of its own, half_width_ie / R_IE: two axes' slack
    need not be one length of cable (a joint's own play, a cable routed differently)."""

    PARAMS = Section({
        "half_width": non_negative("m of cable length, dead zone +/- half_width"),
        "half_width_ie": Field(OPTIONAL_FLOAT, "m of cable length, the IE axis' own dead zone (per: axis; "
                               "absent: half_width)", default=None, low=0.0),
        "per": PER_AXIS_OR_CABLE,
    })
    cause = "backlash"
    elementwise = True
    min_substeps = 4  # within 0.5 % RMS joint torque of RK4 at dt/40 (tests/test_effects.py)

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        tr = plant.transmission
        ie = params["half_width_ie"]
        if ie is not None and self.per_cable:
            raise ConfigError("half_width_ie is the IE axis' own dead zone: only with per: axis", None,
                              "half_width_ie")
        self.b_dp = params["half_width"] / tr.lever_dp
        self.b_ie = (params["half_width"] if ie is None else ie) / tr.lever_ie
        self.b_cable = params["half_width"] / tr.pulley_radius          # motor rad

    def cable_law(self, stretch):
        return clip(stretch, -self.b_cable, self.b_cable)

    def cable_torque(self, phi_dp, phi_ie, dphi_dp, dphi_ie):
        if self.per_cable:
            c_dp, c_ie = self.per_cable_terms(phi_dp, phi_ie)
            return -self.k_dp * c_dp, -self.k_ie * c_ie
        b0, b1 = self.b_dp, self.b_ie
        return -self.k_dp * clip(phi_dp, -b0, b0), -self.k_ie * clip(phi_ie, -b1, b1)
