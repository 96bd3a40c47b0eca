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

Written element-wise (:mod:`ankle_rt.elementwise`): plain floats per cycle for the daemon (no
allocation), arrays over a batch of devices for the batched cycle.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

from ankle_rt.elementwise import Value, select, stack

if TYPE_CHECKING:
    import numpy as np

CUTOFF_HZ = 5.0            # residual low-pass
TOLERANCE_NM = 6.0         # N m at the ankle, above the motors' Coulomb friction on the axis
TOLERANCE_FRACTION = 0.3   # of |c|: load-dependent cable friction (0.12 identified) and model errors
HOLD_S = 0.05              # s the residual must stay beyond the tolerance
FAST_CUTOFF_HZ = 20.0      # the fast residual: a gauge stepped far off trips at once (no hold)
FAST_TOLERANCE_NM = 12.0   # N m above the slow residual's tolerance
FAST_HOLD_S = 0.04         # s the fast residual must stay beyond it (an unmodelled actuation delay of a
                           # few ms makes a torque step look like a mismatch for about that long)


class GaugeCrossCheck:
    """The residual of the module docstring for both ankle axes [DP, IE]."""

    def __init__(self, dt: float, R: Sequence[Sequence[float]], inertia: float, viscous: float, coulomb: float,
                 velocity_cutoff_hz: float, *, cutoff_hz: float = CUTOFF_HZ, tolerance_nm: float = TOLERANCE_NM,
                 tolerance_fraction: float = TOLERANCE_FRACTION, hold_s: float = HOLD_S):
        """``R``: theta_m = R theta (2x2); ``inertia`` (kg m^2), ``viscous`` (N m s/rad), ``coulomb``
        (N m): one motor's, at the gearbox output. ``velocity_cutoff_hz``: the estimator's motor
        velocity low-pass, which the motor torque goes through too (the same lag on both sides of
        ``c = tau_m - J a - D v``: a torque step is not read as a mismatch while a lags)."""
        self.dt = dt
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
        return stack(checks, shared=("dt",))

    def reset(self, v0: Value, v1: Value, where: bool | np.ndarray = True) -> None:
        """Start over (on activation) from the motor velocities (rad/s) of this cycle; for a batch,
        only where ``where`` (bool per device) holds."""
        self.v0 = select(where, v0, getattr(self, "v0", 0.0))
        self.v1 = select(where, v1, getattr(self, "v1", 0.0))
        # N m: motor torques low-passed like the velocity (u), the previous cycle's (p), the low-passed
        # and the fast residual [DP, IE] (r, f), each motor's low-passed cable torque (c); s the slow and
        # the fast residual have been beyond their tolerances
        for name in ("u0", "u1", "p0", "p1", "r0", "r1", "f0", "f1", "c0", "c1", "beyond", "fast_beyond"):
            setattr(self, name, select(where, 0.0, getattr(self, name, 0.0)))

    def update(self, tau_m0: Value, tau_m1: Value, v0: Value, v1: Value, sg_dp: Value, sg_ie: Value) -> Value:
        """This cycle's motor torques (N m, set values x torque constant), motor velocities (rad/s)
        and gauge torques (N m [DP, IE]); True (per device) once the gauge has disagreed for
        ``hold_s`` or far off at once. The velocities show the torques of the previous cycle."""
        av = self.av
        self.u0 = u0 = self.u0 + av * (self.p0 - self.u0)
        self.u1 = u1 = self.u1 + av * (self.p1 - self.u1)
        self.p0, self.p1 = tau_m0, tau_m1
        jdt, d = self.inertia_dt, self.viscous
        c0 = u0 - jdt * (v0 - self.v0) - d * v0
        c1 = u1 - jdt * (v1 - self.v1) - d * v1
        self.v0, self.v1 = v0 + 0.0, v1 + 0.0    # copies: a batch's estimator updates its arrays in place
        a = self.a
        d0 = sg_dp - (self.r00 * c0 + self.r10 * c1)
        d1 = sg_ie - (self.r01 * c0 + self.r11 * c1)
        self.r0 = r0 = self.r0 + a * (d0 - self.r0)
        self.r1 = r1 = self.r1 + a * (d1 - self.r1)
        af = self.af
        self.f0 = f0 = self.f0 + af * (d0 - self.f0)
        self.f1 = f1 = self.f1 + af * (d1 - self.f1)
        self.c0 = m0 = self.c0 + af * (c0 - self.c0)
        self.c1 = m1 = self.c1 + af * (c1 - self.c1)
        m0, m1 = abs(m0), abs(m1)                  # abs: floats and arrays alike
        f = self.fraction
        tol0 = self.base0 + f * (self.q00 * m0 + self.q10 * m1)
        tol1 = self.base1 + f * (self.q01 * m0 + self.q11 * m1)
        off = (abs(r0) > tol0) | (abs(r1) > tol1)
        self.beyond = beyond = select(off, self.beyond + self.dt, 0.0)
        fast = (abs(f0) > tol0 + FAST_TOLERANCE_NM) | (abs(f1) > tol1 + FAST_TOLERANCE_NM)
        self.fast_beyond = fast_beyond = select(fast, self.fast_beyond + self.dt, 0.0)
        return (beyond >= self.hold) | (fast_beyond >= FAST_HOLD_S)
