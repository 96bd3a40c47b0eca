"""Exact zero-order-hold discretisation of a linear system, without scipy (the runtime stays lean).

Shared by the simulator (sim_backend.model) and the closed-loop analysis (ankle_rt.analysis)."""

from __future__ import annotations

import numpy as np


def expm(M: np.ndarray) -> np.ndarray:
    """Matrix exponential by scaling and squaring with a Taylor series (accurate to ~1e-15 relative
    for the small, well-scaled matrices of this model)."""
    norm = np.linalg.norm(M, 1)
    squarings = max(0, int(np.ceil(np.log2(norm / 0.25)))) if norm > 0.25 else 0
    S = M / (2.0 ** squarings)
    term = np.eye(M.shape[0])
    total = term.copy()
    for k in range(1, 30):
        term = term @ S / k
        total += term
        if np.linalg.norm(term, 1) < 1e-18 * np.linalg.norm(total, 1):
            break
    for _ in range(squarings):
        total = total @ total
    return total


def zoh(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Return (Ad, Bd) with x[k+1] = Ad x[k] + Bd u[k] exact for u held constant over ``h`` seconds."""
    n, m = B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = A
    aug[:n, n:] = B
    E = expm(aug * h)
    return E[:n, :n].copy(), E[:n, n:].copy()
