"""Level walking on the simulated ankle (``sim.scenario: walking``): the wearer's body loads the foot.

Able-bodied ankle kinematics and moments over the stride: :mod:`ankle_rt.gait_data` (Winter 1991's
normative gait data at slow / natural / fast cadence, with Bovi et al. 2011's stance fractions and
moment peaks).

In stance the shank is driven by the body and the foot is on the ground: the ankle feels the
able-bodied moment ``m M_ab(s)`` (plantarflexor moment per kg, pushing the foot towards dorsiflexion)
*through* a compliance around the able-bodied angle ``theta_ab(s)``:

    tau_ext = w(s) [ m M_ab(s) + K_c (theta_ab(s) - theta) + B_c (dtheta_ab(s) - dtheta) ]

``K_c = kappa m`` is the wearer's effective rotational stiffness about the ankle in stance (foot
pad and shoe contact in series with the residual limb in its socket and the body's posture
adjusting; [assumed], of the order of the able-bodied ankle quasi-stiffness, Shamaei, Sawicki and
Dollar 2013). So the joint torque is what the controller renders against the body: a device softer
than the able-bodied ankle lets the ankle dorsiflex further and gives less moment, a stiffer one
the reverse, and if it renders the able-bodied moment-angle curve the ankle follows it exactly.
``w(s)`` fades the contact in over the first 6 % of stance (heel strike, loading response) and out
over the last 4 % (toe-off), so loading is smooth, as through a heel pad. In swing (``w = 0``) the
foot is free. IE (inversion positive) gets the same form with a small frontal-plane moment from
side sway (about 0.15 N m/kg, Winter 1991) and a smaller stiffness.

Stride to stride: the stride period (coefficient of variation 2 %), the moment amplitude (4 %),
the side-sway moment (a random bias per stride) and the angle (+/-1 deg offset) vary, drawn from
``sim.walking.seed`` once at start; walking starts with a heel strike at ``start_s``.

Written element-wise (:mod:`ankle_rt.elementwise`): the per-tick coefficients are floats for one
plant and arrays for a batch (:meth:`WalkingScenario.stack`); the load is linear in the foot's
state with coefficients held over the tick, evaluated at every integration substep by the model
(stiff contacts need that, not a torque held over the tick).
"""

from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

import numpy as np

from ankle_rt.elementwise import Value, lookup, pick, select, stack
from ankle_rt.gait_data import CADENCES, REF_PEAK_MOMENT, TEMPLATE, Template, angle_scale, stride_period_s

KAPPA_DP = 6.0        # N m/rad per kg: stance stiffness of body + contact about the DP axis [assumed]
KAPPA_IE = 2.0        # N m/rad per kg, IE [assumed]
DAMPING_PER_KG = 0.03  # N m s/rad per kg, both axes [assumed]
FADE_IN, FADE_OUT = 0.06, 0.04   # fractions of stance over which the contact loads and unloads
N_STRIDES = 4096      # strides drawn in advance (then repeated): > 1 h of walking


def _smoothstep(x: Value) -> Value:
    x = select(x < 0.0, 0.0, select(x > 1.0, 1.0, x))
    return x * x * (3.0 - 2.0 * x)


class WalkingScenario:
    """The body's load on the foot of one plant (floats) or a batch (arrays, :meth:`stack`).

    Once per tick :meth:`advance` sets the load's coefficients (``a_dp + k_dp theta + b_dp dtheta``
    form); :meth:`torque` is called by the model at every substep. Ground truth for benches:
    ``phase`` (stride phase, 0 at heel strike; -1 before walking starts), ``stride`` (index),
    ``stance`` (the foot on the ground), ``angle_ab`` / ``moment_ab`` (the able-bodied DP angle, rad,
    and plantarflexor moment, N m, of this instant of this stride)."""

    def __init__(self, params: Mapping[str, Any]):
        self.mass = m = float(params["mass_kg"])
        _, self.stance_fraction, peak, push = CADENCES[params["cadence"]]
        period = stride_period_s(params["cadence"])
        self.start = float(params["start_s"])
        rng = np.random.default_rng(params["seed"])
        v = float(params["variability"])
        self.periods = period * (1.0 + 0.02 * v * rng.standard_normal(N_STRIDES))
        self.amplitudes = (m * peak / REF_PEAK_MOMENT) * (1.0 + 0.04 * v * rng.standard_normal(N_STRIDES))
        self.sway = m * (1.0 + 0.3 * v * rng.standard_normal(N_STRIDES))
        self.sway_bias = m * 0.05 * v * rng.standard_normal(N_STRIDES)
        self.offsets = math.radians(1.0) * v * rng.uniform(-1.0, 1.0, N_STRIDES)
        self.angle_scale = angle_scale(push)
        self.k_dp_c, self.k_ie_c = KAPPA_DP * m, KAPPA_IE * m
        self.b_c = DAMPING_PER_KG * m
        self.stride = N_STRIDES - 1     # the next stride (index 0) begins at start_s
        self.t_start = self.t_end = self.start
        self.phase = -1.0
        self.stance = False
        self.angle_ab = self.moment_ab = 0.0
        self.a_dp = self.a_ie = self.k_dp = self.k_ie = self.b = 0.0

    @classmethod
    def stack(cls, scenarios: Sequence["WalkingScenario"]) -> "WalkingScenario":
        """One scenario for a batch: numbers become arrays over the plants, the per-stride draws
        (strides, plants) arrays read with :func:`~ankle_rt.elementwise.pick`."""
        out = stack(scenarios, tables=("periods", "amplitudes", "sway", "sway_bias", "offsets"))
        out.stride = out.stride.astype(np.intp)
        out.stance = np.zeros(len(scenarios), dtype=bool)
        return out

    def advance(self, t: Value) -> None:
        """Set the load for the tick starting at ``t`` (s, plant time)."""
        new = t >= self.t_end
        stride = select(new, (self.stride + 1) % N_STRIDES, self.stride)
        self.stride = stride
        t_start = select(new, self.t_end, self.t_start)
        self.t_start = t_start
        period = pick(self.periods, stride)
        self.t_end = select(new, t_start + period, self.t_end)
        walking = t >= self.start
        s = select(walking, (t - t_start) / period, 0.0)
        sf = self.stance_fraction
        pos, du = Template.position(s, sf)
        stance = walking & (s < sf)
        x = s / sf
        w = select(stance, _smoothstep(x / FADE_IN) * _smoothstep((1.0 - x) / FADE_OUT), 0.0)
        scale = self.angle_scale
        offset = pick(self.offsets, stride)
        angle = lookup(TEMPLATE.dp, pos) * scale + offset
        rate = lookup(TEMPLATE.rate_dp, pos) * (scale * du / period)
        moment = lookup(TEMPLATE.moment_dp, pos) * pick(self.amplitudes, stride)
        ie = lookup(TEMPLATE.ie, pos)
        rate_ie = lookup(TEMPLATE.rate_ie, pos) * (du / period)
        moment_ie = lookup(TEMPLATE.moment_ie, pos) * pick(self.sway, stride) + pick(self.sway_bias, stride)
        k_dp, k_ie, b = w * self.k_dp_c, w * self.k_ie_c, w * self.b_c
        self.a_dp = w * moment + k_dp * angle + b * rate
        self.a_ie = w * moment_ie + k_ie * ie + b * rate_ie
        self.k_dp, self.k_ie, self.b = k_dp, k_ie, b
        self.phase = select(walking, s, -1.0)
        self.stance = stance
        self.angle_ab = angle
        self.moment_ab = select(stance, moment, 0.0)

    def torque(self, th_dp: Value, th_ie: Value, w_dp: Value, w_ie: Value) -> tuple[Value, Value]:
        """N m on the foot [DP, IE] at ankle angles (rad) and rates (rad/s): the body's load."""
        return (self.a_dp - self.k_dp * th_dp - self.b * w_dp,
                self.a_ie - self.k_ie * th_ie - self.b * w_ie)
