"""Linear least squares with the statistics model selection needs: residual sum of squares,
coefficient covariance, the effective sample size of autocorrelated residuals, an information
criterion that uses it, and block cross-validation."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MAX_LAG = 400


@dataclass
class Fit:
    coef: np.ndarray
    rss: float
    n: int
    xtx_inv: np.ndarray | None   # (X^T X)^-1 (pseudo-inverse), for the covariance; None: not computed
    residual: np.ndarray

    @property
    def k(self) -> int:
        return len(self.coef)

    def covariance(self, n_eff: float) -> np.ndarray:
        """Coefficient covariance, inflated by n / n_eff for the residuals' autocorrelation."""
        if self.xtx_inv is None:
            raise ValueError("fitted without its covariance (fit(..., covariance=False))")
        sigma2 = self.rss / max(1, self.n - self.k)
        return self.xtx_inv * sigma2 * (self.n / max(n_eff, 1.0))


def _unit_columns(X: np.ndarray, in_place: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(X with every nonzero column scaled to unit norm, the scales): conditioning for the solvers.
    ``in_place``: X itself is scaled (the same division, without the copy)."""
    scale = np.sqrt(np.einsum("ij,ij->j", X, X))
    scale[scale == 0.0] = 1.0
    return np.divide(X, scale, out=X if in_place else None), scale


def fit(y: np.ndarray, X: np.ndarray, covariance: bool = True) -> Fit:
    """Least squares y ~ X (columns scaled internally for conditioning). ``covariance=False`` leaves
    ``xtx_inv`` out: X^T X costs about as much as the solve itself on a long record (and far more where
    the BLAS threads share loaded cores), and the cross-validation, the refinement's trials and the
    catch-all's comparisons use only the coefficients, the residual and its sum of squares."""
    Xs, scale = _unit_columns(X)
    coef_s, *_ = np.linalg.lstsq(Xs, y, rcond=None)
    coef = coef_s / scale
    residual = y - X @ coef
    xtx_inv = np.linalg.pinv(Xs.T @ Xs) / np.outer(scale, scale) if covariance else None
    return Fit(coef, float(residual @ residual), len(y), xtx_inv, residual)


def rss_only(y: np.ndarray, X: np.ndarray) -> float:
    """Residual sum of squares of y ~ X (cheaper than :func:`fit`; used on grids). X is scaled in place
    and left so: every caller hands a system stacked for this call, and the scaled copy
    :func:`_unit_columns` would make costs ~10 % of the solve (the same division either way)."""
    Xs, _ = _unit_columns(X, in_place=True)
    coef, *_ = np.linalg.lstsq(Xs, y, rcond=None)
    r = y - Xs @ coef
    return float(r @ r)


def effective_samples(residual: np.ndarray, segments: int) -> float:
    """n_eff = n / (1 + 2 sum rho_k) over ``segments`` equal stacked series (one per motor or axis);
    the sum stops at the first lag whose autocorrelation drops below zero (Geyer's initial sequence)."""
    total = 0.0
    for r in np.split(residual, segments):
        r = r - r.mean()
        n = len(r)
        spec = np.fft.rfft(r, 2 * n)
        acf = np.fft.irfft(spec * np.conj(spec))[: min(n, MAX_LAG)]
        if acf[0] <= 0.0:
            total += n
            continue
        rho = acf / acf[0]
        neg = np.flatnonzero(rho[1:] <= 0.0)
        stop = int(neg[0]) + 1 if neg.size else len(rho)
        tau = 1.0 + 2.0 * float(np.sum(rho[1:stop]))
        total += n / max(tau, 1.0)
    return total


def information_criterion(rss: float, n: int, k: int, n_eff: float) -> float:
    """BIC with the effective sample size: n_eff ln(RSS / n) + k ln(n_eff)."""
    return n_eff * math.log(max(rss, 1e-300) / n) + k * math.log(max(n_eff, 2.0))


def block_cv_mse(y: np.ndarray, X: np.ndarray, segments: int, folds: int = 5) -> np.ndarray:
    """Mean squared prediction error on each of ``folds`` contiguous time blocks held out in turn
    (the same time block of every stacked segment), fitting on the rest."""
    n_seg = len(y) // segments
    edges = np.linspace(0, n_seg, folds + 1).astype(int)
    out = np.empty(folds)
    for f in range(folds):
        held = np.zeros(n_seg, dtype=bool)
        held[edges[f]:edges[f + 1]] = True
        held = np.tile(held, segments)
        model = fit(y[~held], X[~held], covariance=False)
        err = y[held] - X[held] @ model.coef
        out[f] = float(err @ err) / max(1, held.sum())
    return out
