"""Able-bodied level-walking ankle data: angle and moment over the stride at three cadences.

After Winter's normative gait data (D. A. Winter, *The Biomechanics and Motor Control of Human Gait*,
2nd ed., University of Waterloo Press, 1991: ankle angle and moment at slow / natural / fast cadence)
with the stance fraction and moment peaks of Bovi, Rabuffetti, Mazzoleni and Ferrarin (2011),
"A multiple-task gait analysis approach: kinematic, kinetic and EMG reference data for healthy young
and adult subjects", *Gait & Posture* 33: 6-13. A key-point table (:data:`KEYPOINTS`) interpolated by
a periodic spline; per cadence the stride is warped so stance takes that cadence's fraction and the
moment and push-off angle are scaled to its peaks. The simulator's walking scenario
(``sim_backend.walking``) drives the ankle with it; ``ankle-rt bench walk`` compares against it.
"""

from __future__ import annotations

import numpy as np

from ankle_rt.elementwise import Value, lookup, select
from ankle_rt.references import periodic_spline

TABLE_SIZE = 1000

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
KEYPOINTS = (
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
REF_PEAK_MOMENT, REF_PUSH_OFF = CADENCES["normal"][2], CADENCES["normal"][3]


def stride_period_s(cadence: str) -> float:
    """One stride (two steps) at ``cadence``, s."""
    return 120.0 / CADENCES[cadence][0]

class Template:
    """The able-bodied stride as tables over the template phase u in [0, 1): DP and IE angles (rad)
    and their rates per unit phase, moments (N m/kg)."""

    def __init__(self) -> None:
        dp, m_dp, ie, m_ie = (np.array(c) for c in periodic_spline(KEYPOINTS, TABLE_SIZE))
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
    return {"phase": s, "angle_dp": lookup(TEMPLATE.dp, pos) * angle_scale(push),
            "moment_dp": lookup(TEMPLATE.moment_dp, pos) * (peak / REF_PEAK_MOMENT), "stance": stance}


def angle_scale(push_off_deg: float) -> float:
    return push_off_deg / REF_PUSH_OFF
