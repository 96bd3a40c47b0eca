"""How far a swing phase's impedance lets the free foot run from toe-off, and where it hands the foot
to the heel strike (swing12).

In swing the foot is off the ground: what moves it is the phase's spring and damper on the inertia the
wearer feels, J / (1 + kp) of the reflected motor inertia through the joint-torque loop (J without it)
plus the foot's own, damped by the phase's B (under the loop the law renders B: its lead on the loop's lag
and the cable's share of the motor's motion, :func:`ankle_rt.lead.law_damping`, cancel what the loop takes):

    J_f theta'' = K (theta_0 - theta) - B theta'

The walk's stance angles run from the able-bodied push-off at the fastest cadence (-20.5 deg, Winter 1991
via :mod:`ankle_rt.gait_data`) to the stance's peak dorsiflexion (12 deg). The foot enters early swing
as it leaves push-off: within those angles, moving at most at the able-bodied push-off's peak rate (8.0
rad/s at fast cadence) or the rate at which a motor reaches ``safety.max_motor_speed_rad_s`` (6.67 rad/s
nominal: a foot released faster trips ``MOTOR_JUMP`` whatever the swing does), whichever is less. It
enters late swing on its way back from push-off where the phase machine lets it: above
``late_swing_angle`` (and up to the stance's peak), slower than ``late_swing_velocity``. From every
corner of that box of states the linear model above, run over the phase's longest stay (``timeout_s``):

- the ankle stays within SWING_RANGE_FRACTION of ``limits.ankle_range_deg`` (30 of 40 deg);
- it never moves faster than it entered (the phase may slow the foot, not speed it past the motor-speed
  limit);
- from the shortest able-bodied swing on (0.39 s at fast cadence: the earliest the heel strike comes
  after toe-off) it lies where the able-bodied heel strike takes the foot, from the loading response's
  plantarflexion (-6.0 deg at fast cadence) to the stance's peak, and so does the phase's equilibrium:
  the heel strike takes the foot where the swing leaves it. Early stance's spring pulls a foot landed
  further plantarflexed back so hard that the gauges read a dorsiflexor moment, a toe-off in the loading
  response: early swing then holds the wearer. And the wearer's weight lands on a dorsiflexed foot.

The model is linear, so the box's corners bound every state inside it; friction, which only brakes, is
left out. Measured on the walking scenario (lockstep, config/walk.yaml, 100 kg): early swing with no
stiffness and damping 0.09-4 N m s/rad ran to ``ANKLE_RANGE``, or landed the heel on a foot at 31-34 deg
of plantarflexion and early stance's spring flung it to ``MOTOR_JUMP``; at damping 5 it landed at 24 deg
at 98 % of the motor-speed limit; early swing at 8-12 N m/rad (damping 4) landed it at -9 to -15 deg at
fast cadence, the toe-off read 60 ms later left early swing's soft spring under the wearer for the
stance (the ankle to 29 deg, the motors at 29.7 of 30 rad/s; at 20 N m/rad: -2 deg, 19 rad/s); late
swing with its equilibrium at +30 deg landed the wearer's weight on the dorsiflexed foot, ``SG_RAIL``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ankle_rt.discretize import expm
from ankle_rt.gait_data import CADENCES, able_bodied, stride_period_s
from ankle_rt.kinematics import motor_ratio
from ankle_rt.params import TransmissionParams

SWING_RANGE_FRACTION = 0.75     # of limits.ankle_range_deg a swing phase may take the foot to
RATE_TOLERANCE = 1e-9           # relative: the entry rate itself is allowed


def _able_bodied_rates(cadence: str, samples: int = 2000) -> np.ndarray:
    """rad/s: the able-bodied DP rate over the stride at ``cadence``."""
    return np.gradient(able_bodied(cadence, samples)["angle_dp"]) * samples / stride_period_s(cadence)


def _loading_response(cadence: str) -> float:
    """rad: the able-bodied ankle's plantarflexion after heel strike (before stance dorsiflexes it)."""
    angle = able_bodied(cadence)["angle_dp"]
    return float(np.min(angle[:int(np.argmax(angle))]))


# rad: the most plantarflexed able-bodied angle over the cadences (the push-off at fast cadence, -20.5 deg)
TOE_OFF_ANGLE = min(float(np.min(able_bodied(c)["angle_dp"])) for c in CADENCES)
# rad: where the able-bodied heel strike takes the foot, the loading response's plantarflexion (-6.0 deg at
# fast cadence)
LANDING_ANGLE = min(_loading_response(c) for c in CADENCES)
# rad/s: the able-bodied push-off's fastest plantarflexion over the cadences (8.0 at fast cadence)
PUSH_OFF_RATE = max(float(-np.min(_able_bodied_rates(c))) for c in CADENCES)
# s: the shortest able-bodied swing, toe-off to heel strike (0.39 s at fast cadence)
SHORTEST_SWING_S = min((1.0 - stance) * stride_period_s(c) for c, (_, stance, _, _) in CADENCES.items())


@dataclass(frozen=True)
class Excursion:
    """What the model does from a box of entry states: angles in rad, rate in rad/s."""

    low: float              # the least angle
    high: float             # the largest angle
    rate: float             # the fastest |rate|
    landing: tuple[float, float]     # the least and largest angle from SHORTEST_SWING_S on


@dataclass(frozen=True)
class SwingLimits:
    """The free-foot model and the bounds of the module docstring for one config."""

    inertia: float          # kg m^2, J_f: what the wearer feels of the motors plus the foot
    angle_limit: float      # rad: the foot must stay within +-this
    entry_rate: float       # rad/s: the fastest the foot enters a swing phase, and the fastest it may move
    dt: float               # s: the model's sampling (the control period)
    horizon: float          # s: the longest a phase lasts (timeout_s)
    stance_angles: tuple[float, float]       # rad: the walk's (push-off, peak dorsiflexion)
    landing: tuple[float, float]             # rad: where the heel strike may find the foot
    late_swing: tuple[float, float]          # late_swing_angle (rad), late_swing_velocity (rad/s)

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any], stance_peak: float) -> "SwingLimits":
        """From ``cfg`` (its torque loop, foot, motors, limits and gait-phase transitions);
        ``stance_peak`` rad: the walk's most dorsiflexed stance angle."""
        from ankle_rt.control.torque_loop import ImpedanceLimits
        from ankle_rt.loop_setup import ReflectedActuator, torque_feedback

        c = cfg["controller"]
        g = c["gait_phase"]
        if torque_feedback(cfg):
            lim = ImpedanceLimits.from_config(cfg)
            motors = lim.inertia[0] / (1.0 + lim.kp[0])
        else:
            motors = ReflectedActuator.from_config(cfg).inertia[0]
        # the ankle DP rate at which a motor (|R[i, 0]| rad/s per rad/s) reaches the motor-speed limit
        motor_rate = cfg["safety"]["max_motor_speed_rad_s"] / float(np.max(np.abs(motor_ratio(
            TransmissionParams(**cfg["transmission"]))[:, 0])))
        return cls(inertia=float(motors + cfg["foot"]["inertia_dp"]),
                   angle_limit=SWING_RANGE_FRACTION * math.radians(cfg["limits"]["ankle_range_deg"]),
                   entry_rate=min(PUSH_OFF_RATE, motor_rate), dt=1.0 / c["rate_hz"], horizon=float(g["timeout_s"]),
                   stance_angles=(TOE_OFF_ANGLE, stance_peak), landing=(LANDING_ANGLE, stance_peak),
                   late_swing=(float(g["late_swing_angle"]), float(g["late_swing_velocity"])))

    def entry_states(self, late: bool) -> np.ndarray:
        """(2, 4): the corners (angle rad, rate rad/s) of the states the foot enters the phase in."""
        w, (lo, hi) = self.entry_rate, self.stance_angles
        rates = (-w, w)
        if late:
            angle, velocity = self.late_swing
            lo, hi = max(angle, lo), max(angle, hi)
            rates = (-w, min(w, max(velocity, -w)))
        return np.array([(a, r) for a in (lo, hi) for r in rates]).T

    def excursion(self, stiffness: float, damping: float, equilibrium: float, starts: np.ndarray) -> Excursion:
        """The model from the ``starts`` (2, n) over the horizon, sampled every control period (the exact
        discretisation, the trajectory built by doubling: a dozen small products)."""
        j = self.inertia
        a = np.array([[0.0, 1.0], [-stiffness / j, -damping / j]])
        step = expm(a * self.dt)
        n = starts.shape[1]
        x = starts - np.array([[equilibrium], [0.0]])
        samples = math.ceil(self.horizon / self.dt) + 1
        while x.shape[1] < samples * n:         # columns: sample k of start i at k n + i
            x = np.hstack([x, step @ x])
            step = step @ step
        x = x[:, :samples * n]
        angle = x[0] + equilibrium
        landed = angle[min(math.ceil(SHORTEST_SWING_S / self.dt), samples - 1) * n:]
        return Excursion(float(angle.min()), float(angle.max()), float(np.abs(x[1]).max()),
                         (float(landed.min()), float(landed.max())))

    def refusal(self, late: bool, stiffness: float, damping: float, equilibrium: float) -> tuple[str, str] | None:
        """(DP parameter name, reason) when a swing phase with these DP parameters lets the foot out of
        the bounds of the module docstring, None when it keeps it in."""
        deg = math.degrees
        starts = self.entry_states(late)
        lo, hi = self.landing
        landing = (f"{deg(lo):.1f}...{deg(hi):.1f} deg (the able-bodied loading response's plantarflexion to the "
                   f"stance's peak)")
        see = "docs/daemon.md \"Swing from toe-off\""
        if not lo <= equilibrium <= hi:
            return ("equilibrium_dp", f"equilibrium_dp {deg(equilibrium):.1f} deg is outside {landing}: the heel strike "
                                      f"would find the foot there ({see})")
        run = self.excursion(stiffness, damping, equilibrium, starts)
        where = (f"entering {'late swing (above late_swing_angle)' if late else 'early swing at toe-off'} "
                 f"anywhere in {deg(starts[0].min()):.1f}...{deg(starts[0].max()):.1f} deg at up to "
                 f"{self.entry_rate:.3g} rad/s, on the {self.inertia:.3g} kg m^2 the wearer feels")
        if run.rate > self.entry_rate * (1.0 + RATE_TOLERANCE):
            return ("stiffness_dp", f"the spring (stiffness_dp {stiffness:g}, damping_dp {damping:g}) speeds the free "
                                    f"foot to {run.rate:.3f} rad/s from {where}, faster than it entered (the lesser of the "
                                    f"push-off's {PUSH_OFF_RATE:.1f} rad/s and safety.max_motor_speed_rad_s at the "
                                    f"ankle): more damping_dp or less stiffness_dp ({see})")
        if max(-run.low, run.high) > self.angle_limit:
            return ("damping_dp", f"the free foot runs to {deg(run.low if -run.low > run.high else run.high):.1f} deg "
                                  f"from {where}, beyond {SWING_RANGE_FRACTION:g} x limits.ankle_range_deg, "
                                  f"{deg(self.angle_limit):.1f} deg: more damping_dp or stiffness_dp ({see})")
        early, late_ = run.landing
        if early < lo or late_ > hi:
            return ("stiffness_dp", f"the foot lies at {deg(early if early < lo else late_):.1f} deg {SHORTEST_SWING_S:.2f} s "
                                    f"or more after {where} (the shortest swing: the heel strike may find it there), outside "
                                    f"{landing}: more stiffness_dp to bring it back ({see})")
        return None
