"""Passivity of the impedance the ankle renders: what the foot feels must never give energy back.

A stable loop (the gain margin, :mod:`ankle_rt.gain_margin`) may still render an impedance whose real
part is negative at some frequency: a foot that moves there is pushed, not resisted, and coupled to a
soft environment (a slack cable's pretension, a wearer's relaxed leg) the pair can oscillate though
each is stable alone. The sampled closed loop's felt impedance Z = T / Theta (ankle torque per ankle
angle, foot free) renders the damping Im Z / w (N m s/rad) at w; passive is that damping >= 0 at
every frequency up to PASSIVITY_MAX_HZ, for cable stiffness x0.7 / 1 / 1.3 and viscous friction
x0.5 / 1 / 2 (the margin's plant range). The load-dependent friction's linearisation (+-mu) is left
out: it stands for a friction that only dissipates. Coulomb friction is not in the model either, so
the check is the frictionless side (measured: a K_ie 100 N m/rad, B_ie 0 setting this check refuses
gives energy back in lockstep at 3-6 Hz on a cable x0.7, and keeps doing so with the plant's friction
at 3 N m; docs/daemon.md "Passivity").
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ankle_rt import analysis as an
from ankle_rt.discretize import zoh
from ankle_rt.linear_model import LinearModel
from ankle_rt.params import PlantParams

# Hz: the foot can drive its ankle up to about here (gait's content ends below 20 Hz); the cable modes
# above (70-110 Hz) are what the gain margin with the foot held covers
PASSIVITY_MAX_HZ = 50.0
PASSIVITY_HZ = np.logspace(-1.0, math.log10(PASSIVITY_MAX_HZ), 60)
# N m s/rad: a rendered damping above minus this is passive (the solve's rounding at a pure spring)
DAMPING_FLOOR = 1e-6


@dataclass(frozen=True)
class LeastDamping:
    """Where an axis renders its least damping over the plant range and PASSIVITY_HZ."""

    damping: float           # N m s/rad, Im Z / w (negative: gives energy back)
    freq_hz: float
    stiffness_factor: float  # of the configured cable
    viscous_factor: float    # of the identified viscous friction

    @property
    def passive(self) -> bool:
        return self.damping >= -DAMPING_FLOOR

    def where(self) -> str:
        return (f"{self.damping:+.3g} N m s/rad at {self.freq_hz:.2g} Hz with the cable x{self.stiffness_factor:g} and "
                f"viscous friction x{self.viscous_factor:g}")


def free_plant_with_ankle_input(p: PlantParams, dt: float, load_slope: float = 0.0) -> tuple:
    """(Ad, Bd_motor, Bd_ankle, Cy, kin): the foot-free plant sampled with a zero-order hold, with the
    ankle torque [DP, IE] as a second input (what the foot puts on the ankle)."""
    A, Bm, Cy = an._plant(p, foot="free", load_slope=load_slope)
    lm = LinearModel.from_params(p)
    Ad, Bd = zoh(A, np.hstack([Bm, lm.B[:, 0:2]]), dt)
    return Ad, Bd[:, 0:2], Bd[:, 2:4], Cy, lm.kin


def receptance(sampled: tuple, loop: "an.ImpedanceLoop | an.MotorPDLoop", freqs_hz: np.ndarray) -> np.ndarray:
    """(len(freqs), 2, 2) rad per N m: the ankle angle per ankle torque of the closed loop on ``sampled``
    (:func:`free_plant_with_ankle_input`)."""
    Ad, Bm, Ba, Cy, kin = sampled
    W, U = loop.rows(kin, kin.K)
    T = an._assemble(Ad, Bm, Cy, W, U, loop.delay_cycles)[0]
    G = np.zeros((T.shape[0], 2))
    G[:an.N_X] = Ba
    z = np.exp(2j * math.pi * np.asarray(freqs_hz) * loop.dt)
    M = z[:, None, None] * np.eye(T.shape[0]) - T
    X = np.linalg.solve(M, np.broadcast_to(G, (len(z), *G.shape)))
    return X[:, 0:2, :]


@functools.lru_cache(maxsize=64)
def least_rendered_damping(p: PlantParams,
                           loop: "an.ImpedanceLoop | an.MotorPDLoop") -> tuple[LeastDamping, LeastDamping]:
    """[DP, IE]: the least damping the loop renders on each axis over the module docstring's range."""
    w = 2.0 * math.pi * PASSIVITY_HZ
    worst: list[LeastDamping | None] = [None, None]
    for kf, vf, _, _, pp in an._plant_cases(p, 0.0, viscous_factors=an.VISCOUS_FACTORS, feet=("free",)):
        X = receptance(free_plant_with_ankle_input(pp, loop.dt), loop, PASSIVITY_HZ)
        for axis in (0, 1):
            damping = (1.0 / X[:, axis, axis]).imag / w
            i = int(np.argmin(damping))
            if worst[axis] is None or damping[i] < worst[axis].damping:
                worst[axis] = LeastDamping(float(damping[i]), float(PASSIVITY_HZ[i]), kf, vf)
    return worst[0], worst[1]
