"""Fit the baseline and every candidate of one residual channel and score them.

For each candidate the nonlinear parameter is searched on its grid (smallest residual sum of squares),
then every model is scored with the information criterion of :mod:`~ankle_rt.diagnosis.regression`
using one effective sample size: the one of the catch-all model's residual, the best available
estimate of how many independent samples the noise holds."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ankle_rt.diagnosis.candidates import Candidate, Channel
from ankle_rt.diagnosis.regression import Fit, effective_samples, fit, information_criterion, rss_only


@dataclass
class Score:
    cause: str
    candidate: Candidate
    nl: float                      # best grid value of the nonlinear parameter (0 when none)
    rss: float
    k: int                         # parameters, nonlinear one included
    profile: list[tuple[float, float]] = field(default_factory=list)   # (grid value, rss)
    ic: float = 0.0
    delta_ic: float = 0.0          # baseline IC - this IC (> 0: better than the baseline)
    reduction: float = 0.0         # 1 - rss / rss_baseline
    size: float = 0.0              # RMS of what it explains / std of the measured side (an NRMSE)


@dataclass
class ChannelScores:
    name: str                      # "motor" or "cable"
    channel: Channel
    baseline: Fit
    scores: list[Score]
    catch_all_rss: float
    n_eff: float
    catch_all_delta_ic: float = 0.0
    catch_all_reduction: float = 0.0
    catch_all_X: np.ndarray | None = field(default=None, repr=False)
    catch_all_size: float = 0.0


def design_matrix(ch: Channel, Xb: np.ndarray, cand: Candidate, nl: float) -> tuple[np.ndarray, np.ndarray]:
    """(y, X) of the baseline extended by ``cand`` at ``nl``."""
    d = cand.design(ch, nl)
    y = d.y if d.y is not None else ch.target()
    return y, np.hstack([Xb, d.X])


def score_channel(name: str, ch: Channel, candidates: tuple[Candidate, ...],
                  catch_all) -> ChannelScores:
    y0 = ch.target()
    Xb = ch.baseline_design()
    base = fit(y0, Xb)
    scores: list[Score] = []
    best_blocks = []
    for cand in candidates:
        if not cand.applies(ch):
            continue
        profile = []
        for nl in cand.grid(ch):
            y, X = design_matrix(ch, Xb, cand, nl)
            profile.append((nl, rss_only(y, X)))
        nl, rss = min(profile, key=lambda p: p[1])
        for extra in getattr(cand, "local_grid", lambda _c, _b: [])(ch, nl):
            y, X = design_matrix(ch, Xb, cand, extra)
            profile.append((extra, rss_only(y, X)))
        profile.sort()
        nl, rss = min(profile, key=lambda p: p[1])
        d = cand.design(ch, nl)
        if d.X.shape[1]:
            best_blocks.append(d.X)
        scores.append(Score(cand.cause, cand, nl, rss, Xb.shape[1] + d.X.shape[1] + (cand.nonlinear is not None),
                            profile))
    Xc = np.hstack([Xb, catch_all(ch)] + best_blocks)
    full = fit(y0, Xc)
    n_eff = effective_samples(full.residual, ch.m)
    n = len(y0)
    ic_base = information_criterion(base.rss, n, Xb.shape[1], n_eff)
    scale = float(np.std(ch.measured()))

    def size(rss: float) -> float:
        return math.sqrt(max(0.0, base.rss - rss) / n) / max(scale, 1e-300)

    for s in scores:
        s.ic = information_criterion(s.rss, n, s.k, n_eff)
        s.delta_ic = ic_base - s.ic
        s.reduction = 1.0 - s.rss / base.rss
        s.size = size(s.rss)
    out = ChannelScores(name, ch, base, scores, full.rss, n_eff, catch_all_X=Xc)
    out.catch_all_delta_ic = ic_base - information_criterion(full.rss, n, Xc.shape[1], n_eff)
    out.catch_all_reduction = 1.0 - full.rss / base.rss
    out.catch_all_size = size(full.rss)
    return out
