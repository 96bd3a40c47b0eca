"""Joint encoders cross-checked against the motors and the strain gauges: a joint encoder read with the wrong
sign, the wrong scale or stuck shows a cable stretch the gauges do not show the torque of.

The motor and joint encoders give the cables' stretch torque ``K (R^-1 theta_m - theta_joint)`` on the configured
cable (what the encoder rate source, ``torque_rate_source: encoders``, differentiates); the gauges measure that
torque. Both low-passed at ``CUTOFF_HZ`` and counted from activation (a joint encoder's zero need not be the
motors', nor the foot unloaded), the stretch's change stays within ``FACTOR`` x the gauges' change (a cable down
to 1 / FACTOR of the configured stiffness) plus ``safety.joint_mismatch_rad`` of angle times K (counts, creep,
the cables' play). Beyond it for ``HOLD_S`` on either axis is the fault, before a flipped sign has driven the
ankle away (it does within 1-2 s at rest, the law's stiffness turned negative) or rung the loop up; the smaller
the angle, the sooner. One bad sample is not enough (``HOLD_S``; the loop skips it). A stretch changing against
the gauges' change (beyond ``safety.joint_mismatch_rad``) faults too, after ``AGAINST_HOLD_S``: a joint encoder
reading half the angle under a stiff law stays within twice the gauges' size but not their sign (K_ie 100: the
ankle's 0.03 rad read as 0.015, a stretch of +1.8 N m against the gauges' -1.5). That hold is longer than the
strain-gauge cross-check's, because a gauge gone bad (stuck, flipped) drags the stretch against itself too and is
``SG_MISMATCH`` to name.

Written element-wise (:mod:`ankle_rt.elementwise`): plain floats per cycle for the daemon (no allocation),
arrays over a batch of devices for the batched cycle.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

from ankle_rt.elementwise import Value, select, stack

if TYPE_CHECKING:
    import numpy as np

CUTOFF_HZ = 5.0       # the low-passes: a single bad sample of 10 mrad moves the DP stretch's by 0.44 N m
FACTOR = 2.0          # the stretch's change at most this times the gauges' (the estimate's cable x0.5 and up)
HOLD_S = 0.05         # s beyond the tolerance (a 30 mrad single sample stays beyond 0.43 N m for 36 ms)
# s of a stretch against the gauges' change (the sign): longer than the strain-gauge cross-check's 0.15 s, which
# names a bad gauge first (a stuck gauge's loop drags the stretch against it within 50 ms)
AGAINST_HOLD_S = 0.2


class JointCrossCheck:
    """The comparison of the module docstring for both ankle axes [DP, IE]."""

    def __init__(self, dt: float, cable_dp: float, cable_ie: float, mismatch_rad: float, watch: bool):
        """``cable_dp``, ``cable_ie``: N m/rad, the configured cable's stiffness at the ankle (K's diagonal);
        ``mismatch_rad``: the angle allowed beside the cable's error (``safety.joint_mismatch_rad``); ``watch``:
        whether a disagreement faults (where the controller acts on the joint encoders; the filters run anyway,
        so a batch may mix)."""
        self.dt = dt
        self.k0, self.k1 = cable_dp, cable_ie
        self.base0, self.base1 = mismatch_rad * cable_dp, mismatch_rad * cable_ie
        self.watch = watch
        self.a = 1.0 - math.exp(-2.0 * math.pi * CUTOFF_HZ * dt)
        # N m: the stretch and gauge torques low-passed, their values at activation, s beyond
        self.r0 = self.r1 = self.g0 = self.g1 = self.o0 = self.o1 = self.h0 = self.h1 = self.beyond = self.against = 0.0

    @classmethod
    def stack(cls, checks: Sequence["JointCrossCheck"]) -> "JointCrossCheck":
        """One cross-check standing for ``checks`` (one per device of a batch): numbers as arrays."""
        return stack(checks, shared=("dt",))

    def start(self, est_dp: Value, est_ie: Value, joint_dp: Value, joint_ie: Value, sg_dp: Value, sg_ie: Value,
              where: bool | np.ndarray = True) -> None:
        """The filters from this sample (the first one, or after a reset; for a batch only where ``where``):
        estimated and joint-encoder angles (rad), gauge torques (N m [DP, IE])."""
        self.r0 = select(where, self.k0 * (est_dp - joint_dp) + sg_dp, self.r0)
        self.r1 = select(where, self.k1 * (est_ie - joint_ie) + sg_ie, self.r1)
        self.g0 = select(where, sg_dp, self.g0)
        self.g1 = select(where, sg_ie, self.g1)

    def activated(self, where: bool | np.ndarray = True) -> None:
        """The changes count from here (on activation)."""
        self.o0 = select(where, self.r0, self.o0)
        self.o1 = select(where, self.r1, self.o1)
        self.h0 = select(where, self.g0, self.h0)
        self.h1 = select(where, self.g1, self.h1)
        self.beyond = select(where, 0.0, self.beyond)
        self.against = select(where, 0.0, self.against)

    def update(self, est_dp: Value, est_ie: Value, joint_dp: Value, joint_ie: Value, sg_dp: Value, sg_ie: Value,
               active: bool | np.ndarray) -> Value:
        """This sample's angles and gauge torques (as :meth:`start`; the stretch is K (estimate - joint) + gauge);
        True (per device) once the joint encoders have disagreed for ``HOLD_S`` while ``active`` and watched."""
        a = self.a
        self.r0 = r0 = self.r0 + a * (self.k0 * (est_dp - joint_dp) + sg_dp - self.r0)
        self.r1 = r1 = self.r1 + a * (self.k1 * (est_ie - joint_ie) + sg_ie - self.r1)
        self.g0 = g0 = self.g0 + a * (sg_dp - self.g0)
        self.g1 = g1 = self.g1 + a * (sg_ie - self.g1)
        d0, d1, e0, e1 = r0 - self.o0, r1 - self.o1, g0 - self.h0, g1 - self.h1
        watched = active & self.watch
        off = watched & ((abs(d0) > self.base0 + FACTOR * abs(e0)) | (abs(d1) > self.base1 + FACTOR * abs(e1)))
        opposed = watched & (_against(d0, e0, self.base0) | _against(d1, e1, self.base1))
        self.beyond = beyond = select(off, self.beyond + self.dt, 0.0)
        self.against = against = select(opposed, self.against + self.dt, 0.0)
        return (beyond >= HOLD_S) | (against >= AGAINST_HOLD_S)


def _against(stretch: Value, gauge: Value, base: Value) -> Value:
    """Whether a change of the stretch torque (N m) lies outside what a cable of 1 / FACTOR or more of the configured
    stiffness makes of the gauges' change, sign included: between 0 and FACTOR x it, give or take ``base``."""
    half = 0.5 * FACTOR * gauge
    return abs(stretch - half) > abs(half) + base
