"""The diagnosis: from measured data to a named cause, fitted effect parameters and the gain.

Steps (docs/diagnosis.md explains the choices):
1. Build the motor channel and, where joint angles are measured, the cable channel.
2. In each channel re-fit the baseline (J, D, kc per motor; K, K beta, offset per ankle axis), score every
   candidate block (nonlinear parameter on a grid) and a catch-all block by the information criterion
   with the effective sample size.
3. Verdict: ``none`` unless a model beats the baseline both statistically and in size; ``unknown`` when
   the catch-all finds a discrepancy the best named candidate explains only in small part; otherwise the
   best named candidate, if block cross-validation confirms it.
4. Refine the named effect's nonlinear parameter with scipy.optimize.least_squares (variable projection)
   and take parameter uncertainties from the Jacobian, inflated for autocorrelation.
5. Measure the gain: inverse-model NRMSE of baseline and extended model on the validation data (or the
   held-out last quarter of the identification data).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ankle_rt.config import Config
from ankle_rt.diagnosis.candidates import (CABLE_CANDIDATES, MOTOR_CANDIDATES, Candidate, Channel,
                                           catch_all_cable, catch_all_motor)
from ankle_rt.diagnosis.regression import block_cv_mse, fit, rss_only
from ankle_rt.diagnosis.selection import ChannelScores, Score, design_matrix, score_channel
from ankle_rt.diagnosis.signals import CableChannel, Geometry, MotorChannel
from ankle_rt.interchange import InterchangeError, Recording

#: a model must beat the baseline's information criterion by this much (nats x 2) to count
IC_THRESHOLD = 20.0
#: ... and remove at least this fraction of the baseline's residual sum of squares
MIN_REDUCTION = 0.04
#: the catch-all must remove this fraction before a discrepancy counts as real without a name
MIN_UNKNOWN_REDUCTION = 0.10
#: practical size: what a named effect explains must reach this NRMSE (RMS / std of the measured torque);
#: on effect-free data the best named candidate explains <= 0.001
MIN_SIZE = 0.003
#: ... and what the catch-all explains, this much: on effect-free data it fits <= 0.0035 of noise and
#: friction-transition error of the velocity estimate with its many columns
MIN_SIZE_UNKNOWN = 0.006
#: a named candidate must explain at least this fraction of what the catch-all removes
MIN_EXPLAINED = 0.6
HOLDOUT_FRACTION = 0.25
CV_FOLDS = 5

PLANTS = ("ankle", "actuator")


class DiagnosisError(ValueError):
    """The inputs cannot be diagnosed as asked (the message says what is missing)."""


@dataclass
class Diagnosis:
    cause: str
    confidence: float
    channel: str | None
    candidates: list[dict[str, Any]]
    parameters: dict[str, dict[str, float]]
    baseline: dict[str, Any]          # baseline-only re-fit, per channel
    nrmse_baseline: float
    nrmse_extended: float
    validation: str
    notes: list[str] = field(default_factory=list)
    effect: dict[str, Any] | None = None        # the sim.effects entry, when a cause is named
    actuator_refit: dict[str, float] | None = None
    baseline_extended: dict[str, Any] | None = None   # the baseline part of the extended model's fit
    detail: dict[str, Any] = field(default_factory=dict, repr=False)   # fits and channels for the report

    @property
    def gain(self) -> float:
        """nrmse_baseline / nrmse_extended (> 1: the extended model predicts better)."""
        return self.nrmse_baseline / self.nrmse_extended if self.nrmse_extended > 0 else 1.0

    def to_json(self) -> dict[str, Any]:
        return {"cause": self.cause, "confidence": round(self.confidence, 4), "channel": self.channel,
                "candidates": self.candidates, "parameters": self.parameters, "baseline": self.baseline,
                "baseline_extended": self.baseline_extended,
                "nrmse_baseline": self.nrmse_baseline, "nrmse_extended": self.nrmse_extended,
                "gain": self.gain, "validation": self.validation, "effect": self.effect,
                "notes": self.notes}


# -- inputs -------------------------------------------------------------------------------------------
def geometry_of(cfg: Config) -> Geometry:
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import PlantParams

    tr = PlantParams.from_config(cfg).transmission
    kin = Kinematics.from_params(tr)
    return Geometry(R_inv=kin.R_inv, R_inv_T=kin.R_inv_T, K=np.diag(kin.K).copy(),
                    levers=np.array([tr.lever_dp, tr.lever_ie]))


def split_recording(rec: Recording, fraction: float) -> tuple[Recording, Recording]:
    """(first part, last ``fraction``) of a recording, for a held-out validation."""
    cut = int(round(len(rec) * (1.0 - fraction)))
    head = Recording({k: v[:cut] for k, v in rec.columns.items()}, rec.source)
    tail = Recording({k: v[cut:] for k, v in rec.columns.items()}, rec.source + " (held-out part)")
    return head, tail


@dataclass
class Inputs:
    kt: float | None
    v_eps: float
    geometry: Geometry | None
    notes: list[str]


def resolve_inputs(rec: Recording, plant: str, cfg: Config | None) -> Inputs:
    if plant not in PLANTS:
        raise DiagnosisError(f"unknown plant {plant!r} (expected one of {', '.join(PLANTS)})")
    notes: list[str] = []
    if plant == "ankle":
        if cfg is None:
            raise DiagnosisError("--plant ankle needs --config (kinematics, torque constant)")
        if not rec.two_motors:
            raise InterchangeError("the ankle plant needs both motors", rec.source, "motor_pos_2", 0)
    kt = cfg["actuator"]["torque_constant"] if cfg is not None else None
    if kt is None and rec.input_kind == "current":
        kt = 1.0
        notes.append("no config: currents used as the input unit (J, D, kc per ampere)")
    geometry = geometry_of(cfg) if plant == "ankle" else None
    if cfg is not None:
        v_eps = cfg["actuator"]["friction_smoothing_velocity"]
    else:
        v_eps = fit_smoothing_velocity(rec, kt, geometry)
        notes.append(f"no config: Coulomb smoothing velocity fitted from the data: {v_eps:.3g} (position unit/s)")
    return Inputs(kt, v_eps, geometry, notes)


def fit_smoothing_velocity(rec: Recording, kt: float | None, geometry: Geometry | None) -> float:
    """The baseline's nonlinear parameter when no config gives it: v_eps of kc tanh(v / v_eps), searched on
    a grid relative to the 99th-percentile speed. Scored jointly with the Stribeck block (at its best
    velocity), which acts at the same low speeds and would otherwise pull v_eps towards itself."""
    probe = MotorChannel(rec, kt, geometry, 1.0)
    v99 = float(np.percentile(np.abs(probe.vel), 99)) or 1.0
    stribeck = next(c for c in MOTOR_CANDIDATES if c.cause == "stribeck")
    y = probe.target()
    best = (math.inf, v99 * 1e-3)
    for v_eps in v99 * np.geomspace(2e-4, 2e-2, 13):
        probe.set_smoothing_velocity(float(v_eps))
        Xb = probe.baseline_design()
        rss = min(rss_only(y, np.hstack([Xb, stribeck.design(probe, vs).X])) for vs in stribeck.grid(probe))
        best = min(best, (rss, float(v_eps)))
    return best[1]


def build_channels(rec: Recording, inputs: Inputs) -> dict[str, Channel]:
    chans: dict[str, Channel] = {"motor": MotorChannel(rec, inputs.kt, inputs.geometry, inputs.v_eps)}
    if inputs.geometry is not None and CableChannel.available(rec):
        chans["cable"] = CableChannel(rec, inputs.geometry)
    return chans


# -- verdict ------------------------------------------------------------------------------------------
def _sigmoid(x: float) -> float:
    return 1.0 / (1.0 + math.exp(-max(-50.0, min(50.0, x))))


def significant(score: Score) -> bool:
    return score.delta_ic > IC_THRESHOLD and score.reduction > MIN_REDUCTION and score.size > MIN_SIZE


def cv_confirms(cs: ChannelScores, score: Score) -> tuple[bool, int]:
    """Block cross-validation of baseline against the candidate: (confirmed, folds won)."""
    ch = cs.channel
    Xb = ch.baseline_design()
    y, X = design_matrix(ch, Xb, score.candidate, score.nl)
    base = block_cv_mse(ch.target(), Xb, ch.m, CV_FOLDS)
    cand = block_cv_mse(y, X, ch.m, CV_FOLDS)
    wins = int(np.sum(cand < base))
    return bool(np.median(cand / base) < 1.0 - 0.5 * MIN_REDUCTION and wins >= CV_FOLDS - 1), wins


@dataclass
class Verdict:
    cause: str
    confidence: float
    channel: ChannelScores | None = None
    score: Score | None = None
    cv_wins: int = 0
    reason: str = ""


def catch_all_cv_reduction(cs: ChannelScores) -> float:
    """1 - median over held-out time blocks of (catch-all error / baseline error): what the catch-all
    predicts where it was not fitted (its in-sample gain partly fits noise: it has many columns)."""
    ch = cs.channel
    base = block_cv_mse(ch.target(), ch.baseline_design(), ch.m, CV_FOLDS)
    full = block_cv_mse(ch.target(), cs.catch_all_X, ch.m, CV_FOLDS)
    return 1.0 - float(np.median(full / base))


def unexplained(cs: ChannelScores) -> bool:
    """A discrepancy is real when the catch-all beats the baseline in the criterion and in held-out blocks."""
    return (cs.catch_all_delta_ic > IC_THRESHOLD and cs.catch_all_reduction > MIN_UNKNOWN_REDUCTION
            and cs.catch_all_size > MIN_SIZE_UNKNOWN and catch_all_cv_reduction(cs) > MIN_UNKNOWN_REDUCTION)


def decide(channels: list[ChannelScores]) -> Verdict:
    named = [(cs, s) for cs in channels for s in cs.scores if significant(s)]
    if named:
        # ranked by the share of its channel's residual removed (comparable across channels), then by the
        # information criterion; the runner-up margin for the confidence is in the criterion
        best_cs, best = max(named, key=lambda p: (p[1].reduction, p[1].delta_ic))
        explained = best.reduction / max(best_cs.catch_all_reduction, 1e-12)
        if explained < MIN_EXPLAINED and unexplained(best_cs):
            return Verdict("unknown", (1.0 - explained) * min(1.0, best_cs.catch_all_reduction / 0.2), best_cs,
                           reason=f"best named candidate {best.cause} explains only {100 * explained:.0f} % "
                                  "of what the catch-all removes")
        ok, wins = cv_confirms(best_cs, best)
        if not ok:
            return Verdict("none", 0.5, best_cs, best, wins,
                           reason=f"{best.cause} not confirmed by block cross-validation ({wins}/{CV_FOLDS} folds)")
        rivals = [s.delta_ic for s in best_cs.scores if s is not best]
        margin = best.delta_ic - max(rivals) if rivals else best.delta_ic
        conf = _sigmoid(margin / 4.0) * min(1.0, explained / 0.9) * wins / CV_FOLDS
        return Verdict(best.cause, conf, best_cs, best, wins)
    real = [cs for cs in channels if unexplained(cs)]
    if real:
        cs = max(real, key=lambda c: c.catch_all_reduction)
        return Verdict("unknown", min(1.0, cs.catch_all_reduction / 0.2), cs,
                       reason=f"catch-all removes {100 * cs.catch_all_reduction:.0f} % of the residual; "
                              "no named candidate is significant")
    named_hint = [min(s.reduction / MIN_REDUCTION, s.size / MIN_SIZE) for cs in channels for s in cs.scores]
    unknown_hint = [min(cs.catch_all_reduction / MIN_UNKNOWN_REDUCTION, cs.catch_all_size / MIN_SIZE_UNKNOWN)
                    for cs in channels]
    hint = max(named_hint + unknown_hint + [0.0])
    hint = min(1.0, hint)
    return Verdict("none", 1.0 - 0.5 * max(0.0, hint))


# -- refinement ---------------------------------------------------------------------------------------
@dataclass
class ExtendedFit:
    candidate: Candidate
    nl: float
    nl_sd: float
    coef: np.ndarray
    cov: np.ndarray
    n_base: int


def refine(cs: ChannelScores, score: Score) -> ExtendedFit:
    """Continuous nonlinear parameter by variable projection around the grid optimum."""
    from scipy.optimize import least_squares

    ch, cand = cs.channel, score.candidate
    Xb = ch.baseline_design()
    nl, nl_sd = score.nl, 0.0
    if cand.nonlinear is not None and not cand.integer:
        grid = [g for g, _ in score.profile]
        i = grid.index(score.nl)
        lo, hi = grid[max(0, i - 1)], grid[min(len(grid) - 1, i + 1)]
        if hi > lo:
            def resid(p: np.ndarray) -> np.ndarray:
                y, X = design_matrix(ch, Xb, cand, float(p[0]))
                return fit(y, X).residual
            sol = least_squares(resid, [score.nl], bounds=([lo], [hi]), x_scale=[score.nl],
                                diff_step=[1e-3])
            nl = float(sol.x[0])
            jtj = float(sol.jac[:, 0] @ sol.jac[:, 0])
            r = sol.fun
            sigma2 = float(r @ r) / max(1, len(r) - score.k)
            nl_sd = math.sqrt(sigma2 / jtj * len(r) / cs.n_eff) if jtj > 0 else math.inf
    y, X = design_matrix(ch, Xb, cand, nl)
    f = fit(y, X)
    return ExtendedFit(cand, nl, nl_sd, f.coef, f.covariance(cs.n_eff), Xb.shape[1])


# -- gain ---------------------------------------------------------------------------------------------
def nrmse(ch: Channel, coef: np.ndarray, cand: Candidate | None = None, nl: float = 0.0) -> float:
    """RMS error of the inverse model's prediction / std of the measured side (filtered alike)."""
    Xb = ch.baseline_design()
    if cand is None:
        y, X = ch.target(), Xb
    else:
        y, X = design_matrix(ch, Xb, cand, nl)
    scale = ch.measured()
    err = y - X @ coef
    return float(np.sqrt(np.mean(err ** 2)) / max(np.std(scale), 1e-300))


# -- reporting helpers ---------------------------------------------------------------------------------
BASELINE_NAMES = {"motor": (("inertia", "kg m^2"), ("damping", "N m s/rad"), ("coulomb", "N m")),
                  "cable": (("stiffness", "N m/rad"), ("stiffness_times_beta", "N m s/rad"), ("offset", "N m"))}


def baseline_dict(name: str, coef: np.ndarray, cov: np.ndarray, per: int) -> dict[str, Any]:
    out = {}
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    for j, (key, unit) in enumerate(BASELINE_NAMES[name]):
        idx = [j + per * i for i in range(len(coef) // per)]
        out[key] = {"value": [float(coef[i]) for i in idx], "sd": [float(sd[i]) for i in idx], "unit": unit}
    if name == "cable":
        out["beta"] = {"value": [float(coef[1 + per * i] / coef[per * i]) for i in range(2)], "unit": "s"}
    return out


def effect_entry(cause: str, params: dict[str, tuple[float, float]]) -> dict[str, Any]:
    entry: dict[str, Any] = {"type": cause}
    for k, (v, _) in params.items():
        entry[k] = int(round(v)) if k == "periods_per_rev" else float(v)
    return entry


# -- the whole -----------------------------------------------------------------------------------------
def diagnose(ident: Recording, validation: Recording | None = None, *, plant: str = "ankle",
             cfg: Config | None = None) -> Diagnosis:
    """Diagnose the model discrepancy of ``ident`` (see the module docstring)."""
    inputs = resolve_inputs(ident, plant, cfg)
    notes = list(inputs.notes)
    if validation is None:
        ident, validation = split_recording(ident, HOLDOUT_FRACTION)
        vname = f"held-out last {int(100 * HOLDOUT_FRACTION)} % of {ident.source}"
    else:
        if validation.two_motors != ident.two_motors:
            raise InterchangeError("validation file has a different number of motors", validation.source,
                                   "motor_pos_2", 0)
        vname = validation.source
    chans = build_channels(ident, inputs)
    vchans = build_channels(validation, inputs)
    if plant == "ankle" and "cable" not in chans:
        notes.append("no joint angles (ankle_dp, ankle_ie): cable side (backlash, stiffness) not diagnosed")
    scored = [score_channel("motor", chans["motor"], MOTOR_CANDIDATES, catch_all_motor)]
    if "cable" in chans and "cable" in vchans:
        scored.append(score_channel("cable", chans["cable"], CABLE_CANDIDATES, catch_all_cable))
    verdict = decide(scored)
    if verdict.reason:
        notes.append(verdict.reason)

    candidates = [{"cause": "none", "channel": None, "score": 0.0, "rss_reduction": 0.0, "size": 0.0}]
    for cs in scored:
        for s in cs.scores:
            item = {"cause": s.cause, "channel": cs.name, "score": round(s.delta_ic, 2),
                    "rss_reduction": round(s.reduction, 5), "size": round(s.size, 5)}
            if s.candidate.nonlinear:
                item[s.candidate.nonlinear] = s.nl
            candidates.append(item)
        candidates.append({"cause": "unknown", "channel": cs.name, "score": round(cs.catch_all_delta_ic, 2),
                           "rss_reduction": round(cs.catch_all_reduction, 5), "size": round(cs.catch_all_size, 5),
                           "catch_all": True})
    candidates.sort(key=lambda c: -c["score"])

    main = verdict.channel or scored[0]
    per = 3
    base_fit = main.baseline
    baseline = {cs.name: baseline_dict(cs.name, cs.baseline.coef, cs.baseline.covariance(cs.n_eff), per)
                for cs in scored}
    vch = vchans[main.name]
    nrmse_base = nrmse(vch, base_fit.coef)
    nrmse_ext = nrmse_base
    parameters: dict[str, dict[str, float]] = {}
    effect = None
    actuator_refit = None
    baseline_extended = None
    detail: dict[str, Any] = {"channels": scored, "validation_channels": vchans, "verdict": verdict}
    motor = scored[0]
    motor_coef = motor.baseline.coef
    if verdict.score is not None and verdict.cause not in ("none", "unknown"):
        ext = refine(main, verdict.score)
        k0 = ext.n_base
        params = ext.candidate.parameters(ext.coef[k0:], ext.cov[k0:, k0:], ext.nl, ext.nl_sd, main.channel,
                                          ext.coef[:k0])
        parameters = {k: {"value": v, "sd": sd} for k, (v, sd) in params.items()}
        effect = effect_entry(verdict.cause, params)
        nrmse_ext = nrmse(vch, ext.coef, ext.candidate, ext.nl)
        detail["extended"] = ext
        baseline_extended = {main.name: baseline_dict(main.name, ext.coef[:k0], ext.cov[:k0, :k0], per)}
        if main.name == "motor":
            motor_coef = ext.coef[:k0]
    if cfg is not None:
        m = len(motor_coef) // per
        actuator_refit = {key: float(np.mean([motor_coef[j + per * i] for i in range(m)]))
                          for j, (key, _) in enumerate(BASELINE_NAMES["motor"])}
    return Diagnosis(cause=verdict.cause, confidence=float(verdict.confidence),
                     channel=verdict.channel.name if verdict.channel and verdict.cause != "none" else None,
                     candidates=candidates, parameters=parameters, baseline=baseline,
                     nrmse_baseline=nrmse_base, nrmse_extended=nrmse_ext, validation=vname, notes=notes,
                     effect=effect, actuator_refit=actuator_refit, baseline_extended=baseline_extended,
                     detail=detail)
