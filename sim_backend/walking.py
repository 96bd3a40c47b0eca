"""Level walking on the simulated ankle (``sim.scenario: walking``): the wearer's body loads the foot.

Able-bodied ankle kinematics and moments over the stride, after Winter's normative gait data (D. A.
Winter, *The Biomechanics and Motor Control of Human Gait*, 2nd ed., 1991, ankle angle and moment at
slow / natural / fast cadence) with the stance fraction and moment peaks of Bovi, Rabuffetti, Mazzoleni
and Ferrarin (2011), *Gait & Posture* 33: 6-13 (speed-dependent ankle moment and angle in adults):
a key-point table per cadence, interpolated by a periodic spline (:data:`DP_KEYPOINTS`).

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
from ankle_rt.references import periodic_spline

TABLE_SIZE = 1000
G = 9.81

# Cadences in steps/min (Winter 1991: slow 87, natural 105, fast 123) with the stance fraction,
# the peak plantarflexor moment (N m/kg) and the push-off plantarflexion (deg) that go with them
# (Winter 1991; Bovi et al. 2011, their slow / natural / fast adults).
CADENCES: dict[str, tuple[float, float, float, float]] = {
    #         steps/min, stance fraction, peak moment N m/kg, push-off deg
    "slow": (87.0, 0.64, 1.35, -14.0),
    "normal": (105.0, 0.62, 1.50, -17.0),
    "fast": (123.0, 0.60, 1.60, -20.0),
}

# (template phase, DP angle deg (dorsiflexion +), plantarflexor moment N m/kg, IE angle deg, IE moment
# N m/kg): one stride from heel strike, stance in [0, TEMPLATE_STANCE). Natural cadence, Winter 1991.
TEMPLATE_STANCE = 0.62
DP_KEYPOINTS = (
    (0.00, 0.0, 0.00, 2.0, 0.00),
    (0.03, -3.0, -0.10, 0.0, -0.03),
    (0.08, -5.0, 0.00, -1.0, -0.05),
    (0.18, 1.0, 0.35, -2.5, 0.05),
    (0.30, 5.0, 0.80, -3.0, 0.12),
    (0.42, 9.0, 1.30, -2.0, 0.15),
    (0.48, 10.0, 1.50, -1.0, 0.14),
    (0.54, 5.0, 1.25, 1.0, 0.08),
    (0.59, -8.0, 0.45, 3.0, 0.02),
    (0.62, -17.0, 0.00, 5.0, 0.00),
    (0.66, -15.0, 0.00, 5.0, 0.00),
    (0.75, -5.0, 0.00, 3.0, 0.00),
    (0.87, 0.0, 0.00, 2.0, 0.00),
    (1.00, 0.0, 0.00, 2.0, 0.00),
)
_REF_PEAK_MOMENT, _REF_PUSH_OFF = CADENCES["normal"][2], CADENCES["normal"][3]

KAPPA_DP = 6.0        # N m/rad per kg: stance stiffness of body + contact about the DP axis [assumed]
KAPPA_IE = 2.0        # N m/rad per kg, IE [assumed]
DAMPING_PER_KG = 0.03  # N m s/rad per kg, both axes [assumed]
FADE_IN, FADE_OUT = 0.06, 0.04   # fractions of stance over which the contact loads and unloads
N_STRIDES = 4096      # strides drawn in advance (then repeated): > 1 h of walking


class Template:
    """The able-bodied stride as tables over the template phase u in [0, 1): DP and IE angles (rad)
    and their rates per unit phase, moments (N m/kg)."""

    def __init__(self) -> None:
        dp, m_dp, ie, m_ie = (np.array(c) for c in periodic_spline(DP_KEYPOINTS, TABLE_SIZE))
        m_dp[int(TEMPLATE_STANCE * TABLE_SIZE):] = 0.0   # no moment in swing (the spline's ripples)
        m_ie[int(TEMPLATE_STANCE * TABLE_SIZE):] = 0.0
        self.dp, self.ie = np.radians(dp), np.radians(ie)
        self.moment_dp, self.moment_ie = m_dp, m_ie
        self.rate_dp = np.gradient(self.dp) * TABLE_SIZE   # rad per unit phase
        self.rate_ie = np.gradient(self.ie) * TABLE_SIZE

    @staticmethod
    def position(s: Value, stance: Value) -> Value:
        """Table position of stride phase ``s`` in [0, 1) for a stance fraction ``stance``: stance is
        mapped onto the template's stance, swing onto its swing. Also returns d(position)/ds."""
        in_stance = s < stance
        u = select(in_stance, s * (TEMPLATE_STANCE / stance),
                   TEMPLATE_STANCE + (s - stance) * ((1.0 - TEMPLATE_STANCE) / (1.0 - stance)))
        du = select(in_stance, TEMPLATE_STANCE / stance, (1.0 - TEMPLATE_STANCE) / (1.0 - stance))
        return u * TABLE_SIZE, du


TEMPLATE = Template()


def able_bodied(cadence: str, samples: int = 200) -> dict[str, np.ndarray]:
    """The able-bodied stride at ``cadence`` (no variability): gait phase, DP angle (rad) and
    plantarflexor moment (N m/kg), for plots and error metrics."""
    _, stance, peak, push = CADENCES[cadence]
    s = np.arange(samples) / samples
    pos, _ = Template.position(s, stance)
    return {"phase": s, "angle_dp": lookup(TEMPLATE.dp, pos) * _angle_scale(push),
            "moment_dp": lookup(TEMPLATE.moment_dp, pos) * (peak / _REF_PEAK_MOMENT), "stance": stance}


def _angle_scale(push_off_deg: float) -> float:
    return push_off_deg / _REF_PUSH_OFF


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
        period, self.stance_fraction, peak, push = CADENCES[params["cadence"]]
        period = 120.0 / period
        self.start = float(params["start_s"])
        rng = np.random.default_rng(params["seed"])
        v = float(params["variability"])
        self.periods = period * (1.0 + 0.02 * v * rng.standard_normal(N_STRIDES))
        self.amplitudes = (m * peak / _REF_PEAK_MOMENT) * (1.0 + 0.04 * v * rng.standard_normal(N_STRIDES))
        self.sway = m * (1.0 + 0.3 * v * rng.standard_normal(N_STRIDES))
        self.sway_bias = m * 0.05 * v * rng.standard_normal(N_STRIDES)
        self.offsets = math.radians(1.0) * v * rng.uniform(-1.0, 1.0, N_STRIDES)
        self.angle_scale = _angle_scale(push)
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
        stance = walking & (s < sf) if s.__class__ is np.ndarray else (walking and s < sf)
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
