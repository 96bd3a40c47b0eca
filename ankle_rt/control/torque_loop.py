"""Joint-torque feedback from the strain gauges: what makes the rendered impedance the commanded one.

Open loop, everything between the motor and the ankle (reflected motor inertia 1.9 / 0.6 kg m^2,
gearbox and Bowden-cable friction of several N m at the ankle, load-dependent cable friction) is felt
by the wearer on top of the commanded impedance. The strain gauges measure the joint torque the cables
deliver, so per ankle axis this loop drives the measured torque to the desired one:

    u = tau_des + kp e + ki integral(e) - kd d/dt LP(tau_sg)      e = tau_des - LP(tau_sg)

- ``tau_des`` (feed-forward) is the impedance law's joint torque; ``u`` is the ankle-side motor torque
  (mapped to the motors with R^-T by the caller).
- The integral removes the static error friction leaves (the rendered stiffness at standstill is then
  the commanded one); it is clamped, and so is the whole correction ``kp e + ki int(e) - kd d/dt
  LP(tau_sg)``, to ``max_correction_nm``: a wrong, frozen or glitching torque reading can add at
  most that torque (sensor faults that the safety layer sees -- rail, stale, jumps, NaN -- put the
  daemon into the safe state; see docs/daemon.md).
- ``kd`` on the rate of the measured torque damps the motor-on-cable mode (5-10 Hz with the foot held,
  as in stance), which the plain proportional loop makes unstable with a cycle of delay. It acts on
  the cable's stretch rate, not the motor velocity, so it adds no damping to the free motion the
  wearer feels. The integral is kept slow (``ki``): a fast one turns the reflected motor inertia into
  negative damping (the loop would not be passive).
- The measured torque is low-passed (first order at ``cutoff_hz``, or per axis ``cutoff_hz_dp`` /
  ``cutoff_hz_ie``) so the loop rolls off well below the 77-98 Hz cable modes, whose damping ratio
  (~0.02) it must not eat.
- The rate term differentiates the strain gauges' torque, or (``torque_rate_source: encoders``, with joint
  encoders) the cables' stretch torque K (R^-1 theta_m - theta_joint) on the configured cable, complemented
  below ``torque_rate_crossover_hz_dp/ie`` by the gauges' (which are right about the torque, not only its shape):
  the rate term is what turns the gauges' noise into current (its gain is ``torque_rate / dt`` on a white
  noise), and the encoders' counts are ~3x quieter in torque and not white at rest. A cable stiffer or softer
  than configured scales the term above the crossover, which the margin check's cable range covers. The
  stretch is believed only within ``torque_rate_agreement_nm`` of the filtered gauge torque: a slack cable
  or backlash shows a stretch with no torque behind it (0.2 mm of play: ~5 N m at the DP ankle), and a rate
  term on that phantom is a velocity feedback on the bare motor inertia far beyond the sampled loop's
  stability (kd K dt / J ~ 3); clipped there, the term follows the gauges' own rate (the gauge loop's
  behaviour). The clip bounds the state, not its step (``torque_rate / dt`` times up to twice the agreement),
  so a sample whose stretch leads the gauges by more than half the agreement beyond their low-passed offset
  (one bad joint-encoder sample: 0.1 mrad is 0.14 N m at the DP ankle) is skipped, the state held: at rest
  the lead is the gauges' noise. The linear model has the unclipped, ungated term (small signals).
- A **lag** (``lag_hz`` > 0, ``lag_boost`` > 1: (s + wz) / (s + wz / lag_boost), :class:`ankle_rt.lag.Lag`)
  before the notch raises the P and rate terms' gain below ``lag_hz`` only. A large boost makes the
  loop conditionally stable (stable at its gain, not at a smaller one, which the correction's clamp
  gives it at large amplitudes): the margin check scans smaller gains too and refuses it. Below its
  zero the lag integrates, so its state is held as the integral is while the correction is clamped
  (else it winds up behind the clamp and holds the correction there long after the error is gone).
- A **notch** (``notch_hz`` > 0, a second-order band-stop of width ``notch_zeta`` and gain
  ``notch_depth`` at ``notch_hz``) on ``kp e - kd d/dt LP(tau_sg)`` (not the integral) takes gain out
  of the loop at the free foot's cable mode only, so kp and kd may be larger below it (a smaller
  felt inertia J / (1 + kp)) with the same margin (benchmarks/study_torque_loop_shaping.py). It
  follows the configured cable: ``notch_hz`` is placed for ``notch_cable_stiffness`` and runs at
  x sqrt(transmission.cable_stiffness / notch_cable_stiffness) (:class:`ankle_rt.notch.Notch`).
- The integral is held while the correction is clamped and pushing the same way (conditional
  integration): a large, fast push no longer winds it up (the old loop rendered 9 N m/rad for a
  15 N m 2 Hz sine at K 200).

In motion the loop alone leaves J / (1 + kp), D / (1 + kp) and friction / (1 + kp) of the motor side
in what the wearer feels (the torque error is what accelerates the reflected motor inertia). A
**disturbance observer** (``dob_hz`` > 0) on the ankle-side motor coordinate q = R^-1 theta_m adds

    d = LP_dob(u_{k-1} - tau_sg - J_n (w_k - w_{k-1}) / dt)        w = R^-1 motor_vel

to ``u``: whatever the motor side does that a pure inertia J_n would not (friction, viscous, the
inertia beyond J_n = ``dob_inertia`` x R^T J R) is cancelled below ``dob_hz``, so the loop sees an
inertia J_n and the wearer J_n / (1 + kp). ``d`` is clamped to ``max_observer_nm`` (a wrong torque
reading moves it by at most that), and an **energy tank** keeps it passive: the tank is filled with
``tank_friction_credit`` x the energy the identified motor friction dissipates (Fc |w| + D w^2) and
drained by what the observer puts in (d w); empty, the observer may only brake (d w <= 0). So the
observer never gives the wearer more energy than the physical friction it cancels takes out, plus
the tank's ``tank_j``.

Stability margins across cable stiffness +/- 30 % and the friction range come from the linear model:
:func:`ankle_rt.analysis.torque_loop_margins`. Everything per cycle is plain floats (no allocation)
for one device, arrays over the batch in the batched daemon cycle (:class:`JointTorqueLoop`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping, Sequence

from ankle_rt.config_schema import torque_loop_cutoffs
from ankle_rt.elementwise import Value, clip, minimum, positive_part, select, stack
from ankle_rt.lag import Lag
from ankle_rt.lead import loop_lag
from ankle_rt.loop_setup import ReflectedActuator, rate_from_encoders
from ankle_rt.notch import Notch

if TYPE_CHECKING:
    import numpy as np

    from ankle_rt.config import Config

# of torque_rate_agreement_nm: how far one sample of the cables' stretch may lead the gauges beyond its low-passed
# offset and be believed (the encoder rate source). The lead is the gauges' noise at rest (0.02 N m RMS): half
# the shipped agreement is 2.5 of it, 1.5-1.8 % of the samples skipped; a skipped sample holds the state.
SAMPLE_GATE = 0.5
MIN_DAMPING_RATIO = 0.05        # of the rendered impedance against the reflected inertia / (1 + kp)
# [DP, IE] of the cable stiffness at the ankle: a series-elastic loop cannot render a stiffness near
# its spring's and stay stable. Where the linear margin checks hold with MIN_DAMPING_RATIO (DP: the
# impedance mode's frequency rises with K and the loop's lags eat its damping first).
MAX_STIFFNESS_FRACTION = (0.3, 0.5)


@dataclass(frozen=True)
class TorqueLoopGains:
    """Per-axis gains [DP, IE] of the joint-torque loop (ankle coordinates). No defaults here: the shipped
    values are the config schema's (``controller.torque_loop``), read by :meth:`from_config`."""

    kp: tuple[float, float]                  # N m per N m of torque error
    ki: tuple[float, float]                  # 1/s, integral of the torque error
    torque_rate: tuple[float, float]         # s, kd on the rate of the filtered measured torque
    cutoff_hz: tuple[float, float]           # first-order low-pass of the measured joint torque
    max_correction_nm: tuple[float, float]   # |kp e + ki int e - kd rate| at most this (anti-windup, fault bound)
    dob_hz: float                            # disturbance observer's low-pass; 0: no observer
    dob_inertia: tuple[float, float]         # J_n as a fraction of the reflected motor inertia
    max_observer_nm: tuple[float, float]     # |d| at most this
    tank_j: float                            # J, the energy tank's capacity
    tank_friction_credit: float              # share of the identified friction's dissipation the tank gets
    notch: Notch                             # band-stops on the P and rate terms, on the configured cable
    notch2: Notch                            # the second band-stops, after the first
    rate_damping: tuple[float, float]        # N m s/rad, on the high-passed ankle-side motor rate
    rate_damping_hz: tuple[float, float]     # Hz, that high-pass's corner
    lag: Lag                                 # low-frequency boosts on the P and rate terms, before the notch
    rate_from_encoders: bool                 # the rate terms on the cables' stretch torque (else the gauges')
    rate_crossover_hz: tuple[float, float]   # ... with the gauges' below this (Hz)
    rate_agreement_nm: float                 # ... and within this of the filtered gauge torque

    @classmethod
    def from_config(cls, c: Mapping[str, Any], cable_stiffness: float) -> "TorqueLoopGains":
        """From ``controller.torque_loop``, the notches moved to the cable of ``cable_stiffness`` N/m
        (``transmission.cable_stiffness``; :meth:`ankle_rt.notch.Notch.from_config`)."""
        pair = lambda key: (float(c[key + "_dp"]), float(c[key + "_ie"]))  # noqa: E731
        return cls(kp=pair("kp"), ki=pair("ki"), torque_rate=pair("torque_rate"),
                   cutoff_hz=torque_loop_cutoffs(c), max_correction_nm=pair("max_correction"),
                   dob_hz=float(c["dob_hz"]), dob_inertia=pair("dob_inertia"), max_observer_nm=pair("max_observer"),
                   tank_j=float(c["tank_j"]), tank_friction_credit=float(c["tank_friction_credit"]),
                   notch=Notch.from_config(c, cable_stiffness), notch2=Notch.from_config(c, cable_stiffness, "notch2"),
                   rate_damping=pair("motor_rate_damping"), rate_damping_hz=pair("motor_rate_damping_hz"),
                   lag=Lag.from_config(c), rate_from_encoders=rate_from_encoders(c),
                   rate_crossover_hz=pair("torque_rate_crossover_hz"),
                   rate_agreement_nm=float(c["torque_rate_agreement_nm"]))


class JointTorqueLoop:
    """The loop of the module docstring for both ankle axes.

    Written element-wise (:mod:`ankle_rt.elementwise`): for one device its numbers are floats; for a
    batch of devices (:meth:`stack`, the batched daemon cycle) they are arrays over the batch and the
    same :meth:`update` runs once for all of them."""

    def __init__(self, gains: TorqueLoopGains, dt: float, actuator: ReflectedActuator | None = None,
                 motor_limit: float = math.inf):
        """``actuator``: needed with the observer (``gains.dob_hz`` > 0). ``motor_limit``: N m per motor at
        the gearbox output, its torque at the peak current (the caller fits the corrections in it, :meth:`fit`)."""
        self.gains = gains
        self.dt = dt
        self.motor_limit = motor_limit
        self.set_gains(*gains.kp, *gains.ki, *gains.torque_rate)
        self.lim0, self.lim1 = gains.max_correction_nm
        self.alpha0, self.alpha1 = (1.0 - math.exp(-2.0 * math.pi * f * dt) for f in gains.cutoff_hz)
        self.rd0, self.rd1 = gains.rate_damping
        self.ar0, self.ar1 = (1.0 - math.exp(-2.0 * math.pi * f * dt) for f in gains.rate_damping_hz)
        self.lag0, self.lag1 = gains.lag.sections(dt)            # (b0, b1, b2, a1, a2) per axis
        # a bool (a bool array over a batch that mixes sources): the rate terms on the cables' stretch
        self.encoder_rate = gains.rate_from_encoders
        self.ab0, self.ab1 = (1.0 - math.exp(-2.0 * math.pi * f * dt) for f in gains.rate_crossover_hz)
        self.agree = gains.rate_agreement_nm
        self.gate = SAMPLE_GATE * gains.rate_agreement_nm
        # a bool (a bool array over a batch that mixes lags): the cycle runs the lag only where one is on
        self.lagged = any(gains.lag.on)
        self.notch0, self.notch1 = gains.notch.sections(dt)
        self.second0, self.second1 = gains.notch2.sections(dt)
        on = gains.dob_hz > 0.0
        if on and actuator is None:
            raise ValueError("JointTorqueLoop: the disturbance observer needs the reflected actuator")
        self.observer = on        # a bool: equal over a stacked batch (stack refuses a mix)
        self.ad = 1.0 - math.exp(-2.0 * math.pi * gains.dob_hz * dt) if on else 0.0
        jn = [gains.dob_inertia[a] * actuator.inertia[a] / dt if on else 0.0 for a in (0, 1)]
        self.jn0, self.jn1 = jn
        self.dlim0, self.dlim1 = gains.max_observer_nm if on else (0.0, 0.0)
        self.tank_max = gains.tank_j
        credit = gains.tank_friction_credit * dt
        self.cc0, self.cc1 = (credit * actuator.coulomb[0], credit * actuator.coulomb[1]) if on else (0.0, 0.0)
        self.cv0, self.cv1 = (credit * actuator.viscous[0], credit * actuator.viscous[1]) if on else (0.0, 0.0)
        self.f0 = self.f1 = self.i0 = self.i1 = 0.0
        self.d0 = self.d1 = self.u0 = self.u1 = self.w0 = self.w1 = 0.0
        self.e0 = self.e1 = 0.0
        self.s0 = self.s1 = self.b0 = self.b1 = 0.0     # the filtered rate torque, the gauges' lead over the stretch
        self.n01 = self.n02 = self.n11 = self.n12 = 0.0
        self.m01 = self.m02 = self.m11 = self.m12 = 0.0
        self.g01 = self.g11 = 0.0
        self.r0 = self.r1 = 0.0                         # the motor rates' low-pass (the high-pass is w - r)
        self.c0 = self.c1 = 0.0                         # this cycle's corrections (N m), for fit
        self.held_i0 = self.held_i1 = self.held_g01 = self.held_g11 = 0.0   # the states fit falls back to
        self.reset_state(0.0, 0.0)

    def set_gains(self, kp0: Value, kp1: Value, ki0: Value, ki1: Value, rate0: Value, rate1: Value) -> None:
        """Per-axis kp, ki (1/s) and torque-rate gain (s) [DP, IE] from now on (a ramp's point; plain
        floats, no allocation). ``gains`` keeps the configured set."""
        dt = self.dt
        self.kp0, self.kp1 = kp0, kp1
        self.kidt0, self.kidt1 = ki0 * dt, ki1 * dt
        self.kdr0, self.kdr1 = rate0 / dt, rate1 / dt

    @property
    def lag_s(self) -> tuple[Value, Value]:
        """s [DP, IE]: the loop follows a desired torque as tau_des / (1 + s lag) (:func:`ankle_rt.lead.loop_lag`:
        the rate term acts on the measured torque, the filter's delay takes some of it back), a lag that turns
        a commanded stiffness K into K lag of negative damping (-0.86 N m s/rad at K_ie 100 with the classic
        loop: the IE ankle gave energy back at 2 Hz). The impedance law leads it (:func:`ankle_rt.lead.law_damping`)."""
        dt = self.dt
        return (loop_lag(self.kp0, self.kdr0 * dt, self.alpha0, dt), loop_lag(self.kp1, self.kdr1 * dt, self.alpha1, dt))

    @classmethod
    def stack(cls, loops: Sequence["JointTorqueLoop"]) -> "JointTorqueLoop":
        """One loop standing for ``loops`` (one per device of a batch): gains and state become arrays
        over the batch (``gains``, descriptive only, is the first device's)."""
        return stack(loops, shared=("gains",), columns=("lag0", "lag1", "notch0", "notch1", "second0", "second1"))

    def reset_state(self, tau_dp: Value, tau_ie: Value, w_dp: Value = 0.0, w_ie: Value = 0.0,
                    where: bool | np.ndarray = True, stretch_dp: Value = 0.0, stretch_ie: Value = 0.0) -> None:
        """Start from the measured torques (N m), the ankle-side motor rates ``w`` (rad/s, what
        :meth:`update` is given) and the stretch torques (N m, with the encoder rate source) with an empty
        integrator (on activation); for a batch, only where ``where`` (bool per device) holds. The observer
        differences the rate from the last cycle: a rate left from before a deactivation would read as a
        disturbance J_n dw/dt on activation."""
        self.f0 = select(where, tau_dp, self.f0)
        self.f1 = select(where, tau_ie, self.f1)
        self.s0 = select(where, tau_dp, self.s0)
        self.s1 = select(where, tau_ie, self.s1)
        self.b0 = select(where, tau_dp - stretch_dp, self.b0)      # the stretch's offset: no rate on activation
        self.b1 = select(where, tau_ie - stretch_ie, self.b1)
        self.i0 = select(where, 0.0, self.i0)
        self.i1 = select(where, 0.0, self.i1)
        self.d0 = select(where, 0.0, self.d0)
        self.d1 = select(where, 0.0, self.d1)
        self.w0 = select(where, w_dp, self.w0)
        self.w1 = select(where, w_ie, self.w1)
        self.r0 = select(where, w_dp, self.r0)        # a steady rate is no damping's business
        self.r1 = select(where, w_ie, self.r1)
        self.u0 = select(where, tau_dp, self.u0)     # at rest the motors hold the cable torque
        self.u1 = select(where, tau_ie, self.u1)
        self.e0 = select(where, self.tank_max, self.e0)
        self.e1 = select(where, self.tank_max, self.e1)
        self.n01 = select(where, 0.0, self.n01)
        self.n02 = select(where, 0.0, self.n02)
        self.n11 = select(where, 0.0, self.n11)
        self.n12 = select(where, 0.0, self.n12)
        self.m01 = select(where, 0.0, self.m01)
        self.m02 = select(where, 0.0, self.m02)
        self.m11 = select(where, 0.0, self.m11)
        self.m12 = select(where, 0.0, self.m12)
        self.g01 = select(where, 0.0, self.g01)
        self.g11 = select(where, 0.0, self.g11)

    def update(self, tau_dp: Value, tau_ie: Value, sg_dp: Value, sg_ie: Value, w_dp: Value, w_ie: Value,
               integrate: bool | np.ndarray, stretch_dp: Value = 0.0, stretch_ie: Value = 0.0) -> tuple[Value, Value]:
        """Desired joint torques and tared strain-gauge torques (N m, [DP, IE]) and the ankle-side
        motor rates R^-1 motor_vel (rad/s) in, the ankle-side motor torques (N m, [DP, IE]) out.
        ``integrate`` False holds the integrator and keeps the observer out (soft start). ``stretch``: N m,
        the cables' stretch torques K (R^-1 theta_m - theta_joint), read with the encoder rate source only."""
        p0, p1 = self.f0, self.f1
        f0 = p0 + self.alpha0 * (sg_dp - p0)
        f1 = p1 + self.alpha1 * (sg_ie - p1)
        self.f0, self.f1 = f0, f1
        e0, e1 = tau_dp - f0, tau_ie - f1
        step0, step1 = f0 - p0, f1 - p1    # the rate terms' torque step this cycle
        encoders = self.encoder_rate
        if encoders is not False:          # the stretch, complemented below the crossover by the gauges
            # its lead over the gauges beyond the low-passed offset b: a sample leading by more than the gate
            # (one bad joint sample) is skipped, the state held, and moves b by the gate's worth at most
            gate, agree = self.gate, self.agree
            lead0 = stretch_dp - sg_dp + self.b0
            lead1 = stretch_ie - sg_ie + self.b1
            self.b0 = b0 = self.b0 - self.ab0 * clip(lead0, -gate, gate)
            self.b1 = b1 = self.b1 - self.ab1 * clip(lead1, -gate, gate)
            q0, q1 = self.s0, self.s1
            s0 = select(abs(lead0) <= gate, q0 + self.alpha0 * (stretch_dp + b0 - q0), q0)
            s1 = select(abs(lead1) <= gate, q1 + self.alpha1 * (stretch_ie + b1 - q1), q1)
            self.s0 = s0 = clip(s0, f0 - agree, f0 + agree)
            self.s1 = s1 = clip(s1, f1 - agree, f1 + agree)
            step0, step1 = select(encoders, s0 - q0, step0), select(encoders, s1 - q1, step1)
        # the lag, then the notches on the P and rate terms (the identity without one)
        x0, x1 = self.kp0 * e0 - self.kdr0 * step0, self.kp1 * e1 - self.kdr1 * step1
        lagged = self.lagged is not False
        if lagged:
            x0, g01, _ = _section(self.lag0, x0, self.g01, 0.0)
            x1, g11, _ = _section(self.lag1, x1, self.g11, 0.0)
        pd0, self.n01, self.n02 = _section(self.notch0, x0, self.n01, self.n02)
        pd1, self.n11, self.n12 = _section(self.notch1, x1, self.n11, self.n12)
        pd0, self.m01, self.m02 = _section(self.second0, pd0, self.m01, self.m02)
        pd1, self.m11, self.m12 = _section(self.second1, pd1, self.m11, self.m12)
        # the motor-rate damping on the rate's high-pass, beside the shaped terms (not through the notches)
        self.r0 = r0 = self.r0 + self.ar0 * (w_dp - self.r0)
        self.r1 = r1 = self.r1 + self.ar1 * (w_ie - self.r1)
        pd0 = pd0 - self.rd0 * (w_dp - r0)
        pd1 = pd1 - self.rd1 * (w_ie - r1)
        c0, i0 = self._correction(e0, pd0, self.i0 + self.kidt0 * e0, self.i0, self.lim0, integrate)
        c1, i1 = self._correction(e1, pd1, self.i1 + self.kidt1 * e1, self.i1, self.lim1, integrate)
        self.held_i0, self.held_i1, self.held_g01, self.held_g11 = self.i0, self.i1, self.g01, self.g11
        self.i0, self.i1 = i0, i1
        if lagged:
            self.g01 = self._lag_state(self.g01, g01, c0, self.lim0)
            self.g11 = self._lag_state(self.g11, g11, c1, self.lim1)
        self.c0, self.c1 = c0, c1
        u0 = tau_dp + c0 + self._observe(0, sg_dp, w_dp, integrate)
        u1 = tau_ie + c1 + self._observe(1, sg_ie, w_ie, integrate)
        self.u0, self.u1 = u0, u1
        return u0, u1

    def fit(self, scale: Value) -> tuple[Value, Value]:
        """This cycle's outputs with both corrections scaled by ``scale`` (0-1: what the motors' peak
        current leaves beside the desired torque, :func:`correction_room`), and where scaled the
        integrators and lags kept at their last states: conditional integration against the actuator,
        not only against ``max_correction`` (at the current clamp they would wind up behind it)."""
        cut = 1.0 - scale
        short = cut > 0.0
        self.u0 = self.u0 - cut * self.c0
        self.u1 = self.u1 - cut * self.c1
        self.c0, self.c1 = scale * self.c0, scale * self.c1
        self.i0 = select(short, self.held_i0, self.i0)
        self.i1 = select(short, self.held_i1, self.i1)
        self.g01 = select(short, self.held_g01, self.g01)
        self.g11 = select(short, self.held_g11, self.g11)
        return self.u0, self.u1

    @staticmethod
    def _correction(e: Value, pd: Value, i_new: Value, i_old: Value, lim: Value,
                    integrate: bool | np.ndarray) -> tuple[Value, Value]:
        """The clamped correction and the integrator: it grows only while the correction is not
        clamped in the direction of the error (conditional integration)."""
        i_new = clip(i_new, -lim, lim)
        raw = pd + i_new
        wind = ((raw > lim) & (e > 0.0)) | ((raw < -lim) & (e < 0.0))
        i = select(integrate, select(wind, i_old, i_new), i_old)
        return clip(pd + i, -lim, lim), i

    @staticmethod
    def _lag_state(s_old: Value, s_new: Value, c: Value, lim: Value) -> Value:
        """The lag's next state, held where the correction is at its clamp and the state would push it
        further: below its zero the lag integrates (its boost is an integral's gain), and unheld it winds
        up to lag_boost x kp x the error behind a clamp it cannot pass, then holds the correction there
        until it has leaked away (lag_hz 0.05, lag_boost 10: 20 s after a 30 s one-sided error;
        conditional integration, as the integral's)."""
        wind = ((c >= lim) & (s_new > s_old)) | ((c <= -lim) & (s_new < s_old))
        return select(wind, s_old, s_new)

    def _observe(self, axis: int, sg: Value, w: Value, integrate: bool | np.ndarray) -> Value:
        """The observer's torque on ``axis`` (0 DP, 1 IE), tank-guarded; 0 without an observer."""
        if not self.observer:
            return 0.0
        if axis == 0:
            d, u, w_prev, jn, lim, tank, cc, cv = self.d0, self.u0, self.w0, self.jn0, self.dlim0, self.e0, self.cc0, self.cv0
        else:
            d, u, w_prev, jn, lim, tank, cc, cv = self.d1, self.u1, self.w1, self.jn1, self.dlim1, self.e1, self.cc1, self.cv1
        d = d + self.ad * (u - sg - jn * (w - w_prev) - d)
        out = select(integrate, clip(d, -lim, lim), 0.0)
        # the tank: credit from the friction the observer cancels, debit what it puts in
        power = out * w
        out = select((tank > 0.0) | (power <= 0.0), out, 0.0)
        tank = clip(tank + cc * abs(w) + cv * w * w - self.dt * out * w, 0.0, self.tank_max)
        if axis == 0:
            self.d0, self.w0, self.e0 = d, w, tank
        else:
            self.d1, self.w1, self.e1 = d, w, tank
        return out


def correction_room(total: Value, correction: Value, limit: Value) -> Value:
    """The share (0-1) of a motor's ``correction`` (N m) that fits: the motor torque ``total`` (N m, the
    correction included) kept within +-``limit`` (its torque at the peak current) by taking back only
    the part of the correction that pushes it beyond. 1 where it fits or pulls back, 0 where the rest
    alone is beyond (the current clamp's job then; the desired torque keeps the motors first)."""
    over = positive_part(abs(total) - limit)
    pushing = select(total * correction > 0.0, abs(correction), 0.0)
    return 1.0 - minimum(over, pushing) / (pushing + (pushing == 0.0))


def _section(c: tuple[float, ...], x: Value, s1: Value, s2: Value) -> tuple[Value, Value, Value]:
    """One second-order section ``c`` = (b0, b1, b2, a1, a2) in direct form II transposed: its output
    for the input ``x`` and its next states from ``s1``, ``s2`` (a first-order one keeps s2 at 0)."""
    b0, b1, b2, a1, a2 = c
    y = b0 * x + s1
    return y, b1 * x - a1 * y + s2, b2 * x - a2 * y


@dataclass(frozen=True)
class ImpedanceLimits:
    """The impedances the closed loop renders stably, per ankle axis [DP, IE].

    With the foot free the loop is the reflected inertia J / (1 + kp) on the commanded spring, damped
    by B + D / (1 + kp), plus the integral. Two conditions keep it stable with a cycle of delay, half
    the identified viscous friction D and cable stiffness +-30 % (checked at their boundary with the
    linear model, tests/test_impedance_torque_loop.py):

    - the integral: c (1 + kp) >= 2 J ki, c = D / 2 + (1 + kp) B (the Routh condition, factor 2);
    - the rendered damping ratio (B + D / (2 (1 + kp))) / (2 sqrt(K J / (1 + kp))) >= MIN_DAMPING_RATIO;
    - B counts the law's lead K kd / (1 + kp) on top of the commanded: the law damps the motor rate with at
      least B + K lag (ankle_rt.lead.law_damping), and the motor's damping is what the conditions need
      (the ankle renders B: the loop's lag takes the lead back at the ankle, not at the motor);
    - K <= MAX_STIFFNESS_FRACTION x the cable stiffness at the ankle (0.3 DP, 0.5 IE).
    """

    inertia: tuple[float, float]          # kg m^2, reflected motor inertia R^T J R (diagonal)
    viscous: tuple[float, float]          # N m s/rad, reflected viscous friction R^T D R
    max_stiffness: tuple[float, float]    # N m/rad
    kp: tuple[float, float]
    ki: tuple[float, float]
    lag: tuple[float, float] = (0.0, 0.0)    # s, kd / (1 + kp): the law adds K lag of damping on the motor rate

    @classmethod
    def from_config(cls, cfg: "Config") -> "ImpedanceLimits":
        from ankle_rt.kinematics import Kinematics
        from ankle_rt.params import TransmissionParams

        kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
        act, tl = ReflectedActuator.from_config(cfg), cfg["controller"]["torque_loop"]
        # with the observer the loop sees its nominal inertia and no viscous friction (it cancels it)
        dob = tl["dob_hz"] > 0.0
        inertia = tuple(act.inertia[a] * (tl[f"dob_inertia_{n}"] if dob else 1.0) for a, n in enumerate(("dp", "ie")))
        return cls(inertia=inertia, viscous=(0.0, 0.0) if dob else act.viscous,
                   max_stiffness=(MAX_STIFFNESS_FRACTION[0] * float(kin.K[0, 0]),
                                  MAX_STIFFNESS_FRACTION[1] * float(kin.K[1, 1])),
                   kp=(tl["kp_dp"], tl["kp_ie"]), ki=(tl["ki_dp"], tl["ki_ie"]),
                   lag=(tl["torque_rate_dp"] / (1.0 + tl["kp_dp"]), tl["torque_rate_ie"] / (1.0 + tl["kp_ie"])))

    def min_damping(self, axis: int, stiffness: float) -> float:
        """N m s/rad: the least commanded damping for ``stiffness`` N m/rad on ``axis`` (0 DP, 1 IE)."""
        g, J, d = 1.0 + self.kp[axis], self.inertia[axis], self.viscous[axis] / (2.0 * (1.0 + self.kp[axis]))
        integral = 2.0 * J * self.ki[axis] / g ** 2
        ratio = 2.0 * MIN_DAMPING_RATIO * math.sqrt(stiffness * J / g)
        return max(0.0, max(integral, ratio) - d - stiffness * self.lag[axis])

    def check(self, gains: Mapping[str, float]) -> tuple[str, str] | None:
        """(gain name, reason) for the first impedance gain outside the stable set, None if all fit."""
        for axis, name in enumerate(("dp", "ie")):
            k, b = gains[f"stiffness_{name}"], gains[f"damping_{name}"]
            if k > self.max_stiffness[axis]:
                return (f"stiffness_{name}", f"stiffness_{name} {k:g} N m/rad is above {self.max_stiffness[axis]:.0f}, "
                        f"the most the joint-torque loop renders stably ({MAX_STIFFNESS_FRACTION[axis]:g} x the cable stiffness)")
            need = self.min_damping(axis, k)
            if b < need:
                return (f"damping_{name}", f"damping_{name} {b:g} N m s/rad is below {need:.3g}, the least the "
                        f"joint-torque loop needs with stiffness_{name} {k:g} (docs/daemon.md)")
        return None
