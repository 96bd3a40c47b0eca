"""Strain gauges cross-checked against the motors: a gauge that is stuck, drifting, wired with its
sign flipped or stepping towards its rail reads a joint torque the motors are not delivering.

The motors tell what reaches the ankle: per motor the cable torque is the motor torque (set value x
torque constant, gearbox output) less what the motor's own inertia and viscous friction take,
``c = tau_m - J a - D v``, and the ankle sees ``R^T c`` (the controller's ``tau_m = R^-T u``
inverted). The difference from the gauge torque, low-passed at ``cutoff_hz`` (the estimate's
acceleration noise and the cable modes are far above it), is the residual. What the model leaves
out bounds how large a healthy residual can be: the Coulomb friction both motors put on an axis
(kc, not subtracted: its sign is unknown at standstill) and the load-dependent cable friction and
model errors, ``tolerance_fraction`` of each motor's cable torque mapped to the axis (|R|^T |c|: a
heavy DP load loads both motors, so it widens the IE tolerance too); ``tolerance_nm`` adds margin.
A residual beyond it for ``hold_s`` on either axis is the fault.

An actuation delay between set value and motor torque (amplifier, bus, a serial bridge) makes the
motors deliver an earlier set value than this cycle's: on a large step the prediction runs ahead of
the gauges by the whole step for that long. Up to ``max_delay_s`` of it is allowed for: the motor
torque's share of the prediction on each axis, kept for the last ``max_delay_s`` in a preallocated
ring, spans an interval, and the mismatch is the gauge's distance from it (zero inside). While the
set values hold still the interval is one point and the check is the undelayed one; a gauge going
bad is seen as soon as it leaves what any delay in the window could explain.

Written element-wise (:mod:`ankle_rt.elementwise`): plain floats per cycle for the daemon (no
allocation), arrays over a batch of devices for the batched cycle.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

from ankle_rt.elementwise import Value, any_true, fill, outside, select, stack

if TYPE_CHECKING:
    import numpy as np

CUTOFF_HZ = 5.0            # residual low-pass
TOLERANCE_NM = 6.0         # N m at the ankle, above the motors' Coulomb friction on the axis
TOLERANCE_FRACTION = 0.3   # of |c|: load-dependent cable friction (0.12 identified) and model errors
HOLD_S = 0.04              # s the residual must stay beyond the tolerance (0.05 missed a 57 N m spike
                           # held 20 ms under the shipped loop, whose rebound ended the residual at 47 ms)
FAST_CUTOFF_HZ = 20.0      # the fast residual: a gauge stepped far off trips at once (no hold)
FAST_TOLERANCE_NM = 12.0   # N m above the slow residual's tolerance
FAST_HOLD_S = 0.04         # s the fast residual must stay beyond it (an actuation lag the model leaves
                           # out makes a torque step look like a mismatch for about that long)


class GaugeCrossCheck:
    """The residual of the module docstring for both ankle axes [DP, IE]."""

    def __init__(self, dt: float, R: Sequence[Sequence[float]], inertia: float, viscous: float, coulomb: float,
                 velocity_cutoff_hz: float, *, cutoff_hz: float = CUTOFF_HZ, tolerance_nm: float = TOLERANCE_NM,
                 tolerance_fraction: float = TOLERANCE_FRACTION, hold_s: float = HOLD_S, max_delay_s: float = 0.0):
        """``R``: theta_m = R theta (2x2); ``inertia`` (kg m^2), ``viscous`` (N m s/rad), ``coulomb``
        (N m): one motor's, at the gearbox output. ``velocity_cutoff_hz``: the estimator's motor
        velocity low-pass, which the motor torque goes through too (the same lag on both sides of
        ``c = tau_m - J a - D v``: a torque step is not read as a mismatch while a lags).
        ``max_delay_s``: the actuation delay allowed for, beyond the one cycle modelled."""
        self.dt = dt
        # rings of the motor torques' share of each axis's torque (N m), low-passed slow (s) and fast
        # (e), this cycle's and the last max_delay_s worth (a fractional delay lies between two whole
        # cycles: both are kept); head: the slot this cycle writes
        slots = math.ceil(max_delay_s / dt - 1e-9) + 1
        self.s0, self.s1, self.e0, self.e1 = ([0.0] * slots for _ in range(4))
        self.slots, self.head = slots, 0
        self.r00, self.r01, self.r10, self.r11 = float(R[0][0]), float(R[0][1]), float(R[1][0]), float(R[1][1])
        self.inertia_dt = inertia / dt
        self.viscous = viscous
        self.a = 1.0 - math.exp(-2.0 * math.pi * cutoff_hz * dt)
        self.af = 1.0 - math.exp(-2.0 * math.pi * FAST_CUTOFF_HZ * dt)
        self.av = 1.0 - math.exp(-2.0 * math.pi * velocity_cutoff_hz * dt)
        # |R| maps per-motor torque magnitudes to what they can do on each axis
        self.q00, self.q01, self.q10, self.q11 = abs(self.r00), abs(self.r01), abs(self.r10), abs(self.r11)
        # the motors' Coulomb friction as seen on each axis (|R|^T kc), plus the margin
        self.base0 = coulomb * (self.q00 + self.q10) + tolerance_nm
        self.base1 = coulomb * (self.q01 + self.q11) + tolerance_nm
        self.fraction = tolerance_fraction
        self.hold = hold_s
        self.reset(0.0, 0.0)

    @classmethod
    def stack(cls, checks: Sequence["GaugeCrossCheck"]) -> "GaugeCrossCheck":
        """One cross-check standing for ``checks`` (one per device of a batch): numbers as arrays."""
        return stack(checks, shared=("dt", "slots", "head"), tables=("s0", "s1", "e0", "e1"))

    def reset(self, v0: Value, v1: Value, where: bool | np.ndarray = True) -> None:
        """Start over (on activation) from the motor velocities (rad/s) of this cycle; for a batch,
        only where ``where`` (bool per device) holds."""
        self.v0 = select(where, v0, getattr(self, "v0", 0.0))
        self.v1 = select(where, v1, getattr(self, "v1", 0.0))
        for ring in (self.s0, self.s1, self.e0, self.e1):
            fill(ring, 0.0, where)
        # N m: motor torques low-passed like the velocity (u), the previous cycle's (p), the gauge side
        # [DP, IE] low-passed slow and fast (g, h), each motor's low-passed cable torque (c); s the slow
        # and the fast residual have been beyond their tolerances
        for name in ("u0", "u1", "p0", "p1", "g0", "g1", "h0", "h1", "c0", "c1", "beyond", "fast_beyond"):
            setattr(self, name, select(where, 0.0, getattr(self, name, 0.0)))

    def update(self, tau_m0: Value, tau_m1: Value, v0: Value, v1: Value, sg_dp: Value, sg_ie: Value) -> Value:
        """This cycle's motor torques (N m, set values x torque constant), motor velocities (rad/s)
        and gauge torques (N m [DP, IE]); True (per device) once the gauge has disagreed for
        ``hold_s`` or far off at once. The velocities show the torques of the previous cycle."""
        av = self.av
        self.u0 = u0 = self.u0 + av * (self.p0 - self.u0)
        self.u1 = u1 = self.u1 + av * (self.p1 - self.u1)
        self.p0, self.p1 = tau_m0, tau_m1
        r00, r01, r10, r11 = self.r00, self.r01, self.r10, self.r11
        jdt, d = self.inertia_dt, self.viscous
        l0 = jdt * (v0 - self.v0) + d * v0          # what each motor's inertia and viscous friction take
        l1 = jdt * (v1 - self.v1) + d * v1
        c0, c1 = u0 - l0, u1 - l1
        self.v0, self.v1 = v0 + 0.0, v1 + 0.0    # copies: a batch's estimator updates its arrays in place
        a, af = self.a, self.af
        # the gauge torque plus the motors' own load: what the (delayed) motor torques must explain,
        # and the motor torques' share of each axis, both low-passed slow and fast (the filters are
        # linear: a delayed prediction filtered is the filtered prediction delayed, kept in the rings)
        y0 = sg_dp + (r00 * l0 + r10 * l1)
        y1 = sg_ie + (r01 * l0 + r11 * l1)
        x0 = r00 * u0 + r10 * u1
        x1 = r01 * u0 + r11 * u1
        self.g0 = g0 = self.g0 + a * (y0 - self.g0)
        self.g1 = g1 = self.g1 + a * (y1 - self.g1)
        self.h0 = h0 = self.h0 + af * (y0 - self.h0)
        self.h1 = h1 = self.h1 + af * (y1 - self.h1)
        head = self.head
        last = head - 1                              # the previous slot (-1: the ring's end)
        s0, s1, e0, e1 = self.s0, self.s1, self.e0, self.e1
        p0, p1, q0, q1 = s0[last], s1[last], e0[last], e1[last]
        s0[head] = p0 = p0 + a * (x0 - p0)
        s1[head] = p1 = p1 + a * (x1 - p1)
        e0[head] = q0 = q0 + af * (x0 - q0)
        e1[head] = q1 = q1 + af * (x1 - q1)
        self.head = head + 1 if head + 1 < self.slots else 0
        self.c0 = m0 = self.c0 + af * (c0 - self.c0)
        self.c1 = m1 = self.c1 + af * (c1 - self.c1)
        m0, m1 = abs(m0), abs(m1)                  # abs: floats and arrays alike
        f = self.fraction
        tol0 = self.base0 + f * (self.q00 * m0 + self.q10 * m1)
        tol1 = self.base1 + f * (self.q01 * m0 + self.q11 * m1)
        ftol0, ftol1 = tol0 + FAST_TOLERANCE_NM, tol1 + FAST_TOLERANCE_NM
        # the residuals against this cycle's prediction; where one is beyond its tolerance, how far
        # the gauge side lies outside what the window's delays predict (never further: asked then only)
        r0, r1, f0, f1 = g0 - p0, g1 - p1, h0 - q0, h1 - q1
        off = (abs(r0) > tol0) | (abs(r1) > tol1)
        fast = (abs(f0) > ftol0) | (abs(f1) > ftol1)
        if any_true(off | fast):
            r0, r1, f0, f1 = outside(g0, s0), outside(g1, s1), outside(h0, e0), outside(h1, e1)
            off = (abs(r0) > tol0) | (abs(r1) > tol1)
            fast = (abs(f0) > ftol0) | (abs(f1) > ftol1)
        self.beyond = beyond = select(off, self.beyond + self.dt, 0.0)
        self.fast_beyond = fast_beyond = select(fast, self.fast_beyond + self.dt, 0.0)
        return (beyond >= self.hold) | (fast_beyond >= FAST_HOLD_S)
