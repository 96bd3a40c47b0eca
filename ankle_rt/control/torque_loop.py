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
- The measured torque is low-passed (first order at ``cutoff_hz``) so the loop rolls off well below
  the 77-98 Hz cable modes, whose damping ratio (~0.02) it must not eat.

Stability margins across cable stiffness +/- 30 % and the friction range come from the linear model:
:func:`ankle_rt.analysis.torque_loop_margins`. Everything per cycle is plain floats (no allocation)
for one device, arrays over the batch in the batched daemon cycle (:class:`JointTorqueLoop`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Mapping, Sequence

from ankle_rt.elementwise import Value, clip, select, stack
from ankle_rt.gain_margin import torque_feedback  # noqa: F401  (re-exported: its historical home)

if TYPE_CHECKING:
    import numpy as np

    from ankle_rt.config import Config

MIN_DAMPING_RATIO = 0.05        # of the rendered impedance against the reflected inertia / (1 + kp)
# [DP, IE] of the cable stiffness at the ankle: a series-elastic loop cannot render a stiffness near
# its spring's and stay stable. Where the linear margin checks hold with MIN_DAMPING_RATIO (DP: the
# impedance mode's frequency rises with K and the loop's lags eat its damping first).
MAX_STIFFNESS_FRACTION = (0.3, 0.5)


@dataclass(frozen=True)
class TorqueLoopGains:
    """Per-axis gains [DP, IE] of the joint-torque loop (ankle coordinates)."""

    kp: tuple[float, float]                  # N m per N m of torque error
    ki: tuple[float, float]                  # 1/s, integral of the torque error
    torque_rate: tuple[float, float]         # s, kd on the rate of the filtered measured torque
    cutoff_hz: float                         # first-order low-pass of the measured joint torque
    max_correction_nm: tuple[float, float]   # |kp e + ki int e - kd rate| at most this (anti-windup, fault bound)

    @classmethod
    def from_config(cls, c: Mapping[str, Any]) -> "TorqueLoopGains":
        """From ``controller.torque_loop``."""
        pair = lambda key: (float(c[key + "_dp"]), float(c[key + "_ie"]))  # noqa: E731
        return cls(kp=pair("kp"), ki=pair("ki"), torque_rate=pair("torque_rate"),
                   cutoff_hz=float(c["cutoff_hz"]), max_correction_nm=pair("max_correction"))


class JointTorqueLoop:
    """The loop of the module docstring for both ankle axes.

    Written element-wise (:mod:`ankle_rt.elementwise`): for one device its numbers are floats; for a
    batch of devices (:meth:`stack`, the batched daemon cycle) they are arrays over the batch and the
    same :meth:`update` runs once for all of them."""

    def __init__(self, gains: TorqueLoopGains, dt: float):
        self.gains = gains
        self.dt = dt
        self.set_gains(*gains.kp, *gains.ki, *gains.torque_rate)
        self.lim0, self.lim1 = gains.max_correction_nm
        self.alpha = 1.0 - math.exp(-2.0 * math.pi * gains.cutoff_hz * dt)
        self.f0 = self.f1 = self.i0 = self.i1 = 0.0
        self.reset_state(0.0, 0.0)

    def set_gains(self, kp0: Value, kp1: Value, ki0: Value, ki1: Value, rate0: Value, rate1: Value) -> None:
        """Per-axis kp, ki (1/s) and torque-rate gain (s) [DP, IE] from now on (a ramp's point; plain
        floats, no allocation). ``gains`` keeps the configured set."""
        dt = self.dt
        self.kp0, self.kp1 = kp0, kp1
        self.kidt0, self.kidt1 = ki0 * dt, ki1 * dt
        self.kdr0, self.kdr1 = rate0 / dt, rate1 / dt

    @classmethod
    def stack(cls, loops: Sequence["JointTorqueLoop"]) -> "JointTorqueLoop":
        """One loop standing for ``loops`` (one per device of a batch): gains and state become arrays
        over the batch (``gains``, descriptive only, is the first device's)."""
        return stack(loops, shared=("gains",))

    def reset_state(self, tau_dp: Value, tau_ie: Value, where: bool | np.ndarray = True) -> None:
        """Start from the measured torques (N m) with an empty integrator (on activation); for a
        batch, only where ``where`` (bool per device) holds."""
        self.f0 = select(where, tau_dp, self.f0)
        self.f1 = select(where, tau_ie, self.f1)
        self.i0 = select(where, 0.0, self.i0)
        self.i1 = select(where, 0.0, self.i1)

    def update(self, tau_dp: Value, tau_ie: Value, sg_dp: Value, sg_ie: Value,
               integrate: bool | np.ndarray) -> tuple[Value, Value]:
        """Desired joint torques and tared strain-gauge torques (N m, [DP, IE]) in, the ankle-side
        motor torques (N m, [DP, IE]) out. ``integrate`` False holds the integrator (soft start)."""
        a = self.alpha
        p0, p1 = self.f0, self.f1
        f0 = p0 + a * (sg_dp - p0)
        f1 = p1 + a * (sg_ie - p1)
        self.f0, self.f1 = f0, f1
        e0, e1 = tau_dp - f0, tau_ie - f1
        lim0, lim1 = self.lim0, self.lim1
        i0 = select(integrate, clip(self.i0 + self.kidt0 * e0, -lim0, lim0), self.i0)
        i1 = select(integrate, clip(self.i1 + self.kidt1 * e1, -lim1, lim1), self.i1)
        self.i0, self.i1 = i0, i1
        c0 = clip(self.kp0 * e0 + i0 - self.kdr0 * (f0 - p0), -lim0, lim0)
        c1 = clip(self.kp1 * e1 + i1 - self.kdr1 * (f1 - p1), -lim1, lim1)
        return tau_dp + c0, tau_ie + c1


@dataclass(frozen=True)
class ImpedanceLimits:
    """The impedances the closed loop renders stably, per ankle axis [DP, IE].

    With the foot free the loop is the reflected inertia J / (1 + kp) on the commanded spring, damped
    by B + D / (1 + kp), plus the integral. Two conditions keep it stable with a cycle of delay, half
    the identified viscous friction D and cable stiffness +-30 % (checked at their boundary with the
    linear model, tests/test_impedance_torque_loop.py):

    - the integral: c (1 + kp) >= 2 J ki, c = D / 2 + (1 + kp) B (the Routh condition, factor 2);
    - the rendered damping ratio (B + D / (2 (1 + kp))) / (2 sqrt(K J / (1 + kp))) >= MIN_DAMPING_RATIO;
    - K <= MAX_STIFFNESS_FRACTION x the cable stiffness at the ankle (0.3 DP, 0.5 IE).
    """

    inertia: tuple[float, float]          # kg m^2, reflected motor inertia R^T J R (diagonal)
    viscous: tuple[float, float]          # N m s/rad, reflected viscous friction R^T D R
    max_stiffness: tuple[float, float]    # N m/rad
    kp: tuple[float, float]
    ki: tuple[float, float]

    @classmethod
    def from_config(cls, cfg: "Config") -> "ImpedanceLimits":
        from ankle_rt.kinematics import Kinematics
        from ankle_rt.params import TransmissionParams

        kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
        col = [float(kin.R[0, a] ** 2 + kin.R[1, a] ** 2) for a in (0, 1)]
        a, tl = cfg["actuator"], cfg["controller"]["torque_loop"]
        return cls(inertia=(a["inertia"] * col[0], a["inertia"] * col[1]),
                   viscous=(a["damping"] * col[0], a["damping"] * col[1]),
                   max_stiffness=(MAX_STIFFNESS_FRACTION[0] * float(kin.K[0, 0]),
                                  MAX_STIFFNESS_FRACTION[1] * float(kin.K[1, 1])),
                   kp=(tl["kp_dp"], tl["kp_ie"]), ki=(tl["ki_dp"], tl["ki_ie"]))

    def min_damping(self, axis: int, stiffness: float) -> float:
        """N m s/rad: the least commanded damping for ``stiffness`` N m/rad on ``axis`` (0 DP, 1 IE)."""
        g, J, d = 1.0 + self.kp[axis], self.inertia[axis], self.viscous[axis] / (2.0 * (1.0 + self.kp[axis]))
        integral = 2.0 * J * self.ki[axis] / g ** 2
        ratio = 2.0 * MIN_DAMPING_RATIO * math.sqrt(stiffness * J / g)
        return max(0.0, max(integral, ratio) - d)

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

