"""The paper's own actuator identification numbers (section 3, Table 1 and Fig. 3), kept as a record,
and what its friction model predicts on its own measurements.

Sign convention used everywhere in :mod:`ankle_rt.identification`: positive motor velocity is CCW,
negative is CW (the paper's Fig. 3 shows negative torques for CW). Friction magnitudes are positive
numbers: ``kc_pos``/``kv_pos`` act for positive (CCW) velocity, ``kc_neg``/``kv_neg`` for negative (CW).
(The paper labels its through-origin CW slope "kv+"; the values below are what its numbers give.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ankle_rt.identification.friction import AffineFit, fit_affine, fit_through_origin

#: Fig. 3: steady motor speeds (rad/s) of the PI velocity loop, both directions.
PAPER_SPEEDS = (3.0, 5.0, 8.0)
#: Fig. 3: steady motor torques (N m, kt = 1.66 N m/A) at those speeds, CW (negative velocity).
PAPER_TORQUES_CW = (-0.43, -0.63, -0.80)
#: Fig. 3: the same for CCW (positive velocity).
PAPER_TORQUES_CCW = (0.45, 0.63, 0.83)
#: Table 1, identified: J (kg m^2), D = kv (N m s/rad), kc+ = kc- (N m), with their SDs.
PAPER_TABLE1 = {"J": (0.048, 0.002), "D": (0.112, 0.01), "kc_pos": (0.28, 0.01), "kc_neg": (0.28, 0.01)}
#: Table 1, nominal (datasheet) values.
PAPER_NOMINAL = {"J": 0.028, "D": 0.02, "kc_pos": 0.0, "kc_neg": 0.0}
#: Sections 3.1 and 3.2: the friction model the paper simulates with.
PAPER_KC = 0.28
PAPER_KV = 0.112


@dataclass(frozen=True)
class PaperFrictionAnalysis:
    """The paper's friction model against its own Fig. 3 measurements (magnitudes, N m)."""

    speeds: np.ndarray             # rad/s
    measured: np.ndarray           # N m, mean of |CW| and CCW at each speed
    kv_origin_cw: float            # N m s/rad, fit through the origin (the paper's method)
    kv_origin_ccw: float
    kv_origin: float               # their mean (the paper's 0.112)
    predicted: np.ndarray          # N m, kc = 0.28 + kv_origin * speed (what the paper simulates)
    overprediction: np.ndarray     # predicted / measured - 1, per speed
    affine_cw: AffineFit           # |tau| = kc + kv |v| per direction
    affine_ccw: AffineFit
    affine: AffineFit              # both directions pooled

    def lines(self) -> list[str]:
        """A short text report."""
        out = ["Paper's friction model against its own Fig. 3 measurements",
               f"  through-origin fit (paper's method): kv CW = {self.kv_origin_cw:.4f}, "
               f"kv CCW = {self.kv_origin_ccw:.4f}, mean kv = {self.kv_origin:.4f} N m s/rad",
               f"  paper's model tau_F = {PAPER_KC:.2f} + {self.kv_origin:.3f} |v|:"]
        for v, m, p, e in zip(self.speeds, self.measured, self.predicted, self.overprediction):
            out.append(f"    {v:4.1f} rad/s: measured {m:.3f} N m, predicted {p:.3f} N m ({100 * e:+.0f} %)")
        out.append(f"  affine fit |tau| = kc + kv |v|: CW kc = {self.affine_cw.kc:.3f}, kv = {self.affine_cw.kv:.4f}; "
                   f"CCW kc = {self.affine_ccw.kc:.3f}, kv = {self.affine_ccw.kv:.4f}; "
                   f"pooled kc = {self.affine.kc:.3f} N m, kv = {self.affine.kv:.4f} N m s/rad")
        return out


def paper_friction_analysis() -> PaperFrictionAnalysis:
    """Refit the paper's Fig. 3 numbers: its through-origin kv plus kc = 0.28 double-counts the Coulomb
    part (about +40 % at 3 rad/s); an affine fit per direction separates kc and kv."""
    v = np.asarray(PAPER_SPEEDS)
    cw = np.abs(np.asarray(PAPER_TORQUES_CW))
    ccw = np.asarray(PAPER_TORQUES_CCW)
    kv_cw, kv_ccw = fit_through_origin(v, cw), fit_through_origin(v, ccw)
    kv0 = 0.5 * (kv_cw + kv_ccw)
    measured = 0.5 * (cw + ccw)
    predicted = PAPER_KC + kv0 * v
    return PaperFrictionAnalysis(
        speeds=v, measured=measured, kv_origin_cw=kv_cw, kv_origin_ccw=kv_ccw, kv_origin=kv0,
        predicted=predicted, overprediction=predicted / measured - 1.0,
        affine_cw=fit_affine(v, cw), affine_ccw=fit_affine(v, ccw),
        affine=fit_affine(np.concatenate([v, v]), np.concatenate([cw, ccw])))
