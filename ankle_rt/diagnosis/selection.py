"""Select the set of effects one residual channel holds: forward selection over the candidate blocks,
confirmed by block cross-validation, pruned by a drop-one test, then the catch-all on top of the chosen
model to see what is left unexplained.

Every model is the channel's baseline regression extended by some candidate blocks (each at a value of
its nonlinear parameter); all are scored with the information criterion of
:mod:`~ankle_rt.diagnosis.regression` using one effective sample size: the one of the catch-all model's
residual, the best available estimate of how many independent samples the noise holds."""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ankle_rt.diagnosis.candidates import Candidate, CatchAll, Channel, Design
from ankle_rt.diagnosis.regression import Fit, block_cv_mse, effective_samples, fit, information_criterion, rss_only

#: a block must beat the model without it by this much in the information criterion (nats x 2) ...
IC_THRESHOLD = 20.0
#: ... remove at least this fraction of that model's residual sum of squares ...
MIN_REDUCTION = 0.04
#: ... and be of practical size: what it explains must reach this NRMSE (RMS / std of the measured
#: torque); on effect-free data the best named candidate explains <= 0.001
MIN_SIZE = 0.003
#: a block removing this share of the residual counts whatever its size
LARGE_REDUCTION = 0.25
#: the catch-all must remove this fraction (in-sample and in held-out blocks) before a discrepancy counts
#: as real without a name ...
MIN_UNKNOWN_REDUCTION = 0.10
#: ... and explain this much: on effect-free data it fits <= 0.0035 of noise and friction-transition error
MIN_SIZE_UNKNOWN = 0.006
#: ... and predict held-out time blocks this much better: in closed loop the controller's reaction to past
#: noise makes the torque history correlate with the residual, which the catch-all's latency columns fit
#: in-sample (up to ~20 % in held-out blocks on effect-free slow motion); an effect outside the vocabulary
#: predicts held-out blocks by >= 50 % in the tests
MIN_UNKNOWN_CV = 0.4
#: a remainder the catch-all predicts this well in held-out blocks counts down to MIN_SIZE, the size a
#: named effect needs (strong motion can make a clear discrepancy small against the measured torque; below
#: MIN_SIZE it is no discrepancy a model change could remove: generator D's effect-free walking seed 115,
#: 0.0006, 60 % held-out)
LARGE_UNKNOWN_CV = 0.6
#: two hypotheses whose criteria differ by less than this are reported as ambiguous
AMBIGUOUS_IC = 10.0
CV_FOLDS = 5
MAX_EFFECTS = 4
#: coordinate passes re-searching the chosen blocks' nonlinear parameters, at most
REGRID_PASSES = 3
#: rows a subset of the data must hold per fitted column before a fit on it alone is judged
MIN_ROWS_PER_COLUMN = 10
#: designs a channel keeps cached while it is selected (least recently used dropped first): at least this
#: many, and more while they take less than MAX_DESIGN_BYTES (a 30 s record's selection built 155 of its
#: designs twice under the count alone, a quarter of its cogging screens); after the selection only the
#: chosen terms' stay (:meth:`ChannelModels.keep_only`)
MAX_DESIGNS = 160
MAX_DESIGN_BYTES = 256 << 20
#: the largest condition number of a grid's column-scaled system that :class:`Projector` solves (beyond it,
#: and for any zero column, the pseudo-inverse of numpy.linalg.lstsq, which cuts singular values below
#: eps x rows: ~3e11 on a 30 s record)
PROJECTION_COND = 1e6


@dataclass
class Term:
    """One candidate block at one value of its nonlinear parameter."""

    candidate: Candidate
    nl: float
    design: Design

    @property
    def cause(self) -> str:
        return self.candidate.cause


@dataclass
class Score:
    """A candidate scored against a reference model (the baseline, or the model chosen so far)."""

    cause: str
    candidate: Candidate
    nl: float
    rss: float
    k: int
    profile: list[tuple[float, float]] = field(default_factory=list)   # (grid value, rss)
    delta_ic: float = 0.0          # reference IC - this IC (> 0: better than the reference)
    reduction: float = 0.0         # 1 - rss / rss_reference
    size: float = 0.0              # RMS of what it explains / std of the measured side (an NRMSE)


@dataclass
class TermStats:
    """What a chosen effect earns with the others in (drop-one), and how close its best rival came."""

    term: Term
    delta_ic: float
    reduction: float               # share of the model-without-it's residual it removes
    share: float                   # share of the baseline residual it removes (with the others in)
    size: float
    cv_wins: int
    rival: str | None = None       # the candidate that fits nearly as well in its place, if any
    rival_margin: float = math.inf

    @property
    def confidence(self) -> float:
        margin = min(self.rival_margin, self.delta_ic)
        return 1.0 / (1.0 + math.exp(-max(-50.0, min(50.0, margin / 4.0)))) * self.cv_wins / CV_FOLDS


@dataclass
class ChannelResult:
    name: str                      # "motor" or "cable"
    channel: Channel
    baseline: Fit
    first: list[Score]             # every candidate alone against the baseline (the candidate table)
    n_eff: float
    models: ChannelModels          # the channel's systems, designs and fits (cached)
    terms: list[TermStats] = field(default_factory=list)
    model: Fit | None = None
    notes: list[str] = field(default_factory=list)
    catch_all_delta_ic: float = 0.0        # catch-all on top of the chosen model
    catch_all_reduction: float = 0.0
    catch_all_size: float = 0.0
    catch_all_cv_reduction: float = 0.0
    catch_all_total: float = 0.0           # catch-all's reduction of the baseline residual
    correlates: list[tuple[str, float]] = field(default_factory=list)
    nl_sd: list[float] = field(default_factory=list)     # sd of each term's nonlinear parameter

    @property
    def named_share(self) -> float:
        """Share of the baseline residual the chosen effects remove together."""
        return 0.0 if self.model is None else 1.0 - self.model.rss / self.baseline.rss

    @property
    def unexplained(self) -> bool:
        """A discrepancy the chosen effects leave: the catch-all beats them in the criterion and in
        held-out blocks, by a practical size (or predicts the held-out blocks far better)."""
        return (self.catch_all_delta_ic > IC_THRESHOLD and self.catch_all_reduction > MIN_UNKNOWN_REDUCTION
                and self.catch_all_cv_reduction > MIN_UNKNOWN_CV
                and (self.catch_all_size > MIN_SIZE_UNKNOWN
                     or (self.catch_all_cv_reduction > LARGE_UNKNOWN_CV and self.catch_all_size > MIN_SIZE)))


class ChannelModels:
    """Models of one channel: the baseline plus candidate blocks. Designs are cached by (candidate form,
    value), residual sums of squares, cross-validation errors and fits by the set of terms: the search,
    the selection, the validation and the report all build their systems here."""

    def __init__(self, ch: Channel):
        self.ch = ch
        self.Xb = ch.baseline_design()
        self.y0 = ch.target()
        self.n = len(self.y0)
        self.scale = max(float(np.std(ch.measured())), 1e-300)
        self._designs: dict[tuple[str, float], Design] = {}
        self._design_bytes = 0
        self._rss: dict[tuple, float] = {}
        self._cv: dict[tuple, np.ndarray] = {}
        self._fits: dict[tuple, Fit] = {}
        self._grids: dict[tuple, list[float]] = {}      # search_grid's values by candidate and residual

    @cached_property
    def baseline(self) -> Fit:
        """The baseline alone fitted (its residual is what the candidates and the catch-all's periodic
        friction search; fitted once per channel state, as the models are built on one)."""
        return fit(self.y0, self.Xb)

    def design(self, cand: Candidate, nl: float, built: Design | None = None) -> Design:
        """``cand``'s columns at ``nl``, from a cache of the most recently used (MAX_DESIGNS, and more up to
        MAX_DESIGN_BYTES: the cogging search screens dozens of counts per step, each a few hundred kB on a
        long record); ``built``: the design at ``nl`` built already (stored, never built again)."""
        key = (type(cand).__name__, float(nl))       # a form of its own per class
        d = self._designs.pop(key, None)
        if d is None:
            d = built or cand.design(self.ch, nl)
            self._design_bytes += d.nbytes
        self._designs[key] = d                       # most recent last
        while len(self._designs) > MAX_DESIGNS and self._design_bytes > MAX_DESIGN_BYTES:
            self._design_bytes -= self._designs.pop(next(iter(self._designs))).nbytes
        return d

    def keep_only(self, terms: list[Term]) -> None:
        """Drop every cached design but those of ``terms`` (a channel's result keeps its models for the
        validation and the report, which use its chosen terms)."""
        keep = {(type(t.candidate).__name__, t.nl) for t in terms}
        self._designs = {k: d for k, d in self._designs.items() if k in keep}
        self._design_bytes = sum(d.nbytes for d in self._designs.values())

    def term(self, cand: Candidate, nl: float, built: Design | None = None) -> Term:
        return Term(cand, float(nl), self.design(cand, nl, built))

    def terms(self, specs: list[tuple[Candidate, float]]) -> list[Term]:
        return [self.term(c, nl) for c, nl in specs]

    @staticmethod
    def _key(terms: list[Term]) -> tuple:
        return tuple(sorted((type(t.candidate).__name__, t.nl) for t in terms))

    def system(self, terms: list[Term]) -> tuple[np.ndarray, np.ndarray]:
        """(y, X) of the baseline extended by ``terms``."""
        y = next((t.design.y for t in terms if t.design.y is not None), self.y0)
        return y, np.hstack([self.Xb] + [t.design.X for t in terms])

    def slices(self, terms: list[Term]) -> list[slice]:
        """Each term's columns in the X of :meth:`system`."""
        out, k = [], self.Xb.shape[1]
        for t in terms:
            out.append(slice(k, k + t.design.X.shape[1]))
            k += t.design.X.shape[1]
        return out

    def k(self, terms: list[Term]) -> int:
        nonlinear = sum(t.candidate.nonlinear_count for t in terms if t.candidate.nonlinear)
        return self.Xb.shape[1] + sum(t.design.X.shape[1] for t in terms) + nonlinear

    def rss(self, terms: list[Term], shared: Projector | None = None) -> float:
        """RSS of the baseline extended by ``terms`` (cached); ``shared``: the factored columns of all but
        the last term (a grid search's, :class:`Projector`), which solve it where they can."""
        key = self._key(terms)
        if key not in self._rss:
            last = terms[-1].design if terms else None
            rss = None
            if shared is not None and last is not None:
                own_y = last.y if all(t.design.y is None for t in terms[:-1]) else None
                rss = shared.rss(own_y, last.X)
            self._rss[key] = rss if rss is not None else rss_only(*self.system(terms))
        return self._rss[key]

    def ic(self, terms: list[Term], n_eff: float) -> float:
        """The information criterion of the model with ``terms``."""
        return information_criterion(self.rss(terms), self.n, self.k(terms), n_eff)

    def fit(self, terms: list[Term]) -> Fit:
        """The least-squares fit of the baseline extended by ``terms`` (coefficients in their order)."""
        key = tuple((type(t.candidate).__name__, t.nl) for t in terms)
        if key not in self._fits:
            self._fits[key] = fit(*self.system(terms))
        return self._fits[key]

    def cv(self, terms: list[Term]) -> np.ndarray:
        """Block cross-validation errors (one per fold) of the baseline extended by ``terms``."""
        key = self._key(terms)
        if key not in self._cv:
            self._cv[key] = block_cv_mse(*self.system(terms), self.ch.m, CV_FOLDS)
        return self._cv[key]

    def size(self, rss_without: float, rss_with: float) -> float:
        return math.sqrt(max(0.0, rss_without - rss_with) / self.n) / self.scale

    def best_of(self, cand: Candidate, others: list[Term], residual: np.ndarray, current: float | None = None) -> Score:
        """``cand`` added to ``others`` at the value of its nonlinear parameter with the smallest RSS
        (``current``, a value it holds already, scored too: a re-search never makes the model worse)."""
        # the values to score depend only on the candidate, the channel and the residual (the cogging
        # screen builds ~40 designs and an angle spectrum): the same residual searched again (the drop-one
        # rivals, the forms, the re-searches) takes them from here
        key = (type(cand).__name__, hashlib.blake2b(residual.tobytes(), digest_size=20).digest())
        grid = self._grids.get(key)
        if grid is None:
            grid = self._grids[key] = list(cand.search_grid(self.ch, residual, lambda nl: self.design(cand, nl)))
        if current is not None and current not in grid:
            grid = list(grid) + [current]
        shared = None                 # the columns the grid shares, factored once a value needs a solve
        profile = []
        for nl in grid:
            terms = others + [self.term(cand, nl)]
            if shared is None and self._key(terms) not in self._rss:
                y = next((t.design.y for t in others if t.design.y is not None), self.y0)
                shared = Projector(y, np.hstack([self.Xb] + [t.design.X for t in others]))
            profile.append((nl, self.rss(terms, shared)))
        nl, rss = min(profile, key=lambda p: p[1])
        profile.sort()
        return Score(cand.cause, cand, nl, rss, self.k(others + [self.term(cand, nl)]), profile)


class Projector:
    """The columns a grid search shares (the baseline and the terms held fixed), factored once: the QR of
    their column-scaled X. Each grid value's residual sum of squares is then the shared residual's less
    what the candidate's own columns, projected off the shared ones, explain: a few products with Q instead
    of a least-squares solve of the whole stacked system. Mathematically the RSS of the full system; in
    floating point it differs from numpy.linalg.lstsq's in the last digits. Where the shared or the whole
    system is ill-conditioned (PROJECTION_COND), has a zero column or not twice as many rows as columns, or
    holds a non-finite number, ``rss`` returns None and the caller solves the whole system as before."""

    def __init__(self, y: np.ndarray, A: np.ndarray):
        from scipy.linalg import qr
        scale = np.sqrt(np.einsum("ij,ij->j", A, A))
        self.ok = bool(np.all(scale > 0.0) and np.all(np.isfinite(scale)) and np.all(np.isfinite(y))
                       and A.shape[0] >= 2 * A.shape[1])
        if not self.ok:
            return
        self.Q, self.R = qr(A / scale, mode="economic", check_finite=False)
        sv = np.linalg.svd(self.R, compute_uv=False)
        self.ok = bool(sv[-1] * PROJECTION_COND > sv[0])
        self.y = y
        self.y_perp = self._perp(y)

    def _perp(self, B: np.ndarray) -> np.ndarray:
        """B less its projection on the shared columns (twice: orthogonal to them to the last digits)."""
        Q = self.Q
        B = B - Q @ (Q.T @ B)
        return B - Q @ (Q.T @ B)

    def rss(self, y: np.ndarray | None, B: np.ndarray) -> float | None:
        """RSS of ``y`` (None: the shared one) on the shared columns and ``B`` (None where the whole system
        is to be solved instead: see the class docstring)."""
        if not self.ok:
            return None
        if y is not None and y is not self.y and not np.all(np.isfinite(y)):
            return None
        yp = self.y_perp if y is None or y is self.y else self._perp(y)
        if B.shape[1] == 0:
            return float(yp @ yp)
        scale = np.sqrt(np.einsum("ij,ij->j", B, B))
        p, q = self.R.shape[1], B.shape[1]
        if not (np.all(scale > 0.0) and np.all(np.isfinite(scale)) and len(B) >= 2 * (p + q)):
            return None
        Q = self.Q
        Bs = B / scale
        C = Q.T @ Bs                           # the candidate's columns on the shared ones ...
        Bp = Bs - Q @ C
        Bp -= Q @ (Q.T @ Bp)                   # ... and off them, orthogonal to the last digits
        G = Bp.T @ Bp
        try:
            L = np.linalg.cholesky(G)
        except np.linalg.LinAlgError:
            return None
        R = np.zeros((p + q, p + q))           # the whole scaled system's R: its condition number
        R[:p, :p] = self.R
        R[:p, p:] = C
        R[p:, p:] = L.T
        sv = np.linalg.svd(R, compute_uv=False)
        if not sv[-1] * PROJECTION_COND > sv[0]:
            return None
        c = np.linalg.solve(G, Bp.T @ yp)
        r = yp - Bp @ c
        return float(r @ r)


def score_against(models: ChannelModels, score: Score, ref_rss: float, ref_k: int, n_eff: float) -> Score:
    ic = information_criterion(score.rss, models.n, score.k, n_eff)
    score.delta_ic = information_criterion(ref_rss, models.n, ref_k, n_eff) - ic
    score.reduction = 1.0 - score.rss / ref_rss
    score.size = models.size(ref_rss, score.rss)
    return score


def significant(score: Score) -> bool:
    """Beats the reference in the criterion, by a share of its residual, and by a practical size (or by
    a large share: a strong motion can make a clear effect small against the measured torque)."""
    return (score.delta_ic > IC_THRESHOLD and score.reduction > MIN_REDUCTION
            and (score.size > MIN_SIZE or score.reduction > LARGE_REDUCTION))


def cv_wins(models: ChannelModels, without: list[Term], with_: list[Term]) -> tuple[bool, int]:
    """Block cross-validation of the model without against the model with a block: (confirmed, folds won)."""
    a = models.cv(without)
    b = models.cv(with_)
    wins = int(np.sum(b < a))
    return bool(np.median(b / a) < 1.0 - 0.5 * MIN_REDUCTION and wins >= CV_FOLDS - 1), wins


def select_channel(name: str, ch: Channel, candidates: tuple[Candidate, ...], catch_all: CatchAll) -> ChannelResult:
    """Forward selection, drop-one pruning, re-gridding of the chosen blocks, and the catch-all on top."""
    models = ChannelModels(ch)
    base = models.baseline
    if not base.rss > 0.0:
        # a silent or constant signal (gauges that read exactly zero, motors that never move): every
        # share and criterion below is relative to this residual, and there is nothing to explain
        out = ChannelResult(name, ch, base, [], float(len(models.y0)), models)
        out.notes.append("the baseline fits it exactly (a silent or constant signal): no effect can be tested on it")
        return out
    pool = [c for c in candidates if c.applies(ch)]
    first = [models.best_of(c, [], base.residual) for c in pool]
    C, groups = catch_all(models)
    best_blocks = [models.term(s.candidate, s.nl).design.X for s in first]
    full = fit(models.y0, np.hstack([models.Xb, C] + best_blocks), covariance=False)
    n_eff = effective_samples(full.residual, ch.m)
    k0 = models.Xb.shape[1]
    for s in first:
        score_against(models, s, base.rss, k0, n_eff)
    out = ChannelResult(name, ch, base, first, n_eff, models)

    chosen: list[Term] = []
    refused: dict[str, str] = {}          # calibrations passed over in the selection, and why
    current = base
    while len(chosen) < MAX_EFFECTS:
        left = [c for c in pool if all(t.cause != c.cause for t in chosen)]    # one form per cause
        trials = [score_against(models, models.best_of(c, chosen, current.residual), current.rss,
                                models.k(chosen), n_eff) for c in left]
        added = False
        for s in sorted(filter(significant, trials), key=lambda s: -s.delta_ic):
            term = models.term(s.candidate, s.nl)
            # a calibration is chosen only at values a calibration takes: on a linear rig the motor angles
            # follow the joint angles, and the encoder-scale columns fitted the rig's law of the motor
            # angles (ratios of 7750 and -1280, generator E), refused only after it had kept the cable's
            # dead zone and stiffening out
            if term.candidate.calibration and (why := _calibration_refusal(models, chosen + [term], n_eff)):
                refused[term.cause] = why
                continue
            ok, _ = cv_wins(models, chosen, chosen + [term])
            if ok:
                chosen.append(term)
                current = models.fit(chosen)
                added = True
                break
        if not added:
            break
    out.notes += [f"{cause} passed over in the selection: {why}" for cause, why in refused.items()
                  if all(t.cause != cause for t in chosen)]
    chosen = _prune(models, chosen, n_eff)
    chosen, out.nl_sd = _settle(models, chosen, n_eff)
    forms = _best_forms(models, list(chosen), pool, n_eff)
    if [type(t.candidate) for t in forms] != [type(t.candidate) for t in chosen]:
        chosen, out.nl_sd = _settle(models, forms, n_eff)
    # the drop-one test again at the re-searched values: a block chosen while another's value was biased
    # (a dead zone too wide before the stiffening took its share) may have nothing left to explain
    pruned = _prune(models, list(chosen), n_eff)
    if len(pruned) < len(chosen):
        chosen, out.nl_sd = _refine(models, pruned, n_eff)
    chosen = _with_richer_forms(models, chosen, n_eff)
    chosen, out.nl_sd, dropped = _plausible(models, chosen, out.nl_sd, out)
    chosen, out.nl_sd = _shown_in_motion(models, chosen, out.nl_sd, n_eff, out)
    chosen, out.nl_sd = _calibrations_in_place(models, chosen, out.nl_sd, pool, n_eff, out)
    dropped_causes = {d.cause for d in dropped}
    rivals = [c for c in pool if c.cause not in dropped_causes]
    out.terms = [_term_stats(models, chosen, i, rivals, n_eff, base.rss) for i in range(len(chosen))]
    out.model = models.fit(chosen)
    _catch_all_on_top(out, models, chosen, C, groups, n_eff, base)
    models.keep_only(chosen)
    return out


def _settle(models: ChannelModels, chosen: list[Term], n_eff: float) -> tuple[list[Term], list[float]]:
    """Every chosen value searched again with the others in, the continuous ones refined, and the integer
    ones re-searched with the refined values in until they stay: (terms, sd of each nonlinear value)."""
    chosen = _regrid(models, chosen)
    chosen, sds = _refine(models, chosen, n_eff)
    for _ in range(REGRID_PASSES):
        # an integer value (never refined) chosen beside an unrefined continuous one may be off: re-grid
        # the integers with the refined values in, and refine again, until they stay
        before = [t.nl for t in chosen]
        chosen = _regrid(models, chosen, integer_only=True)
        if [t.nl for t in chosen] == before:
            break
        chosen, sds = _refine(models, chosen, n_eff)
    return chosen, sds


def _drop_score(models: ChannelModels, chosen: list[Term], i: int, n_eff: float) -> Score:
    rest = chosen[:i] + chosen[i + 1:]
    t = chosen[i]
    s = Score(t.cause, t.candidate, t.nl, models.rss(chosen), models.k(chosen))
    return score_against(models, s, models.rss(rest), models.k(rest), n_eff)


def _prune(models: ChannelModels, chosen: list[Term], n_eff: float) -> list[Term]:
    """Drop-one test: every block must still earn its place with the others in; drop the weakest that
    does not, and test again."""
    while chosen:
        drops = [_drop_score(models, chosen, i, n_eff) for i in range(len(chosen))]
        weak = [i for i, s in enumerate(drops) if not significant(s)]
        if not weak:
            break
        del chosen[min(weak, key=lambda i: drops[i].delta_ic)]
    return chosen


def _regrid(models: ChannelModels, chosen: list[Term], integer_only: bool = False) -> list[Term]:
    """Search each chosen block's nonlinear parameter (``integer_only``: the integer ones) again with the
    others in, in coordinate passes until no value moves (at most REGRID_PASSES): a value chosen alone
    is biased by the effects not yet in the model (Stribeck + delay; a stiffening exponent chosen before
    the slack is in)."""
    for _ in range(REGRID_PASSES):
        moved = False
        for i, t in enumerate(chosen):
            if t.candidate.nonlinear is None or (integer_only and not t.candidate.integer):
                continue
            others = chosen[:i] + chosen[i + 1:]
            s = models.best_of(t.candidate, others, models.fit(others).residual, t.nl)
            before = [u.nl for u in chosen]
            chosen[i] = models.term(t.candidate, s.nl)
            chosen = _linked_together(models, chosen, i)
            moved |= [u.nl for u in chosen] != before
        if not moved:
            break
    return chosen


def _best_forms(models: ChannelModels, chosen: list[Term], pool: list[Candidate], n_eff: float) -> list[Term]:
    """Each chosen term in the form of its cause that fits best with the others in, by the criterion, every
    value settled again around it (:func:`_settle`): the forms compete once more at the final values,
    since the form picked first, while another effect was still out of the model, need not be the one that
    fits beside it (stiffening on the taut stretch picked alone, where a dead zone then explains the slack
    and the cubic law the rest; the dead zone's width moves with the form)."""
    for i, t in enumerate(chosen):
        others = chosen[:i] + chosen[i + 1:]
        residual = models.fit(others).residual
        for c in pool:
            if c.cause != t.cause or c is chosen[i].candidate:
                continue
            trial = chosen[:i] + [models.term(c, models.best_of(c, others, residual).nl)] + chosen[i + 1:]
            trial = _settle(models, trial, n_eff)[0]
            if models.ic(trial, n_eff) < models.ic(chosen, n_eff):
                chosen = trial
    return chosen


def _linked_together(models: ChannelModels, chosen: list[Term], i: int) -> list[Term]:
    """Term ``i`` and the terms linked to it (:meth:`Candidate.linked`: the same slack) moved together to
    the grid value where the model fits best, when that beats their present values: one parameter at a
    time cannot follow the valley along which both must agree (backlash and the stiffening beyond it)."""
    t = chosen[i]
    moving = {i} | {j for j, o in enumerate(chosen) if j != i and t.candidate.linked(o.candidate)}
    if len(moving) == 1:
        return chosen
    best, best_rss = chosen, models.rss(chosen)
    for v in t.candidate.grid(models.ch):
        trial = [models.term(o.candidate, v) if j in moving else o for j, o in enumerate(chosen)]
        if (rss := models.rss(trial)) < best_rss:
            best, best_rss = trial, rss
    return best


def _with_richer_forms(models: ChannelModels, chosen: list[Term], n_eff: float) -> list[Term]:
    """Each chosen term with an ``upgrade`` (a richer form of its effect at the same nonlinear value)
    takes that form where the extra columns pass the significance tests against the chosen model."""
    for i, t in enumerate(chosen):
        up = t.candidate.upgrade
        if up is None:
            continue
        richer = chosen[:i] + [models.term(up, t.nl)] + chosen[i + 1:]
        s = Score(t.cause, up, t.nl, models.rss(richer), models.k(richer))
        if significant(score_against(models, s, models.rss(chosen), models.k(chosen), n_eff)):
            chosen = richer
    return chosen


def _plausible(models: ChannelModels, chosen: list[Term], nl_sd: list[float],
               out: ChannelResult) -> tuple[list[Term], list[float], list[Candidate]]:
    """The chosen terms without those whose fitted shape contradicts their physics (one at a time, the
    model re-fitted; each noted in ``out``), their nonlinear parameters' sd, and the dropped candidates
    (their causes are no rivals of the rest either): what such a term fitted is left to the catch-all."""
    dropped: list[Candidate] = []
    while True:
        coef = models.fit(chosen).coef
        base = coef[:models.Xb.shape[1]]
        why = [t.candidate.implausible(coef[sl], t.nl, models.ch, base)
               for t, sl in zip(chosen, models.slices(chosen))]
        bad = next((i for i, w in enumerate(why) if w), None)
        if bad is None:
            return chosen, nl_sd, dropped
        out.notes.append(f"{chosen[bad].cause} dropped: {why[bad]}")
        dropped.append(chosen[bad].candidate)
        chosen, nl_sd = chosen[:bad] + chosen[bad + 1:], nl_sd[:bad] + nl_sd[bad + 1:]


def _shown_in_motion(models: ChannelModels, chosen: list[Term], nl_sd: list[float], n_eff: float,
                     out: ChannelResult) -> tuple[list[Term], list[float]]:
    """The chosen terms without those that must show while the motors move (:attr:`Candidate.in_motion`)
    and do not (each dropped with a note, :func:`_not_in_motion`). A motor that sticks takes its torque
    before it moves: the breakaway lags the torque, which a short actuation delay fitted. Only where some
    rest is stuck (signals.stuck): where the friction law holds every rest, the motors creep through them
    and the rows beside them are as good as any."""
    rows = getattr(models.ch, "moving_rows", None)
    if rows is None or rows.all() or not models.ch.stuck.any():
        return chosen, nl_sd
    for i in reversed(range(len(chosen))):
        if not chosen[i].candidate.in_motion or (why := _not_in_motion(models, chosen, i, n_eff)) is None:
            continue
        out.notes.append(f"{chosen[i].cause} dropped: {why}")
        chosen, nl_sd = chosen[:i] + chosen[i + 1:], nl_sd[:i] + nl_sd[i + 1:]
    return chosen, nl_sd


def _calibrations_in_place(models: ChannelModels, chosen: list[Term], nl_sd: list[float], pool: list[Candidate],
                           n_eff: float, out: ChannelResult) -> tuple[list[Term], list[float]]:
    """Each chosen effect tested against the calibration (:attr:`Candidate.calibration`, not chosen yet)
    that fits best in its place, when that is better by more than AMBIGUOUS_IC (closer, both are reported
    as alternatives) and its fitted values are a calibration's (:meth:`Candidate.rejection`): the
    calibration takes the place, and the effect stays beside it only where it then passes the criterion,
    the residual share and the held-out blocks on top of it and the calibration still earns its own place
    (each change noted). Of two explanations the data prefer, the one that only re-tunes the baseline names
    nothing: a Stribeck term at its grid's narrowest beside the effects that fit first is a sharper Coulomb
    transition (generator D seed 719: cogging and a Stribeck term of confidence 0.0005, the transition
    30.8 better in its place)."""
    for cause in [t.cause for t in chosen if not t.candidate.calibration]:
        i = next((j for j, o in enumerate(chosen) if o.cause == cause), None)    # one term per cause
        if i is None:
            continue
        t = chosen[i]
        others = chosen[:i] + chosen[i + 1:]
        residual = models.fit(others).residual
        trials = [others + [models.term(c, models.best_of(c, others, residual).nl)] for c in pool
                  if c.calibration and all(o.cause != c.cause for o in chosen)]
        trials = [tr for tr in trials if _calibration_refusal(models, tr, n_eff) is None]
        if not trials:
            continue
        trial = min(trials, key=lambda tr: models.ic(tr, n_eff))
        if (margin := models.ic(chosen, n_eff) - models.ic(trial, n_eff)) <= AMBIGUOUS_IC:
            continue
        trial, trial_sd = _settle(models, trial, n_eff)
        calibration = trial[-1].cause
        again = score_against(models, models.best_of(t.candidate, trial, models.fit(trial).residual),
                              models.rss(trial), models.k(trial), n_eff)
        both = trial + [models.term(t.candidate, again.nl)]
        # on top of the calibration the effect needs the criterion, the residual share and the held-out
        # blocks, not the practical size again: the size it passed included the low-speed friction both
        # fit (D 703: a true Stribeck term 0.0005 on top, removing 10.7 % of the residual)
        back = (again.delta_ic > IC_THRESHOLD and again.reduction > MIN_REDUCTION
                and cv_wins(models, trial, both)[0])
        if back and not significant(_drop_score(models, both, len(both) - 2, n_eff)):
            continue            # beside the effect the calibration adds nothing: the effect alone stays
        out.notes.append(f"{calibration} fits {margin:.1f} better in the place of {t.cause}: "
                         + (f"{t.cause} kept beside it (criterion gain {again.delta_ic:.1f} on top)" if back else
                            f"{t.cause} replaced (on top of it, criterion gain {again.delta_ic:.1f}, "
                            f"removes {100 * again.reduction:.1f} % of the residual)"))
        chosen, nl_sd = _settle(models, both, n_eff) if back else (trial, trial_sd)
    return chosen, nl_sd


def _calibration_refusal(models: ChannelModels, terms: list[Term], n_eff: float) -> str | None:
    """Why the last of ``terms`` fits no values its calibration can take (:meth:`Candidate.rejection`
    beside the others: a torque-constant scale within its range, a sharper transition, not a smoother
    one), or None. A calibration refused later would take with it the effects it kept out."""
    f = models.fit(terms)
    sl = models.slices(terms)[-1]
    cov = f.covariance(n_eff)
    t = terms[-1]
    return t.candidate.refusal(f.coef[sl], cov[sl, sl], t.nl, 0.0, models.ch, f.coef[:models.Xb.shape[1]])


def _not_in_motion(models: ChannelModels, chosen: list[Term], i: int, n_eff: float) -> str | None:
    """Why term ``i`` does not show while the motors move (None: it does). It must pass the tests with
    the others in on the rows where no motor rests within the filter's reach (effect-free generator D
    records fitted a 1 ms delay from the breakaways after the rests). With :attr:`Candidate.mid_stroke`
    it must also remove MIN_REDUCTION of the residual where no motor rests or reverses: a command's
    latency shifts the whole torque, mid-stroke too, while a motor that sticks for a moment at each
    reversal, shorter than any rest the stuck test judges, breaks away late only there (generator D seed
    138: a load on sticking motors fitted a 1.6 ms delay that made the mid-stroke rows' fit twice as bad).
    Mid-stroke it need only not fit worse than that: where the motors rest at most reversals (steps) few
    rows are left, too few for the criterion (D seed 398, 1 %: a true 5.2 ms delay)."""
    ch = models.ch
    s = _score_on_rows(models, chosen, i, ch.moving_rows, n_eff)
    if not significant(s):
        return (f"where no motor rests ({100 * ch.moving_rows.mean():.0f} % of the rows) it removes "
                f"{100 * s.reduction:.1f} % of the residual (criterion gain {s.delta_ic:.1f}): what it fits is "
                "the motors' breakaway after a rest")
    rows = ch.sliding_rows
    if not chosen[i].candidate.mid_stroke or rows.sum() <= MIN_ROWS_PER_COLUMN * models.k(chosen):
        return None
    s = _score_on_rows(models, chosen, i, rows, n_eff)
    if s.reduction > MIN_REDUCTION:
        return None
    return (f"where no motor rests or reverses ({100 * rows.mean():.0f} % of the rows) it removes "
            f"{100 * s.reduction:.1f} % of the residual: what it fits is the motors' breakaway at the reversals")


def _score_on_rows(models: ChannelModels, chosen: list[Term], i: int, rows: np.ndarray, n_eff: float) -> Score:
    """Term ``i`` scored with the others in on ``rows`` of the stacked system alone (both models fitted
    there, ``n_eff`` scaled by the share of rows kept)."""
    rest = chosen[:i] + chosen[i + 1:]
    (y, X), (_, Xr) = models.system(chosen), models.system(rest)
    yr = next((t.design.y for t in rest if t.design.y is not None), models.y0)
    rss_with, rss_without = rss_only(y[rows], X[rows]), rss_only(yr[rows], Xr[rows])
    s = Score(chosen[i].cause, chosen[i].candidate, chosen[i].nl, rss_with, models.k(chosen))
    n, share = int(rows.sum()), float(rows.mean())
    ic = information_criterion(rss_with, n, s.k, n_eff * share)
    s.delta_ic = information_criterion(rss_without, n, models.k(rest), n_eff * share) - ic
    s.reduction = 1.0 - rss_with / rss_without
    s.size = math.sqrt(max(0.0, rss_without - rss_with) / n) / models.scale
    return s


def _refine(models: ChannelModels, chosen: list[Term], n_eff: float) -> tuple[list[Term], list[float]]:
    """Each continuous nonlinear parameter by variable projection (the linear coefficients solved inside)
    between its grid neighbours, the others held (one coordinate pass); its uncertainty from the
    Jacobian, sigma^2 (J^T J)^-1 inflated by n / n_eff."""
    from scipy.optimize import least_squares

    sds = [0.0] * len(chosen)
    for i, t in enumerate(chosen):
        cand = t.candidate
        if cand.nonlinear is None or cand.integer:
            continue
        grid = sorted(cand.grid(models.ch))
        lo = max([g for g in grid if g < t.nl], default=t.nl)
        hi = min([g for g in grid if g > t.nl], default=t.nl)
        if hi <= lo:
            continue
        others = chosen[:i] + chosen[i + 1:]
        # the solver's trial designs, kept here rather than in the models' cache (they would push out the
        # grid's); it starts from the chosen value's cached design and ends on one of its trials
        trials = {t.nl: t.design}

        def resid(p: np.ndarray) -> np.ndarray:
            nl = float(p[0])
            if nl not in trials:
                trials[nl] = cand.design(models.ch, nl)
            return fit(*models.system(others + [Term(cand, nl, trials[nl])]), covariance=False).residual

        sol = least_squares(resid, [t.nl], bounds=([lo], [hi]), x_scale=[t.nl], diff_step=[1e-3])
        chosen[i] = models.term(cand, float(sol.x[0]), trials.get(float(sol.x[0])))
        jtj = float(sol.jac[:, 0] @ sol.jac[:, 0])
        r = sol.fun
        sigma2 = float(r @ r) / max(1, len(r) - models.k(chosen))
        sds[i] = math.sqrt(sigma2 / jtj * len(r) / n_eff) if jtj > 0 else math.inf
    return chosen, sds


def _term_stats(models: ChannelModels, chosen: list[Term], i: int, pool: list[Candidate], n_eff: float,
                rss_base: float) -> TermStats:
    s = _drop_score(models, chosen, i, n_eff)
    rest = chosen[:i] + chosen[i + 1:]
    _, wins = cv_wins(models, rest, chosen)
    stats = TermStats(chosen[i], s.delta_ic, s.reduction, (models.rss(rest) - s.rss) / rss_base, s.size, wins)
    ic_full = information_criterion(s.rss, models.n, models.k(chosen), n_eff)
    residual = models.fit(rest).residual
    for rival in pool:
        if any(t.cause == rival.cause for t in chosen):
            continue
        r = models.best_of(rival, rest, residual)
        if rival.calibration and _calibration_refusal(models, rest + [models.term(rival, r.nl)], n_eff):
            continue              # at values no calibration takes it is no rival (nor chosen: select_channel)
        margin = information_criterion(r.rss, models.n, r.k, n_eff) - ic_full
        if margin < stats.rival_margin:
            stats.rival, stats.rival_margin = rival.cause, margin
    return stats


def _catch_all_on_top(out: ChannelResult, models: ChannelModels, chosen: list[Term], C: np.ndarray,
                      groups: list[str], n_eff: float, base: Fit) -> None:
    """What the catch-all still finds beyond the chosen model, and which of its groups (position,
    velocity, load, time, ...) that remainder correlates with."""
    y, X = models.system(chosen)
    model = out.model
    Xc = np.hstack([X, C])
    full = fit(y, Xc, covariance=False)
    n = models.n
    out.catch_all_delta_ic = (information_criterion(model.rss, n, X.shape[1], n_eff)
                              - information_criterion(full.rss, n, Xc.shape[1], n_eff))
    out.catch_all_reduction = 1.0 - full.rss / model.rss
    out.catch_all_size = models.size(model.rss, full.rss)
    out.catch_all_total = 1.0 - fit(models.y0, np.hstack([models.Xb, C]), covariance=False).rss / base.rss
    if out.catch_all_reduction > MIN_UNKNOWN_REDUCTION:
        cv_model = models.cv(chosen)
        cv_full = block_cv_mse(y, Xc, models.ch.m, CV_FOLDS)
        out.catch_all_cv_reduction = 1.0 - float(np.median(cv_full / cv_model))
        removed = model.rss - full.rss
        names = list(dict.fromkeys(groups))
        shares = []
        for g in names:
            cols = [j for j, gj in enumerate(groups) if gj == g]
            shares.append((g, (model.rss - rss_only(y, np.hstack([X, C[:, cols]]))) / max(removed, 1e-300)))
        out.correlates = sorted(shares, key=lambda p: -p[1])


def replicates(vmodels: ChannelModels, specs: list[tuple[Candidate, float]],
               catch_all: CatchAll) -> tuple[bool, float, float]:
    """(whether, criterion gain, residual share): does the catch-all find a remainder beyond the named
    ``specs`` on the held-out (validation) data too, each refitted there? A remainder left beside named
    effects must show on data the selection never saw before it is called ``unknown``: a form a little
    off the true one leaves a remainder in-sample the catch-all's many columns fit (issue 21)."""
    y, X = vmodels.system(vmodels.terms(specs))
    C, _ = catch_all(vmodels)
    Xc = np.hstack([X, C])
    model, full = fit(y, X, covariance=False), fit(y, Xc, covariance=False)
    n_eff = effective_samples(full.residual, vmodels.ch.m)
    gain = (information_criterion(model.rss, vmodels.n, X.shape[1], n_eff)
            - information_criterion(full.rss, vmodels.n, Xc.shape[1], n_eff))
    reduction = 1.0 - full.rss / model.rss
    return gain > IC_THRESHOLD and reduction > MIN_UNKNOWN_REDUCTION, gain, reduction
