"""The diagnosis: from measured data to the set of effects the model lacks, each fitted, and the gain.

Steps (docs/diagnosis.md explains the choices):
1. Screen the data (sensor artefacts are warned about and masked, never named as physics); irregular
   sample times are put on a uniform grid.
2. Build the motor channel and, where joint angles are measured, the cable channel; a strain-gauge
   offset drift found on the cable side becomes a nuisance term of both baselines.
3. In each channel re-fit the baseline and select a set of candidate blocks: forward selection by the
   information criterion with the effective sample size, each addition confirmed by block
   cross-validation, each chosen block kept only if it still earns its place with the others in.
4. The catch-all on top of the chosen model: a significant remainder is ``unknown``, with what it
   correlates with; a named set that explains only a small part of the catch-all's gain is not named.
5. Refine the continuous nonlinear parameters (variable projection), take uncertainties from the
   Jacobian inflated for autocorrelation, and measure the gain on the validation data (or the held-out
   last quarter): an effect whose own validation gain is <= 1 is dropped.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ankle_rt.config import Config, ConfigError, config_data, config_from_data
from ankle_rt.diagnosis.candidates import (CABLE_CANDIDATES, ENCODER_SCALE_RANGE, INPUT_GROUPS, LOAD_CANDIDATES,
                                           MOTOR_CANDIDATES, RELAXATION_GROUP, Candidate, CatchAll, Channel,
                                           EncoderScale, catch_all_cable, catch_all_motor, folded_coulomb,
                                           time_columns, without_groups)
from ankle_rt.diagnosis.regression import rss_only
from ankle_rt.diagnosis.resample import repair_stale_rows, to_uniform_grid
from ankle_rt.diagnosis.screening import Screening, screen, strain_gauge_drift, strain_gauge_offset
from ankle_rt.diagnosis.selection import (IC_THRESHOLD, LARGE_REDUCTION, MIN_REDUCTION, MIN_SIZE, MIN_SIZE_UNKNOWN,
                                          MIN_UNKNOWN_REDUCTION, AMBIGUOUS_IC, ChannelModels, ChannelResult, Score,
                                          replicates, select_channel, significant)
from ankle_rt.diagnosis.signals import (LINEAR_LOAD_SHARE, CableChannel, Geometry, LoadChannel, MotorChannel,
                                       lattice_step, require_length)
from ankle_rt.interchange import InterchangeError, Recording

#: a named set must explain at least this fraction of what the catch-all removes from the baseline
#: residual when a remainder is left unexplained; else the discrepancy is ``unknown`` without names
MIN_EXPLAINED = 0.6
HOLDOUT_FRACTION = 0.25
#: a fitted nonlinear parameter in the outer cell of its grid (its optimum may lie beyond what the form can
#: describe) must explain at least this share of the baseline residual to be named
EDGE_MIN_SHARE = 0.01
#: baseline columns per motor (J, D, kc) or ankle axis (K, K beta, offset)
PER = 3

PLANTS = ("ankle", "actuator")
#: what each calibration finding's scales are
CALIBRATION_TEXT = {"torque_constant": "the torque constant, or the strain gauges' gain (only the ratio of the "
                                       "current's torque to the gauges' shows: a gauge gain g reads as a scale g), "
                                       "is (true / configured, per motor)",
                    "coulomb_transition": "the Coulomb friction turns sharper than the configured smoothing "
                                          "velocity (per motor, rad/s),",
                    "encoder_scale": "the motor encoders read, relative to the ankle encoders (per axis),"}
#: candidates that are calibration findings (fitted and reported, never causes or sim effects)
CALIBRATIONS = tuple(c.cause for c in MOTOR_CANDIDATES + CABLE_CANDIDATES if c.calibration)


class DiagnosisError(ValueError):
    """The inputs cannot be diagnosed as asked (the message says what is missing)."""


@dataclass
class Diagnosis:
    causes: list[str]                # every named effect, strongest first; ["none"] or [..., "unknown"]
    confidence: float
    channel: str | None              # channel of causes[0]
    candidates: list[dict[str, Any]]
    effects: list[dict[str, Any]]    # per named effect: type, channel, parameters, confidence, shares
    baseline: dict[str, Any]          # baseline-only re-fit, per channel
    nrmse_baseline: float
    nrmse_extended: float
    validation: str
    notes: list[str] = field(default_factory=list)
    data_warnings: list[str] = field(default_factory=list)
    unexplained: dict[str, Any] | None = None   # channel -> what an unexplained remainder correlates with
    adequacy: dict[str, Any] = field(default_factory=dict)   # channel -> what is left after the chosen model
    actuator_refit: dict[str, float] | None = None
    baseline_extended: dict[str, Any] | None = None   # the baseline part of the extended model's fit
    calibration: list[dict[str, Any]] = field(default_factory=list)   # fitted calibration errors, not causes
    detail: dict[str, Any] = field(default_factory=dict, repr=False)   # fits and channels for the report

    @property
    def cause(self) -> str:
        return self.causes[0]

    @property
    def parameters(self) -> dict[str, dict[str, float]]:
        """Parameters of the strongest named effect (all effects: ``effects``)."""
        return self.effects[0]["parameters"] if self.effects else {}

    @property
    def sim_effects(self) -> list[dict[str, Any]]:
        """The ``sim.effects`` entries of every named effect."""
        return [e["effect"] for e in self.effects]

    @property
    def effect(self) -> dict[str, Any] | None:
        return self.effects[0]["effect"] if self.effects else None

    @property
    def gain(self) -> float:
        """nrmse_baseline / nrmse_extended (> 1: the extended model predicts better)."""
        return self.nrmse_baseline / self.nrmse_extended if self.nrmse_extended > 0 else 1.0

    def to_json(self) -> dict[str, Any]:
        return {"cause": self.cause, "causes": self.causes, "confidence": round(self.confidence, 4),
                "channel": self.channel, "effects": self.effects, "data_warnings": self.data_warnings,
                "unexplained": self.unexplained, "adequacy": self.adequacy, "candidates": self.candidates,
                "parameters": self.parameters, "baseline": self.baseline, "baseline_extended": self.baseline_extended,
                "nrmse_baseline": self.nrmse_baseline, "nrmse_extended": self.nrmse_extended,
                "gain": self.gain, "validation": self.validation, "effect": self.effect,
                "calibration": self.calibration,
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
    cogging_prior: float | None = None      # periods per output revolution, from the config
    current_limit: float | None = None      # A, the amplifier's peak limit, from the config
    counts_per_rev: int | None = None       # motor encoder counts per output revolution (ankle plant)
    coulomb: float | None = None            # N m, the nominal Coulomb friction (tells a stuck motor's rests)
    joint_step: float = 0.0                 # rad, one count of the joint encoders (0: resolved finely)
    gear_ratio: float | None = None         # motor turns per output turn (ankle plant): rotor cogging's counts


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
    prior = limit = counts = coulomb = gear = None
    if cfg is not None:
        coulomb = float(cfg["actuator"]["coulomb"]) or None
        if plant == "ankle":
            counts = int(cfg["actuator"]["encoder_counts_per_rev"])
            gear = float(cfg["actuator"]["gear_ratio"])
        per_motor_rev = (cfg.get("diagnosis") or {}).get("cogging_periods_per_motor_rev")
        if per_motor_rev:
            prior = float(per_motor_rev) * cfg["actuator"]["gear_ratio"]
        if rec.input_kind == "current":
            limit = cfg["amplifier"]["current_limit_peak"]
    # read from the file as logged, before stale rows or a new time grid interpolate between counts
    joint_step = max((lattice_step(rec[c]) for c in ("ankle_dp", "ankle_ie") if c in rec), default=0.0)
    if counts:
        counts = logged_counts(rec, counts, notes)
    return Inputs(kt, v_eps, geometry, notes, prior, limit, counts, coulomb, joint_step, gear)


def logged_counts(rec: Recording, configured: int, notes: list[str]) -> int:
    """The motor encoder counts per output revolution the file shows (the lattice its angles lie on, as
    logged) where they are fewer than the ``configured`` ones, else those: the cogging search stays
    COUNTS_PER_PERIOD counts a period above the coarser of the two (angles logged to 0.01 rad, 628 counts,
    read the lattice's own ripple as cogging at 619 periods)."""
    step = max(lattice_step(rec[c]) for c in ("motor_pos_1", "motor_pos_2") if c in rec)
    if step == 0.0 or round(2.0 * math.pi / step) >= configured:
        return configured
    logged = max(1, round(2.0 * math.pi / step))
    notes.append(f"the motor angles lie on a lattice of {step:.4g} rad ({logged} counts per output revolution), "
                 f"coarser than actuator.encoder_counts_per_rev ({configured}): cogging counts are searched only as "
                 "far as the logged counts resolve")
    return logged


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


def build_channels(rec: Recording, inputs: Inputs, good: np.ndarray | None = None) -> dict[str, Channel]:
    chans: dict[str, Channel] = {"motor": MotorChannel(rec, inputs.kt, inputs.geometry, inputs.v_eps, good,
                                                       inputs.cogging_prior, inputs.counts_per_rev, inputs.coulomb,
                                                       inputs.gear_ratio)}
    if inputs.geometry is not None and CableChannel.available(rec):
        chans["cable"] = CableChannel(rec, inputs.geometry, good, joint_step=inputs.joint_step)
    if inputs.geometry is not None and ("cable" in chans or LoadChannel.available(rec)):
        chans["load"] = LoadChannel(rec, inputs.geometry, good)
    return chans


def _joint_angles_add_noise(chans: dict[str, Channel]) -> float | None:
    """How many times better the spring law of the motor angles (a linear load: the load channel) fits the
    gauges than the cable law of the stretch with the (counted) joint angles, where it is better by more
    than 1 / JOINT_NOISE_RATIO (None: it is not, or the joint angles are not counts). The joint encoders
    then add their counts' error to the stretch rather than information: generator D's bench rigs with
    12-bit joint encoders (a count 1.5 mrad beside 2-7 mrad of stretch) fitted 300-5000x better without
    them, and the cable channel's residual, the joint angles' quantisation, hid a stiffening cable.

    Each law is compared linear, beside the same linear filters of its angle
    (:meth:`CableChannel.history_columns`, in the load's baseline; without them a relaxing cable made any
    joint angles look like noise), and, where the linear laws say "noise", again in its best nonlinear form
    (each side's best single candidate on its own baseline, the cable's without those filters: if anything
    a lean toward the load): a dead zone or a stiffening in the cable fits the linear cable law badly with
    no noise at all, while the rig's softer spring in series hides it in the law of the motor angles
    (generator E: a dead zone per axis on a 350 N m/rad rig, 12x closer without the joint angles, fits 16x
    better than the load's best form once the cable law has its dead zone)."""
    cable, load = chans["cable"], chans["load"]
    if cable.joint_step <= 0.0:
        return None
    rss_cable = rss_only(cable.target(), np.hstack([cable.baseline_design(), cable.history_columns()]))
    rss_load = rss_only(load.target(), load.baseline_design())
    if rss_load >= JOINT_NOISE_RATIO * rss_cable:
        return None
    rss_cable = min(rss_cable, _best_single_form(cable, CABLE_CANDIDATES))
    rss_load = min(rss_load, _best_single_form(load, LOAD_CANDIDATES))
    if rss_load < JOINT_NOISE_RATIO * rss_cable:
        return rss_cable / max(rss_load, 1e-300)
    return None


def _best_single_form(ch: Channel, pool: tuple[Candidate, ...]) -> float:
    """The smallest residual sum of squares of ``ch``'s baseline with one effect of ``pool`` at its best
    value. No calibration: on a linear load the joint angles follow the motor angles, and the encoder-scale
    columns rebuild the load's law of the motor angles in the cable channel (generator D seed 126, 12-bit
    joint encoders: the cable residual 179 -> 0.96 with them, 176 with a dead zone or a stiffening)."""
    models = ChannelModels(ch)
    return min((models.best_of(c, [], models.baseline.residual).rss for c in pool
                if c.applies(ch) and not c.calibration), default=math.inf)


#: the load channel's baseline residual below this share of the cable channel's: the joint angles are noise
JOINT_NOISE_RATIO = 0.1


# -- the chosen model of a channel, refined and fitted ---------------------------------------------------
@dataclass
class ChannelFit:
    """A channel's final model: its effects (candidate, nonlinear value, its sd) and their joint fit."""

    result: ChannelResult
    specs: list[tuple[Candidate, float, float]]      # (candidate, nonlinear value, its sd)
    coef: np.ndarray
    cov: np.ndarray
    slices: list[slice]                              # each effect's coefficients in coef
    n_base: int

    @property
    def name(self) -> str:
        return self.result.name


def joint_fit(result: ChannelResult, specs: list[tuple[Candidate, float, float]]) -> ChannelFit:
    """The baseline and ``specs`` (candidate, nonlinear value, its sd) fitted jointly, with the
    coefficient covariance inflated for the residual's autocorrelation."""
    terms = result.models.terms([(c, v) for c, v, _ in specs])
    f = result.models.fit(terms)
    return ChannelFit(result, specs, f.coef, f.covariance(result.n_eff), result.models.slices(terms),
                      result.models.Xb.shape[1])


def nrmse(models: ChannelModels, specs: list[tuple[Candidate, float]], coef: np.ndarray) -> float:
    """RMS error of the inverse model's prediction / std of the measured side (filtered alike)."""
    y, X = models.system(models.terms(specs))
    err = y - X @ coef
    return float(np.sqrt(np.mean(err ** 2)) / models.scale)


def validation_nrmse(result: ChannelResult, vmodels: ChannelModels, specs: list[tuple[Candidate, float]]) -> float:
    """Fit ``specs`` on the identification channel, predict the validation channel."""
    return nrmse(vmodels, specs, result.models.fit(result.models.terms(specs)).coef)


# -- reporting helpers ---------------------------------------------------------------------------------
BASELINE_NAMES = {"motor": (("inertia", "kg m^2"), ("damping", "N m s/rad"), ("coulomb", "N m")),
                  "cable": (("stiffness", "N m/rad"), ("stiffness_times_beta", "N m s/rad"), ("offset", "N m"))}
#: the load channel's baseline: the cable and the foot's linear load in series (signals.LoadChannel)
BASELINE_NAMES["load"] = BASELINE_NAMES["cable"]


def baseline_dict(name: str, coef: np.ndarray, cov: np.ndarray, m: int) -> dict[str, Any]:
    """The physical baseline parameters per motor or axis (nuisance columns of a sensor drift left out)."""
    out = {}
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    for j, (key, unit) in enumerate(BASELINE_NAMES[name]):
        idx = [j + PER * i for i in range(m)]
        out[key] = {"value": [float(coef[i]) for i in idx], "sd": [float(sd[i]) for i in idx], "unit": unit}
    if name != "motor":
        out["beta"] = {"value": [float(coef[1 + PER * i] / coef[PER * i]) if coef[PER * i] != 0.0 else math.nan
                                 for i in range(m)], "unit": "s"}
    return out


def effect_entry(cand: Candidate, params: dict[str, tuple[float, float]]) -> dict[str, Any]:
    """The ``sim.effects`` entry of a fitted candidate (its form's fixed settings included)."""
    entry: dict[str, Any] = {"type": cand.cause}
    for k, (v, _) in params.items():
        entry[k] = int(round(v)) if k == "periods_per_rev" else float(v)
    return {**entry, **cand.form}


def _why_not(s: Score, chosen: set[str]) -> str | None:
    """Why a candidate scored alone is not among the chosen effects of its channel (None: it is)."""
    if s.cause in chosen:
        return None
    if not significant(s):
        return (f"alone it does not pass the tests (criterion gain {s.delta_ic:.1f}, needs {IC_THRESHOLD:g}; "
                f"removes {100 * s.reduction:.1f} % of the residual, needs {100 * MIN_REDUCTION:g} %; "
                f"size {s.size:.4f}, needs {MIN_SIZE:g} or {100 * LARGE_REDUCTION:g} % of the residual)")
    return ("passes alone but not beside the chosen effects (forward selection, cross-validation, drop-one), "
            "or was rejected or dropped by the validation (notes say which)")


def candidate_table(results: list[ChannelResult], fits: dict[str, ChannelFit]) -> list[dict[str, Any]]:
    """Every candidate alone against its channel's baseline, strongest first, each not chosen with why
    (``dropped``); then ``none`` and the catch-all ``unknown`` of each channel, which are verdicts, not
    causes, and never outrank one."""
    named, tail = [], [{"cause": "none", "channel": None, "score": 0.0, "rss_reduction": 0.0, "size": 0.0}]
    for res in results:
        chosen = {c.cause for c, _, _ in fits[res.name].specs}
        for s in res.first:
            item = {"cause": s.cause, "channel": res.name, "score": round(s.delta_ic, 2),
                    "rss_reduction": round(s.reduction, 5), "size": round(s.size, 5)}
            if (why := _why_not(s, chosen)) is not None:
                item["dropped"] = why
            item.update(s.candidate.nonlinear_values(s.nl))
            named.append(item)
        tail.append({"cause": "unknown", "channel": res.name, "score": round(res.catch_all_delta_ic, 2),
                     "rss_reduction": round(res.catch_all_reduction, 5), "size": round(res.catch_all_size, 5),
                     "catch_all": True})
    named.sort(key=lambda c: -c["score"])
    return named + tail


def _none_confidence(results: list[ChannelResult]) -> float:
    """1 - 1/2 x how close the best candidate (or the catch-all) came to the thresholds."""
    hint = [min(s.reduction / MIN_REDUCTION, s.size / MIN_SIZE, max(0.0, s.delta_ic) / IC_THRESHOLD)
            for r in results for s in r.first]
    hint += [min(r.catch_all_reduction / MIN_UNKNOWN_REDUCTION, r.catch_all_size / MIN_SIZE_UNKNOWN) for r in results]
    return 1.0 - 0.5 * min(1.0, max(hint + [0.0]))


def _describe_remainder(res: ChannelResult) -> dict[str, Any]:
    top = [(g, s) for g, s in res.correlates if s >= 0.25][:3] or res.correlates[:1]
    return {"channel": res.name, "residual_removed_by_catch_all": round(res.catch_all_reduction, 4),
            "size": round(res.catch_all_size, 5),
            "correlates_with": [{"with": g, "share": round(s, 3)} for g, s in top]}


def _add_drift_nuisance(ch: Channel) -> None:
    """A strain-gauge drift as nuisance columns of the channel's baseline (built anew): slow shapes of time
    per motor or axis, beside the load's own dynamics in the load channel, and on the motor side the gauges'
    constant offset as well (the cable side has its own)."""
    ch.nuisance = time_columns(ch)
    if isinstance(ch, LoadChannel):
        ch.nuisance = np.hstack([ch.history_columns(), ch.nuisance])
    if isinstance(ch, MotorChannel):
        ch.nuisance = np.hstack([ch.nuisance, ch.constants()])


def _remove_gauge_offsets(chans: dict[str, Channel], label: str, warnings: list[str]) -> None:
    """Strain-gauge zero offsets found on the cable side (where the ankle encoders show what the cables
    carry): warned about and taken out of the motor channel's cable torque, so they never read as a load
    (``torque_offset``)."""
    if "cable" not in chans or (off := strain_gauge_offset(chans["cable"])) is None:
        return
    warnings.append(f"{label} data: the strain gauges read a zero offset of {off[0]:+.3g} N m (DP), {off[1]:+.3g} "
                    "N m (IE) that the cable stretch from the ankle encoders does not carry: a sensor offset, "
                    "not a load; corrected before the motor side is fitted")
    chans["motor"].remove_gauge_offset(off)


def _motor_scales(chans: dict[str, Channel]) -> None:
    """Where the ankle encoders show a plausible scale ratio of the motor encoders to them, the motor
    channel's rotor cogging may sit at N G / f as well as N G (:meth:`Cogging.rotor_count`; either
    encoder may be the one off): generator B's 1134-period cogging read at 1123 with a 1 % scale."""
    if "cable" not in chans:
        return
    ratios = EncoderScale().ratios(chans["cable"])
    if np.all((ENCODER_SCALE_RANGE[0] < ratios) & (ratios < ENCODER_SCALE_RANGE[1])):
        chans["motor"].motor_scales = (1.0, float(np.mean(ratios)))


def _named_sets(results: list[ChannelResult], notes: list[str], unusable: bool, vmodels: dict[str, ChannelModels],
                catch_alls: dict[str, CatchAll]) -> tuple[dict[str, list[tuple[Candidate, float]]], dict[str, Any]]:
    """Per channel the effects to name, and the channels with an unexplained remainder. A named set that
    explains less than MIN_EXPLAINED of the catch-all's gain is a partial proxy: not named. What the set
    explains is measured jointly (:attr:`ChannelResult.named_share`), not as the sum of each effect's
    drop-one share: overlapping effects (two frictions at every reversal) share what they explain, and
    each one's drop-one share counts only what the others cannot take over. A remainder
    beside named effects counts only where it shows on the validation data too (:func:`replicates`).
    From an ``unusable`` record nothing is named, a remainder neither: what the models leave of gauges
    read against the stretch or of a dead encoder is no discrepancy of the device."""
    chosen: dict[str, list[tuple[Candidate, float]]] = {}
    unexplained: dict[str, Any] = {}
    for res in results:
        specs = [(ts.term.candidate, ts.term.nl) for ts in res.terms]
        if res.unexplained and not unusable:
            explained = res.named_share / max(res.catch_all_total, 1e-12)
            if specs and explained < MIN_EXPLAINED:
                notes.append(f"{res.name} channel: {', '.join(c.cause for c, _ in specs)} explain only "
                             f"{100 * explained:.0f} % of what the catch-all removes: not named")
                specs = []
            held_out = replicates(vmodels[res.name], specs, catch_alls[res.name]) if specs else (True, 0.0, 0.0)
            if held_out[0]:
                unexplained[res.name] = _describe_remainder(res)
            else:
                notes.append(f"{res.name} channel: the catch-all's remainder beside "
                             f"{', '.join(c.cause for c, _ in specs)} (removes {100 * res.catch_all_reduction:.0f} "
                             f"% in-sample) does not show on the validation data (criterion gain "
                             f"{held_out[1]:.1f}, needs {IC_THRESHOLD:g}; removes {100 * held_out[2]:.1f} %, "
                             f"needs {100 * MIN_UNKNOWN_REDUCTION:g} %): not unknown")
        chosen[res.name] = [] if unusable else specs
    return chosen, unexplained


def _validated(res: ChannelResult, vch: ChannelModels, specs: list[tuple[Candidate, float]],
               notes: list[str]) -> list[tuple[Candidate, float]]:
    """Drop, one at a time, the effect whose removal does not make the validation prediction worse."""
    specs = list(specs)
    while specs:
        full = validation_nrmse(res, vch, specs)
        gains = [validation_nrmse(res, vch, specs[:i] + specs[i + 1:]) / full for i in range(len(specs))]
        worst = int(np.argmin(gains))
        if gains[worst] > 1.0:
            break
        notes.append(f"{specs[worst][0].cause} dropped: it does not improve the prediction of the "
                     f"validation data (gain {gains[worst]:.3f})")
        del specs[worst]
    return specs


def _rejection(res: ChannelResult, cf: ChannelFit, i: int) -> str | None:
    """Why the ``i``-th effect of a channel's joint fit cannot be named (None: it can): its fitted
    parameters are non-finite or outside the effect's range, or its nonlinear parameter sits in the outer
    cell of its grid (between the end and its neighbour) while it explains almost nothing (generator C's
    seed 118: a 0.4 ms delay explaining 0.04 % beside a load offset)."""
    cand, nl, nl_sd = cf.specs[i]
    sl = cf.slices[i]
    base = cf.coef[:cf.n_base]
    reason = cand.refusal(cf.coef[sl], cf.cov[sl, sl], nl, nl_sd, res.channel, base)
    if reason or cand.nonlinear is None or cand.integer:
        return reason
    grid = sorted(cand.grid(res.channel))
    share = next(ts.share for ts in res.terms if ts.term.candidate is cand)
    # refined between grid neighbours, a value in an outer cell may be held there by the grid's end
    if len(grid) > 2 and (nl <= grid[1] or nl >= grid[-2]) and share < EDGE_MIN_SHARE:
        return (f"{cand.nonlinear} = {nl:.4g} lies in the edge cell of its grid and the effect explains only "
                f"{100 * share:.2f} % of the residual: the form does not describe what it fits")
    return None


def _sound_fit(res: ChannelResult, chosen: list[tuple[Candidate, float]], notes: list[str]) -> ChannelFit:
    """The joint fit of a channel's chosen effects without those whose fit cannot be a simulator effect
    (each dropped with its reason in ``notes``; the rest re-fitted): nothing non-finite or out of range
    is ever named or written into a config."""
    sd_of = {ts.term.cause: sd for ts, sd in zip(res.terms, res.nl_sd)}
    specs = [(c, v, sd_of[c.cause]) for c, v in chosen]
    while True:
        cf = joint_fit(res, specs)
        reasons = [_rejection(res, cf, i) for i in range(len(specs))]
        bad = next((i for i, r in enumerate(reasons) if r), None)
        if bad is None:
            return cf
        notes.append(f"{res.name} channel: {specs[bad][0].cause} rejected: {reasons[bad]}")
        del specs[bad]


def _effect_entries(results: list[ChannelResult], fits: dict[str, ChannelFit], vchans: dict[str, ChannelModels],
                    notes: list[str]) -> list[dict[str, Any]]:
    """The ``effects`` list: each named effect's parameters, confidence, shares and own validation gain."""
    stats = {(res.name, ts.term.cause): ts for res in results for ts in res.terms}
    effects: list[dict[str, Any]] = []
    for res in results:
        cf = fits[res.name]
        vch = vchans[res.name]
        full = nrmse(vch, [(c, v) for c, v, _ in cf.specs], cf.coef)
        for i, (cand, nl, nl_sd) in enumerate(cf.specs):
            sl = cf.slices[i]
            params = cand.parameters(cf.coef[sl], cf.cov[sl, sl], nl, nl_sd, res.channel, cf.coef[:cf.n_base])
            others = [(c, v) for j, (c, v, _) in enumerate(cf.specs) if j != i]
            ts = stats[(res.name, cand.cause)]
            entry = {"type": cand.cause, "channel": res.name,
                     "parameters": {k: {"value": v, "sd": sd} for k, (v, sd) in params.items()},
                     "confidence": round(ts.confidence, 4), "rss_share": round(ts.share, 5), "size": round(ts.size, 5),
                     "gain": validation_nrmse(res, vch, others) / full if full > 0 else 1.0,
                     "effect": effect_entry(cand, params)}
            if ts.rival is not None and ts.rival_margin < AMBIGUOUS_IC:
                entry["alternative"] = ts.rival
                notes.append(f"{cand.cause} and {ts.rival} fit these data nearly equally well (criterion "
                             f"{ts.rival_margin:.1f} apart: nearly collinear regressors): confidence shared")
            effects.append(entry)
    return sorted(effects, key=lambda e: -e["size"])


def _adequacy(results: list[ChannelResult]) -> dict[str, Any]:
    """Per channel, what the catch-all still finds beyond the chosen model, and the residual's share of
    independent samples (its whiteness)."""
    return {r.name: {"catch_all_reduction": round(r.catch_all_reduction, 4),
                     "catch_all_cv_reduction": round(r.catch_all_cv_reduction, 4),
                     "catch_all_size": round(r.catch_all_size, 5),
                     "independent_share": round(r.n_eff / len(r.channel.target()), 4),
                     "adequate": not r.unexplained} for r in results}


def _gauges_against_stretch(chan_sets: list[dict[str, Any]]) -> str | None:
    """A warning where the gauges read against the stretch in a record (identification, validation): a
    cable stiffness below zero on an axis both alone and beside the encoder-scale columns, with a spring
    term at least AGAINST_SHARE of the gauge torque's sd (a 0.9 motor-encoder scale turns the one alone
    negative, -2152 N m/rad on generator D's seed 112; in walking the scale column can take the other, 115),
    or on a rig (a spring law of the motor angles explaining LINEAR_LOAD_SHARE of both axes' torque; there
    the joint angle's scale column takes the cable's spring term) a rig stiffness below zero. That is a
    gauge of the wrong sign or swapped axes: no cable law holds, and the motor side's cable torque is wrong
    too, so every effect would be judged against it (both gauges flipped read `none`)."""
    for chans in chan_sets:
        found: dict[int, float] = {}
        if "cable" in chans:
            ch = chans["cable"]
            alone = np.linalg.lstsq(ch.baseline_design(), ch.target(), rcond=None)[0][[0, PER]]
            beside, size = EncoderScale().stiffness(ch)
            found |= {i: k for i, k in enumerate(alone) if k < 0.0 and beside[i] < 0.0 and size[i] >= AGAINST_SHARE}
        if "load" in chans and np.all(chans["load"].spring_share >= LINEAR_LOAD_SHARE):
            found |= {i: k for i, k in enumerate(chans["load"].stiffness) if k < 0.0}
        if found:
            axes = ", ".join(f"{CableChannel.AXES[i].upper()} {k:.4g} N m/rad" for i, k in sorted(found.items()))
            return (f"the strain gauges read against the stretch (stiffness fitted at {axes}): a gauge of the "
                    "wrong sign or swapped axes; nothing is named")
    return None


#: size (sd) of a negative spring term against the gauge torque's before the gauges are taken to read against
#: the stretch (flipped gauges: ~1; silent gauges, or motor angles that follow no stretch: ~0)
AGAINST_SHARE = 0.5


def _refit_problem(cfg: Mapping[str, Any], refit: dict[str, float]) -> str | None:
    """Why the config loader would refuse the re-fitted actuator baseline (a range, the controller's gain
    margin on the re-fitted plant), None if it takes it: a baseline fitted where it explains nothing
    (motion one way only: a negative Coulomb term; gauges of the wrong sign: a tenth of the inertia) is
    never simulated or written into a config that then fails to load. The effects' own values are checked
    as candidates (rejection), the controller's build-time checks by the closed loop's run."""
    data = config_data(cfg)
    data["actuator"].update(refit)
    try:
        config_from_data(data, lambda _key: "re-fit", str(getattr(cfg, "source", "config")))
    except ConfigError as exc:
        return str(exc)
    return None


def _holding(res: ChannelResult, ch: MotorChannel) -> np.ndarray:
    """What the motor channel's chosen model holds a resting motor with (N m, samples x motors of ``ch``):
    the nominal Coulomb level the first stuck test used plus what each chosen friction effect adds near
    zero speed (:meth:`Candidate.holding`: a Stribeck excess, mu |tc|), never below 0."""
    h = np.zeros((ch.n_samples, ch.m)) + ch.coulomb
    for ts, sl in zip(res.terms, res.models.slices([ts.term for ts in res.terms])):
        h = h + ts.term.candidate.holding(ch, res.model.coef[sl])
    return np.maximum(h, 0.0)


def _select_motor(chans: dict[str, Channel], vchans: dict[str, Channel], pool: tuple[Candidate, ...],
                  catch_all: CatchAll, drift: bool) -> ChannelResult:
    """The motor channel's selection with the stuck rests judged twice: first against the nominal Coulomb
    level alone (the channels as built), then against what the chosen model's friction holds near zero
    speed (:func:`_holding`: a Stribeck excess and a load-dependent term hold more than Coulomb alone, and
    a rest they hold is one their law explains). Where that changes the stuck rests of the identification
    or validation data, both are weighed again and the channel selected once more (once: the second
    model's friction does not judge the rests again). A rest's torque cannot tell static friction from a
    steep law of velocity, the motion can: the judgement whose model predicts the validation rows far
    from any rest better (:func:`_moving_error`) is kept, the first one restored where it wins."""
    res = select_channel("motor", chans["motor"], pool, catch_all)
    if chans["motor"].coulomb is None:
        return res
    first = _moving_error(res, vchans["motor"])
    levels = [_holding(res, c["motor"]) for c in (chans, vchans)]
    before = int(chans["motor"].stuck.sum())
    if not _weigh_motor_rests(chans, vchans, levels, drift):
        return res
    again = select_channel("motor", chans["motor"], pool, catch_all)
    after = int(chans["motor"].stuck.sum())
    errors = [first, _moving_error(again, vchans["motor"])]
    text = ("stuck rests judged again against what the chosen friction ("
            + ", ".join(ts.term.cause for ts in res.terms) + f") holds near zero speed: {before} -> {after} "
            "stuck samples in the identification data; selected again")
    if errors[0] < errors[1]:
        _weigh_motor_rests(chans, vchans, [c["motor"].coulomb for c in (chans, vchans)], drift)
        res.notes.insert(0, text + f", but that model predicts the validation data where no motor rests worse "
                         f"(NRMSE {errors[1]:.4g} against {errors[0]:.4g}): the first judgement kept")
        return res
    again.notes.insert(0, text)
    return again


def _weigh_motor_rests(chans: dict[str, Channel], vchans: dict[str, Channel], levels: list, drift: bool) -> bool:
    """Judge the motor channels' rests (identification, validation) against the holding ``levels``
    (:meth:`MotorChannel.weigh_rests`) and, with a gauge drift, build its nuisance columns again on the
    signals filtered anew; whether any stuck sample changed."""
    changed = any([c["motor"].weigh_rests(h) for c, h in zip((chans, vchans), levels)])
    if changed and drift:
        for c in (chans, vchans):
            _add_drift_nuisance(c["motor"])
    return changed


def _moving_error(res: ChannelResult, vch: MotorChannel) -> float:
    """The RMS prediction error of ``res``'s chosen motor model (fitted on the identification data) on
    the validation rows where no motor rests within the filter's reach (no stuck sample weighs there, so
    models chosen under either judgement of the rests are compared on the same rows); inf without such
    rows."""
    rows = vch.moving_rows
    if not rows.any():
        return math.inf
    vm = ChannelModels(vch)
    specs = _validated(res, vm, [(ts.term.candidate, ts.term.nl) for ts in res.terms], [])
    y, X = vm.system(vm.terms(specs))
    return float(np.sqrt(np.mean((y - X @ res.models.fit(res.models.terms(specs)).coef)[rows] ** 2)))


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
    require_length(ident)
    require_length(validation)
    ident, note = repair_stale_rows(ident)
    validation, vnote = repair_stale_rows(validation)
    notes += [n for n in (note, vnote) if n]
    scr: Screening = screen(ident, inputs.v_eps, inputs.current_limit, f"identification data ({ident.source})")
    vscr: Screening = screen(validation, inputs.v_eps, inputs.current_limit, f"validation data ({vname})")
    unusable = scr.unusable or vscr.unusable
    warnings = scr.warnings + vscr.warnings
    ident, scr.good, note = to_uniform_grid(ident, scr.good)
    validation, vscr.good, vnote = to_uniform_grid(validation, vscr.good)
    notes += [n for n in (note, vnote) if n]
    chans = build_channels(ident, inputs, scr.good)
    vchans = build_channels(validation, inputs, vscr.good)
    loads = [c.get("load") for c in (chans, vchans)]
    linear_load = all(ch is not None and ch.linear for ch in loads)
    with_joints = "cable" in chans and "cable" in vchans
    noisy_joints = _joint_angles_add_noise(chans) if linear_load and with_joints else None
    cable_side = "load" if linear_load and (not with_joints or noisy_joints) else "cable" if with_joints else None
    spring = ("the gauges read a spring law of the motor angles (a linear load on the foot: the spring term "
              "explains " + ", ".join(f"{100 * v:.1f} %" for v in loads[0].spring_share) + " of the DP, IE torque)"
              if linear_load else "")
    if plant == "ankle" and cable_side is None:
        notes.append("no joint angles (ankle_dp, ankle_ie): cable side (backlash, stiffness) not diagnosed")
    elif cable_side == "load" and not with_joints:
        missing = "no joint angles" if "cable" not in chans else "no joint angles in the validation data"
        notes.append(f"{missing}, but {spring}: a gap between rotor and pulley and a stiffening cable are "
                     "looked for in the load channel")
    elif cable_side == "load":
        notes.append(f"{spring}, {noisy_joints:.0f}x closer than the cable law of the stretch with the joint angles, "
                     f"linear or in its best nonlinear form "
                     f"(one joint count {inputs.joint_step:.3g} rad): the joint encoders add their counts' error "
                     "rather than information, so the cable side is diagnosed in the load channel")
    drift = "cable" in chans and (drift_pp := strain_gauge_drift(chans["cable"])) is not None
    if drift:
        warnings.append("the strain-gauge offsets drift over the record (peak to peak "
                        + ", ".join(f"{d:.3g} N m" for d in drift_pp) + " on DP, IE): fitted as a sensor drift "
                        "in both channels, not as an effect; a load offset on the motors cannot then be told "
                        "from the gauges' own offset, so torque_offset is not tried")
        for ch in list(chans.values()) + list(vchans.values()):
            _add_drift_nuisance(ch)
        scr.skip.add("torque_offset")
    else:
        _remove_gauge_offsets(chans, "identification", warnings)
        _remove_gauge_offsets(vchans, "validation", warnings)
    _motor_scales(chans)
    if (against := _gauges_against_stretch([chans, vchans])) is not None:
        warnings.append(against)
        unusable = True
    skip = scr.skip
    motor_pool = tuple(c for c in MOTOR_CANDIDATES if c.cause not in skip)
    motor_catch_all = without_groups(catch_all_motor, INPUT_GROUPS) if scr.one_way or vscr.one_way else catch_all_motor
    results = [_select_motor(chans, vchans, motor_pool, motor_catch_all, drift)]
    vmodels = {name: ChannelModels(vch) for name, vch in vchans.items()}
    if cable_side == "cable":
        results.append(select_channel("cable", chans["cable"], CABLE_CANDIDATES, catch_all_cable))
    load_catch_all = without_groups(catch_all_cable, {RELAXATION_GROUP})     # in the load's baseline
    if cable_side == "load":
        results.append(select_channel("load", chans["load"], LOAD_CANDIDATES, load_catch_all))

    notes += [f"{res.name} channel: {n}" for res in results for n in res.notes]
    catch_alls = {"motor": motor_catch_all, "cable": catch_all_cable, "load": load_catch_all}
    chosen, unexplained = _named_sets(results, notes, unusable, vmodels, catch_alls)
    for res in results:
        chosen[res.name] = _validated(res, vmodels[res.name], chosen[res.name], notes)
    fits = {res.name: _sound_fit(res, chosen[res.name], notes) for res in results}
    entries = _effect_entries(results, fits, vmodels, notes)
    effects = [e for e in entries if e["type"] not in CALIBRATIONS]
    calibration = [e for e in entries if e["type"] in CALIBRATIONS]
    for e in calibration:
        e.pop("effect")
        warnings.append(f"calibration: {CALIBRATION_TEXT[e['type']]} "
                        + ", ".join(f"{k} {v['value']:.4g} +/- {v['sd']:.2g}" for k, v in e["parameters"].items())
                        + ": fitted as a calibration, not named as an effect")
    causes = [e["type"] for e in effects] + (["unknown"] if unexplained else [])
    if unusable and not causes:
        causes = ["unknown"]
    causes = causes or ["none"]
    if effects or calibration:
        confidence = min(e["confidence"] for e in effects or calibration)
    elif unexplained:
        confidence = min(1.0, max(r.catch_all_reduction for r in results if r.name in unexplained) / 0.2)
    elif unusable:
        confidence = 0.0
    else:
        confidence = _none_confidence(results)
    for name, u in unexplained.items():
        notes.append(f"{name} channel: a significant residual is left unexplained (the catch-all removes "
                     f"{100 * u['residual_removed_by_catch_all']:.0f} % of it); it correlates with "
                     + ", ".join(f"{c['with']} ({100 * c['share']:.0f} %)" for c in u["correlates_with"]))

    main = [r for r in results if fits[r.name].specs] or [r for r in results if r.name in unexplained] or results[:1]
    base_v = [validation_nrmse(r, vmodels[r.name], []) for r in main]
    ext_v = [nrmse(vmodels[r.name], [(c, v) for c, v, _ in fits[r.name].specs], fits[r.name].coef) for r in main]
    nrmse_base = float(np.sqrt(np.mean(np.square(base_v))))
    nrmse_ext = float(np.sqrt(np.mean(np.square(ext_v)))) if entries else nrmse_base
    baseline = {r.name: baseline_dict(r.name, r.baseline.coef, r.baseline.covariance(r.n_eff), r.channel.m)
                for r in results}
    baseline_extended = {name: baseline_dict(name, cf.coef, cf.cov, cf.result.channel.m)
                         for name, cf in fits.items() if cf.specs} or None
    actuator_refit = None
    if cfg is not None:
        mc = fits["motor"].coef
        m = chans["motor"].m
        actuator_refit = {key: float(np.mean([mc[j + PER * i] for i in range(m)]))
                          for j, (key, _) in enumerate(BASELINE_NAMES["motor"])}
        for e in (e for e in calibration if e["type"] == "coulomb_transition"):
            fit_m = fits["motor"]
            sl = fit_m.slices[[c.cause for c, _, _ in fit_m.specs].index("coulomb_transition")]
            folded = [folded_coulomb(mc[2 + PER * i], mc[sl][i], inputs.v_eps) for i in range(m)]
            actuator_refit["coulomb"] = float(np.mean([f[0] for f in folded]))
            actuator_refit["friction_smoothing_velocity"] = float(np.mean([f[1] for f in folded]))
        for e in (e for e in calibration if e["type"] == "torque_constant"):
            scale = float(np.mean([v["value"] for v in e["parameters"].values()]))
            actuator_refit["torque_constant"] = inputs.kt * scale
            # the baseline was fitted in configured-torque units: scale tau = J a + ..., so J, D, kc scale too
            for key in ("inertia", "damping", "coulomb"):
                actuator_refit[key] *= scale
        if unusable:
            actuator_refit = None          # fitted on what the screening found unusable: nothing to re-fit
        elif (problem := _refit_problem(cfg, actuator_refit)) is not None:
            notes.append(f"the re-fitted actuator baseline is not used (neither simulated nor written by "
                         f"--write-model; the config's values stay): {problem}")
            actuator_refit = None
    channel = effects[0]["channel"] if effects else (next(iter(unexplained)) if unexplained else None)
    detail = {"results": results, "fits": fits, "validation_channels": vchans, "validation_models": vmodels}
    return Diagnosis(calibration=calibration, causes=causes, confidence=float(confidence), channel=channel,
                     candidates=candidate_table(results, fits), effects=effects, baseline=baseline,
                     nrmse_baseline=nrmse_base, nrmse_extended=nrmse_ext, validation=vname, notes=notes,
                     data_warnings=warnings, unexplained=unexplained or None, adequacy=_adequacy(results),
                     actuator_refit=actuator_refit, baseline_extended=baseline_extended, detail=detail)
