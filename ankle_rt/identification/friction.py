"""Friction-law fits shared by the estimators: torque magnitude against speed magnitude, per direction.

``fit_affine`` is the friction law the simulator uses (|tau| = kc + kv |v|, Coulomb plus viscous);
``fit_through_origin`` is the paper's section 3.2 method (|tau| = kv |v|), kept to show what it gets wrong.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class AffineFit:
    """|tau| = kc + kv |v| (N m, N m s/rad), with regression standard errors (NaN when not estimable)."""

    kc: float
    kv: float
    kc_se: float
    kv_se: float
    n: int

    def predict(self, speed: np.ndarray | float) -> np.ndarray | float:
        return self.kc + self.kv * speed


def fit_affine(speed: np.ndarray, torque: np.ndarray) -> AffineFit:
    """Least-squares line through (|v|, |tau|) points; needs at least two distinct speeds."""
    v = np.abs(np.asarray(speed, dtype=float))
    tau = np.abs(np.asarray(torque, dtype=float))
    if v.size < 2 or np.ptp(v) <= 0.0:
        raise ValueError(f"an affine friction fit needs at least two distinct speeds, got {np.unique(v).size}")
    X = np.column_stack([np.ones_like(v), v])
    coef, *_ = np.linalg.lstsq(X, tau, rcond=None)
    dof = v.size - 2
    if dof > 0:
        resid = tau - X @ coef
        cov = np.linalg.inv(X.T @ X) * float(resid @ resid) / dof
        kc_se, kv_se = math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])
    else:
        kc_se = kv_se = math.nan
    return AffineFit(float(coef[0]), float(coef[1]), kc_se, kv_se, int(v.size))


def fit_through_origin(speed: np.ndarray, torque: np.ndarray) -> float:
    """kv of |tau| = kv |v| by least squares (the paper's viscous coefficient), N m s/rad."""
    v = np.abs(np.asarray(speed, dtype=float))
    tau = np.abs(np.asarray(torque, dtype=float))
    return float(v @ tau / (v @ v))
