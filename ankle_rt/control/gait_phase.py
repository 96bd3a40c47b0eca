"""Finite-state (gait-phase) impedance control of a powered ankle (Sup, Bohara and Goldfarb 2008; the
Open Source Leg's state machine): per phase of the stride a stiffness, a damping and an equilibrium
angle per ankle axis, ``tau = K (theta_0 - theta) - B dtheta``.

Phases and transitions (``load`` = the plantarflexor moment the strain gauges measure, ``-sg_dp``;
``theta``, ``dtheta`` the estimated DP angle and rate, dorsiflexion positive):

- early stance -> late stance: ``theta > late_stance_angle`` and ``load > late_stance_load_nm``
  (the shank has rolled over the foot; push-off impedance takes over);
- early or late stance -> early swing: ``load < load_off_nm`` (toe-off);
- early swing -> late swing: ``theta > late_swing_angle`` and ``dtheta < late_swing_velocity``
  (the foot is back near neutral and no longer dorsiflexing fast);
- early or late swing -> early stance: ``load > load_on_nm`` held for ``heel_strike_hold_s`` (heel
  strike; see :func:`heel_strike_hold_s`);
- any phase -> safe after ``timeout_s`` in it (a stuck load signal, standing, sitting); safe -> early
  stance on a fresh heel strike only: the load must have fallen below ``load_off_nm`` while safe
  (armed) and then risen above ``load_on_nm`` (held, as for a heel strike). A load stuck high or low
  keeps the ankle safe.

Hysteresis: ``load_on_nm > load_off_nm``, and phases only move forward through the stride, so an
angle hovering at a threshold cannot make them chatter. No transition happens before ``min_dwell_s``
in a phase. The active K, B and K theta_0 move towards the phase's values with a first-order blend of
time constant ``blend_s``, so neither a transition nor a live parameter change (``ctl gains
--phase``) makes the torque jump.

:class:`GaitPhaseLaw` is written element-wise (:mod:`ankle_rt.elementwise`): floats for the daemon,
arrays over a batch after :meth:`GaitPhaseLaw.stack` (per-phase tables become (phases, plants)).
:class:`GaitPhaseController` is a :class:`~ankle_rt.control.base.BatchableController` (the daemon
runs it on floats, the batched cycle on arrays): the law's torques go through the impedance
controller's actuation (:meth:`ImpedanceController.actuate`: the lead on the loop's lag, the
joint-torque loop, R^-T mapping, friction feed-forward and soft start).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Mapping, Sequence

import numpy as np

from ankle_rt.config_schema import IMPEDANCE_GAINS, MAX_CORRECTION_WALKED, dp_torque_at_peak
from ankle_rt.control.gains import GainError, GainRamp
from ankle_rt.control.impedance import ImpedanceController, actuation_from_config
from ankle_rt.control.swing import SwingLimits
from ankle_rt.control.torque_loop import ImpedanceLimits, JointTorqueLoop
from ankle_rt.elementwise import Value, pick, select, stack
from ankle_rt.estimation import Estimate
from ankle_rt.gain_margin import gain_set_refusal
from ankle_rt.gait_data import CADENCES, able_bodied
from ankle_rt.kinematics import Kinematics
from ankle_rt.loop_setup import rate_from_encoders, torque_feedback
from ankle_rt.params import TransmissionParams

if TYPE_CHECKING:
    from ankle_rt.config import Config
    from ankle_rt.control.friction import FrictionFeedForward

PHASES = ("early_stance", "late_stance", "early_swing", "late_swing", "safe")
EARLY_STANCE, LATE_STANCE, EARLY_SWING, LATE_SWING, SAFE = range(len(PHASES))
PHASE_NAMES = ("none", *PHASES)    # by the log record's gait_phase code (1 + phase; 0: another controller)
PARAMS = ("stiffness_dp", "damping_dp", "equilibrium_dp", "stiffness_ie", "damping_ie", "equilibrium_ie")
CABLE_STIFFNESS_LOW = 0.7    # the identified cable stiffness's lower bound (-30 %, as the gain margins)
STANCE_PHASES = (EARLY_STANCE, LATE_STANCE)
SWING_PHASES = (EARLY_SWING, LATE_SWING)
# rad: the able-bodied ankle's most dorsiflexed angle in stance over the cadences (12 deg at fast cadence,
# Winter 1991): where a stance phase's spring meets the push-off's peak load
WALKING_PEAK_DORSIFLEXION = max(float(np.max(able_bodied(c)["angle_dp"])) for c in CADENCES)
# N m/kg: the able-bodied peak plantarflexor moment over the cadences (1.6 at fast cadence, Winter 1991; Bovi
# et al. 2011): the wearer's push-off load a stance phase's spring must hold within the ankle range
WALKING_PEAK_MOMENT = max(peak for _, _, peak, _ in CADENCES.values())
TRANSITIONS = ("load_on_nm", "load_off_nm", "late_stance_angle", "late_stance_load_nm", "late_swing_angle",
               "late_swing_velocity", "min_dwell_s", "timeout_s", "blend_s")


class GaitPhaseLaw:
    """The phase machine and the blended impedance of the module docstring (element-wise)."""

    def __init__(self, phases: Mapping[str, Mapping[str, float]], transitions: Mapping[str, float], dt: float,
                 strike_hold_s: float):
        """``phases``: PHASES name -> PARAMS (N m/rad, N m s/rad, rad); ``transitions``: TRANSITIONS
        (N m, rad, rad/s, s); ``strike_hold_s``: how long the load must stay above ``load_on_nm`` for a
        heel strike (:func:`heel_strike_hold_s`)."""
        for name in PARAMS:                     # per parameter, one value per phase (a pick table)
            setattr(self, name, [float(phases[p][name]) for p in PHASES])
        self.load_on, self.load_off = float(transitions["load_on_nm"]), float(transitions["load_off_nm"])
        self.ls_angle, self.ls_load = float(transitions["late_stance_angle"]), float(transitions["late_stance_load_nm"])
        self.lsw_angle, self.lsw_velocity = float(transitions["late_swing_angle"]), float(transitions["late_swing_velocity"])
        self.dwell, self.timeout = float(transitions["min_dwell_s"]), float(transitions["timeout_s"])
        self.dt = dt
        self.strike_hold = float(strike_hold_s)
        self.alpha = 1.0 - math.exp(-dt / float(transitions["blend_s"]))
        self.phase = SAFE
        self.time = 0.0        # s in the current phase
        self.armed = 0.0       # 1 once the load fell below load_off while safe
        self.loaded = 0.0      # s the load has been above load_on without a break
        # the blended impedance: stiffness K, damping B and spring offset P = K theta_0 per axis (blending
        # P rather than theta_0 keeps the torque P - K theta linear in what is blended: at a fixed angle
        # it moves monotonically, by at most the blend's share of the change per cycle)
        self.k0 = self.b0 = self.p0 = self.k1 = self.b1 = self.p1 = 0.0
        self.start()

    @classmethod
    def stack(cls, laws: Sequence["GaitPhaseLaw"]) -> "GaitPhaseLaw":
        """One law for a batch (one per device): numbers become arrays, per-phase tables (phases, plants)."""
        out = stack(laws, tables=PARAMS)
        out.phase = out.phase.astype(np.intp)
        return out

    def start(self, where: bool | np.ndarray = True) -> None:
        """Back to the safe phase with its impedance at once (on activation; the soft start ramps the
        output in); for a batch only where ``where`` holds."""
        self.phase = select(where, SAFE, self.phase)
        self.time = select(where, 0.0, self.time)
        self.armed = select(where, 0.0, self.armed)
        self.loaded = select(where, 0.0, self.loaded)
        self.k0 = select(where, pick(self.stiffness_dp, SAFE), self.k0)
        self.b0 = select(where, pick(self.damping_dp, SAFE), self.b0)
        self.p0 = select(where, pick(self.stiffness_dp, SAFE) * pick(self.equilibrium_dp, SAFE), self.p0)
        self.k1 = select(where, pick(self.stiffness_ie, SAFE), self.k1)
        self.b1 = select(where, pick(self.damping_ie, SAFE), self.b1)
        self.p1 = select(where, pick(self.stiffness_ie, SAFE) * pick(self.equilibrium_ie, SAFE), self.p1)

    def update(self, load: Value, dp: Value, vdp: Value, ie: Value, vie: Value) -> tuple[Value, Value]:
        """One cycle: ``load`` N m (plantarflexor moment), DP and IE angles (rad) and rates (rad/s) in;
        desired joint torques (N m, [DP, IE]) out."""
        ph = self.phase
        t = self.time + self.dt
        ready = t >= self.dwell
        loaded = select(load > self.load_on, self.loaded + self.dt, 0.0)
        self.loaded = loaded
        on, off = loaded >= self.strike_hold, load < self.load_off
        nxt = select(ready & (ph == EARLY_STANCE) & (dp > self.ls_angle) & (load > self.ls_load), LATE_STANCE, ph)
        nxt = select(ready & ((ph == EARLY_STANCE) | (ph == LATE_STANCE)) & off, EARLY_SWING, nxt)
        nxt = select(ready & (ph == EARLY_SWING) & (dp > self.lsw_angle) & (vdp < self.lsw_velocity), LATE_SWING, nxt)
        nxt = select(ready & ((ph == EARLY_SWING) | (ph == LATE_SWING)) & on, EARLY_STANCE, nxt)
        safe = ph == SAFE
        armed = select(safe & off, 1.0, self.armed)
        nxt = select(ready & safe & on & (armed > 0.0), EARLY_STANCE, nxt)
        nxt = select((ph != SAFE) & (t > self.timeout), SAFE, nxt)
        changed = nxt != ph
        self.armed = select(changed, 0.0, armed)
        self.time = select(changed, 0.0, t)
        self.phase = nxt
        a = self.alpha
        k0, k1 = pick(self.stiffness_dp, nxt), pick(self.stiffness_ie, nxt)
        p0 = self.p0 + a * (k0 * pick(self.equilibrium_dp, nxt) - self.p0)
        p1 = self.p1 + a * (k1 * pick(self.equilibrium_ie, nxt) - self.p1)
        k0 = self.k0 + a * (k0 - self.k0)
        k1 = self.k1 + a * (k1 - self.k1)
        b0 = self.b0 + a * (pick(self.damping_dp, nxt) - self.b0)
        b1 = self.b1 + a * (pick(self.damping_ie, nxt) - self.b1)
        self.k0, self.b0, self.p0, self.k1, self.b1, self.p1 = k0, b0, p0, k1, b1, p1
        return p0 - k0 * dp - b0 * vdp, p1 - k1 * ie - b1 * vie

    def set_phase_params(self, phase: int, **params: float) -> None:
        """New parameters of one phase (one device); reached through the blend, no jump."""
        for name, value in params.items():
            getattr(self, name)[phase] = float(value)

    def phase_params(self) -> dict[str, dict[str, float]]:
        """Phase name -> its parameters (for status; allocates)."""
        return {p: {n: getattr(self, n)[i] for n in PARAMS} for i, p in enumerate(PHASES)}


class GaitPhaseController(ImpedanceController):
    """The built-in ``gait_phase`` controller (``controller.gait_phase``): :class:`GaitPhaseLaw` on the
    estimated ankle and the strain-gauge load, then the impedance controller's actuation (with the
    law's blended stiffness for the lead on the loop's lag)."""

    shared = ("ref", "limits", "gain_maxima", "margin_cfg", "stance_limits", "stance_hold_nm", "swing")

    def __init__(self, kin: Kinematics, law: GaitPhaseLaw, *, dt: float, soft_start_s: float,
                 ankle_limit: float, gain_maxima: Mapping[str, float],
                 friction: "FrictionFeedForward | None" = None, torque_loop: JointTorqueLoop | None = None,
                 limits: ImpedanceLimits | None = None, margin_cfg: Mapping | None = None,
                 stance_limits: Mapping[int, tuple[float, str]] | None = None, stance_hold_nm: float = 0.0,
                 swing: SwingLimits | None = None):
        """``ankle_limit`` rad bounds the equilibria; ``gain_maxima``: ``stiffness`` and ``damping``
        (controller.gain_limits); ``limits``: the torque loop's stable set, checked per phase;
        ``margin_cfg``: the config whose plant and loop every phase's (K, B) must keep the required gain
        margin on (:func:`ankle_rt.gain_margin.gain_set_refusal`), as the impedance controller's gains;
        ``stance_limits``: stance phase -> the N m of DP joint torque its spring may ask for where the
        push-off loads it and what sets that (:func:`stance_torque_limits`, :func:`stance_torque`);
        ``stance_hold_nm``: the plantarflexor moment each stance spring must hold before the ankle
        reaches its range (the heaviest wearer's peak walking moment); ``swing``: how far each swing
        phase may let the free foot run from toe-off (:class:`~ankle_rt.control.swing.SwingLimits`)."""
        self.gait = law
        self.swing = swing
        self.stance_limits = dict(stance_limits or {})
        self.stance_hold_nm = stance_hold_nm
        self.deferred: tuple[int, dict[str, float]] | None = None   # a live change to the stance or swing phase in force
        self.ankle_limit = ankle_limit
        self.gain_maxima = dict(gain_maxima)
        super().__init__(kin, np.zeros(2), {"stiffness_dp": 0.0, "stiffness_ie": 0.0, "damping_dp": 0.0,
                                            "damping_ie": 0.0}, dt=dt, soft_start_s=soft_start_s,
                         friction=friction, torque_loop=torque_loop, limits=None)
        self.limits = limits
        self.margin_cfg = margin_cfg
        self.gains = GainRamp({}, dt=dt, ramp_s=0.0, soft_start_s=soft_start_s)   # the soft start only: the
        for i in range(len(PHASES)):                                               # law blends its own parameters
            self._check_phase(i, {n: getattr(law, n)[i] for n in PARAMS})

    @classmethod
    def from_config(cls, cfg: "Config", kin: Kinematics, ref: np.ndarray,
                    friction: "FrictionFeedForward | None") -> "GaitPhaseController":
        """``controller.gait_phase`` with the joint-torque loop when :func:`torque_feedback` says so.
        Raises ConfigError naming a parameter outside the limits."""
        from ankle_rt.config import ConfigError

        c = cfg["controller"]
        dt = 1.0 / c["rate_hz"]
        g = c["gait_phase"]
        loop, limits, friction = actuation_from_config(cfg, friction)
        law = GaitPhaseLaw({p: g[p] for p in PHASES}, {k: g[k] for k in TRANSITIONS}, dt, heel_strike_hold_s(cfg))
        try:
            return cls(kin, law, dt=dt, soft_start_s=c["soft_start_s"],
                       ankle_limit=math.radians(cfg["limits"]["ankle_range_deg"]),
                       gain_maxima=c["gain_limits"], friction=friction, torque_loop=loop, limits=limits,
                       margin_cfg=phase_margin_config(cfg), stance_limits=stance_torque_limits(cfg),
                       stance_hold_nm=WALKING_PEAK_MOMENT * cfg["wearer"]["mass_kg"],
                       swing=SwingLimits.from_config(cfg, WALKING_PEAK_DORSIFLEXION))
        except GainError as exc:   # a phase's parameter, or the torque-loop gain that limits its margin
            gain = exc.gain.split(".")[-1]
            key = f"torque_loop.{gain}" if gain in c["torque_loop"] else f"gait_phase.{exc.gain}"
            raise ConfigError(str(exc), getattr(cfg, "source", None), f"controller.{key}") from None

    @property
    def phase(self) -> int:
        """The current gait phase (index into PHASES)."""
        return self.gait.phase

    def _check_phase(self, phase: int, params: Mapping[str, float]) -> None:
        name = PHASES[phase]
        for key, value in params.items():
            kind = key.split("_")[0]
            where = f"{name}.{key}"
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise GainError(where, f"{where} must be a finite number, got {value!r}")
            if kind == "equilibrium":
                if abs(value) > self.ankle_limit:
                    raise GainError(where, f"{where} {value:g} rad is beyond the ankle range "
                                           f"+/-{self.ankle_limit:.3g} rad (limits.ankle_range_deg)")
            elif not 0.0 <= value <= self.gain_maxima[kind]:
                raise GainError(where, f"{where} must be in [0, {self.gain_maxima[kind]:g}] "
                                       f"(controller.gain_limits.{kind}), got {value:g}")
        if phase in STANCE_PHASES:
            held = params["stiffness_dp"] * (self.ankle_limit - params["equilibrium_dp"])
            if held < self.stance_hold_nm:
                raise GainError(f"{name}.stiffness_dp",
                                f"{name}: its spring holds {held:.0f} N m of plantarflexor moment before the ankle reaches its "
                                f"range (stiffness_dp x (limits.ankle_range_deg - equilibrium_dp)), below the heaviest "
                                f"wearer's peak walking moment ({self.stance_hold_nm:.0f} N m: wearer.mass_kg x "
                                f"{WALKING_PEAK_MOMENT:g} N m/kg): the ankle would yield under the push-off "
                                f"(docs/daemon.md \"Limits a walker does not trip\")")
        if phase in self.stance_limits:
            most, what = self.stance_limits[phase]
            torque, angle = stance_torque(phase, params, self.gait.ls_angle)
            if torque > most:
                raise GainError(f"{name}.stiffness_dp",
                                f"{name}: its spring asks {torque:.0f} N m DP at {math.degrees(angle):.1f} deg (stiffness_dp "
                                f"x (angle - equilibrium_dp), the walk's most dorsiflexed stance), beyond {what} "
                                f"({most:.0f} N m; docs/daemon.md \"Limits a walker does not trip\")")
        bad = self.limits.check(params) if self.limits is not None else None
        if bad is None and self.swing is not None and phase in SWING_PHASES:
            bad = self.swing.refusal(phase == LATE_SWING, params["stiffness_dp"], params["damping_dp"],
                                     params["equilibrium_dp"])
        if bad is None and self.margin_cfg is not None:      # the slow check only when the quick one passes
            # the gauges' noise is the torque loop's, checked with the config (ankle_rt.config), not a phase's
            bad = gain_set_refusal(self.margin_cfg, {k: params[k] for k in IMPEDANCE_GAINS}, self.friction.viscous_slope,
                                   noise=False)
            # sim.yaml's loop (the rate on the joint encoders) is tuned for the bench, not for stance springs
            if bad is not None and rate_from_encoders(self.margin_cfg["controller"]["torque_loop"]):
                bad = (bad[0], bad[1] + WALK_ON_ENCODERS)
        if bad is not None:
            raise GainError(f"{name}.{bad[0]}", f"{name}: {bad[1]}")

    def check_gains(self, phase: str | None = None, **gains: float) -> None:
        """Raise GainError naming the parameter unless one phase's new parameters (PARAMS names) keep
        the gain limits, the ankle range, the stance bounds, the swing's excursion from toe-off
        (:class:`~ankle_rt.control.swing.SwingLimits`), the torque loop's stable set and its gain margin. Slow with
        the margin (~0.05 s): the daemon runs it off the loop thread, then :meth:`apply_gains`."""
        if phase not in PHASES:
            raise GainError("phase", f"the gait_phase controller needs a phase (one of: {', '.join(PHASES)}), "
                                     f"got {phase!r}")
        i = PHASES.index(phase)
        for name in gains:
            if name not in PARAMS:
                raise GainError(name, f"unknown gait-phase parameter {name!r} (expected one of: {', '.join(PARAMS)})")
        merged = {n: getattr(self.gait, n)[i] for n in PARAMS}
        merged.update(self._deferred_for(i))
        merged.update(gains)
        self._check_phase(i, merged)

    def apply_gains(self, phase: str | None = None, **gains: float) -> None:
        """Start the blend to parameters :meth:`check_gains` accepted (no torque jump). A change to the
        stance or swing phase the ankle is in waits until that phase has ended and applies from its next
        beginning (adv11; swing12 for swing): the checks hold a phase's parameters as it begins (a stance
        spring from the push-off's load, a swing from the toe-off's state), not a spring changed under
        the push-off (late stance at 250 N m/rad, no damping, its equilibrium toggled between -0.55 and
        0.05 rad every 0.3 s while walking: ANKLE_RANGE at 75 kg) or a swing changed mid-flight."""
        i = PHASES.index(phase)
        if i in STANCE_PHASES + SWING_PHASES and i == self.gait.phase:
            self.deferred = (i, {**self._deferred_for(i), **gains})
        else:
            self.gait.set_phase_params(i, **gains)

    def _deferred_for(self, phase: int) -> dict[str, float]:
        return self.deferred[1] if self.deferred is not None and self.deferred[0] == phase else {}

    def start(self, est: Estimate, where: bool | np.ndarray = True) -> None:
        super().start(est, where)
        self.gait.start(where)

    def angles(self, est: Estimate) -> tuple[Value, Value]:
        """The estimate through the cables: what the phase law takes (it has no reference)."""
        return est.dp, est.ie

    def law(self, est: Estimate, ref_dp: Value, ref_ie: Value) -> tuple[Value, Value]:
        """The phase machine's joint torques through the impedance actuation; the reference is unused
        (each phase has its own equilibrium)."""
        self.gains.advance()
        gait = self.gait
        if self.deferred is not None and gait.phase != self.deferred[0]:   # the daemon's only (no batch command)
            gait.set_phase_params(self.deferred[0], **self.deferred[1])
            self.deferred = None
        t0, t1 = gait.update(-est.sg_dp, est.dp, est.dp_vel, est.ie, est.ie_vel)
        return self.actuate(est, t0, t1, gait.k0, gait.k1, gait.b0, gait.b1)


def stance_torque(phase: int, params: Mapping[str, float], late_stance_angle: float) -> tuple[float, float]:
    """N m of DP joint torque a stance phase's spring asks for where the push-off loads it, and that
    angle (rad): the able-bodied stance's most dorsiflexed angle (WALKING_PEAK_DORSIFLEXION; late
    stance at least its entry angle ``late_stance_angle``, it only begins beyond it). The torque loop
    renders it on the wearer: the gauges read it and the motors must give it."""
    angle = WALKING_PEAK_DORSIFLEXION if phase == EARLY_STANCE else max(WALKING_PEAK_DORSIFLEXION, late_stance_angle)
    return abs(params["stiffness_dp"] * (angle - params["equilibrium_dp"])), angle


def stance_torque_limits(cfg: Mapping[str, Any]) -> dict[int, tuple[float, str]]:
    """Stance phase -> (N m, what): the most DP joint torque its spring may ask for at the push-off
    (:func:`stance_torque`). Both: below ``safety.sg_rail_nm``, or the gauges trip ``SG_RAIL`` on the
    wearer's push-off (the shipped 75 kg tuning on a 50 kg wearer's rail of 2 N m/kg, 100 N m: 101 N m
    rendered, ``SG_RAIL`` in the fourth stride at fast cadence; 30 kg: in the first). Late stance also
    within what both motors give at the peak current (:func:`ankle_rt.config_schema.dp_torque_at_peak`,
    224 N m nominal) less, with the joint-torque loop, the correction it may add (``max_correction_dp``, at most
    the device's 30 N m, ``MAX_CORRECTION_WALKED``): 194 N m shipped (at 300 N m/rad, equilibrium -0.55 rad: the 15 A clamp for up to 47 ms per stride,
    ``SG_RAIL`` at 100 kg in the first stride at fast cadence). Early stance hands the push-off over at
    ``late_stance_angle`` (its equilibrium at -0.3 rad under 400 N m/rad, 204 N m here, walks at up to
    13.7 A), so only the rail holds it."""
    rail = (float(cfg["safety"]["sg_rail_nm"]), "safety.sg_rail_nm: the gauges would trip SG_RAIL")
    # the correction the push-off leaves room for: the clamp, at most the device's (beyond it the corrections take
    # only what the peak current leaves beside the desired torque: JointTorqueLoop.fit)
    correction = min(cfg["controller"]["torque_loop"]["max_correction_dp"], MAX_CORRECTION_WALKED[0]) \
        if torque_feedback(cfg) else 0.0
    motors = (dp_torque_at_peak(cfg) - correction, "what both motors give at amplifier.current_limit_peak less "
              "controller.torque_loop.max_correction_dp (at most "
              f"{MAX_CORRECTION_WALKED[0]:g}): the push-off would hold the current clamp")
    return {EARLY_STANCE: rail, LATE_STANCE: min(rail, motors)}


def stance_stiffness_cap(cfg: Mapping[str, Any], phase: int) -> float:
    """N m/rad: the stiffest DP spring :func:`stance_torque_limits` allows a stance phase with ``cfg``'s
    equilibrium and late-stance entry angle (``bench walk`` caps a heavier wearer's scaled stiffness here)."""
    g = cfg["controller"]["gait_phase"]
    torque, _ = stance_torque(phase, {**g[PHASES[phase]], "stiffness_dp": 1.0}, g["late_stance_angle"])
    return stance_torque_limits(cfg)[phase][0] / torque if torque > 0.0 else math.inf


def heel_strike_hold_s(cfg: Mapping[str, Any]) -> float:
    """s the load must stay above ``load_on_nm`` for a heel strike: one period of the free foot's DP
    mode on the cables, 2 pi sqrt(foot.inertia_dp / k), with k the cable stiffness at the ankle at its
    -30 % bound (the longest period; 12 ms nominal). In swing the foot rings in that mode (+-5 N m at
    98 Hz after toe-off on the walking scenario), which averages out over a period: a load above
    ``load_on_nm`` for a whole period is the foot's smooth load, which lies below it in swing (its
    gravity moment and the swing's slow inertial torque), not a half-wave of the ring."""
    k = CABLE_STIFFNESS_LOW * float(Kinematics.from_params(TransmissionParams(**cfg["transmission"])).K[0, 0])
    return 2.0 * math.pi * math.sqrt(cfg["foot"]["inertia_dp"] / k)


WALK_ON_ENCODERS = ("; the joint-torque loop that walks on the joint encoders' rate is config/torque-loop-encoders-walk"
                    ".yaml (include it last), the one on the gauges config/torque-loop-walk.yaml (walk.yaml's)")


def phase_margin_config(cfg: Mapping[str, Any]) -> dict[str, Any]:
    """``cfg`` for the gain-margin model of the phase law, which takes the cable estimate of the ankle
    angle (:meth:`GaitPhaseController.angles`) whatever ``controller.impedance.angle_source`` says (a
    shallow copy: the config may be a controller's read-only view); every phase's (K, B) is checked on it
    (public: the torque-loop studies search loops against the same check)."""
    c = cfg["controller"]
    return {**cfg, "controller": {**c, "impedance": {**c["impedance"], "angle_source": "estimated"}}}
