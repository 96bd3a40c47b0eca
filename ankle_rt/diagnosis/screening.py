"""Screen measured data before the diagnosis fits anything: sensor artefacts must be said, masked where
that is sound, and never read as physics.

Found here (each a plain sentence in ``data_warnings``):
- time gaps and dropouts (a sample period far above the median): the samples around them are masked;
- held or repeated samples of the strain gauges or the amplifier input (a run of identical values that a
  noisy or continuously varying signal does not produce): masked;
- clipping / rail values: a column flat at its own extreme (strain gauges at the end of their range, the
  set current at the amplifier's limit, where the applied current no longer follows it): masked;
- motion in one direction only (friction asymmetry and a load offset then look like the Coulomb term:
  those two candidates are not tried), too little motion, a record too short to diagnose.
Slow strain-gauge drift is found by the cable channel (see :func:`strain_gauge_drift`), where the joint
angles make the gauges' expected torque known.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ankle_rt.diagnosis.signals import lattice_step
from ankle_rt.interchange import Recording

GAP_FACTOR = 1.5              # a sample period above this x the median is a gap
HOLD_SAMPLES = 8              # identical consecutive values of a noisy signal: a held sensor
RAIL_SHARE = 0.005            # share of samples flat at the column's extreme that counts as a rail
RAIL_RUN = 3                  # ... in runs at least this long
ONE_WAY_SHARE = 0.03          # the rarer direction of travel below this share of the moving samples
MOVING_SHARE = 0.2            # moving less than this share of the record: too little motion
MIN_RECORD_S = 2.0            # shorter: nothing is named
SHORT_RECORD_S = 5.0          # shorter: a warning (weak effects may be missed)
MASK_S = 0.01                 # s masked either side of a gap
MIN_USABLE = 0.15             # share of the record that must stay usable after masking
CLIP_WINDOW = 25              # samples: over this a noisy rail's moving mean ...
CLIP_FLAT = 0.5               # ... stays within this (noise sd) of its extreme ...
CLIP_SHARE = 0.015            # ... for at least this share of the record
CLIP_SNR = 10.0               # ... at a level this many noise sd from the median


@dataclass
class Screening:
    good: np.ndarray                               # per sample: usable for the regressions
    warnings: list[str] = field(default_factory=list)
    skip: set[str] = field(default_factory=set)    # candidates that cannot be told apart on these data
    unusable: bool = False        # too short, or too much of it masked: nothing is named
    one_way: bool = False         # a motor moves in one direction only


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of the runs of True in ``flags``."""
    d = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _flat_at_extreme(x: np.ndarray) -> np.ndarray:
    """Samples equal to the column's maximum or minimum, where that extreme is held in runs (a rail).
    Once the rail is known every sample at it is masked, also a single one where the signal only touched
    it: its true value may lie beyond (left in, such touches made a saturating spring fit the cable)."""
    out = np.zeros(len(x), dtype=bool)
    for v in (np.max(x), np.min(x)):
        at = x == v
        runs = [(a, b) for a, b in _runs(at) if b - a >= RAIL_RUN]
        if sum(b - a for a, b in runs) >= max(RAIL_RUN, RAIL_SHARE * len(x)):
            out |= at
    return out


def _noise_sd(x: np.ndarray) -> float:
    """Robust sd of the white noise on a smooth signal, from its second difference (variance 6 sd^2)."""
    return float(1.4826 * np.median(np.abs(np.diff(x, 2))) / math.sqrt(6.0)) if len(x) > 2 else 0.0


def _clipped_noisy(x: np.ndarray, still: np.ndarray | None = None) -> np.ndarray:
    """Samples of a rail that noise added after the clip keeps from being exactly flat: the moving mean
    over CLIP_WINDOW samples stays within CLIP_FLAT noise sd of its extreme for at least CLIP_SHARE of
    the record (noise alone moves it by 1/sqrt(CLIP_WINDOW) sd), at a level CLIP_SNR noise sd or more
    from the median. A smooth peak passes that level in a few samples; a physical torque plateau (a
    motor at its current clamp) keeps following the load (<= 0.8 % of the record in the simulated
    cases, 1.5-18 % per side for a gauge clipped at 70 % of its peak); a signal a few noise sd strong
    (the README's chirp on the IE gauge) lingers near its crests by noise alone. Only samples where a
    motor moves (``still``: none does) count towards CLIP_SHARE: motors that stick hold the cables'
    stretch, and the gauges then read a flat static load wherever it lies (generator D: 3-7 % of a record
    at rest near a crest read as a clipped gauge)."""
    out = np.zeros(len(x), dtype=bool)
    sd = _noise_sd(x)
    if sd <= 0.0 or len(x) < 4 * CLIP_WINDOW:
        return out
    box = np.ones(CLIP_WINDOW)
    mean = np.convolve(x, box / CLIP_WINDOW, mode="same")
    mean[:CLIP_WINDOW] = mean[-CLIP_WINDOW:] = np.median(x)          # edges: windows cut short
    for top in (mean, -mean):
        at = top >= np.max(top) - CLIP_FLAT * sd
        counted = at if still is None else at & ~still
        if np.mean(counted) >= CLIP_SHARE and np.max(top) - np.median(top) >= CLIP_SNR * sd:
            out |= np.convolve(at.astype(float), box, mode="same") > 0.5
    return out


def _held(x: np.ndarray, rail: np.ndarray, at_rest: np.ndarray | None = None,
          angle: np.ndarray | None = None) -> np.ndarray:
    """Runs of >= HOLD_SAMPLES identical values, in a column that otherwise changes almost every sample
    (a noisy sensor or a continuously varying set value). Not held: the column's extremes (a limit,
    however brief), exact zeros (an amplifier switched off, e.g. while the gauges are tared), and a set
    current's runs that its motor explains: throughout which ``at_rest`` holds (computed from an encoder
    that did not move, it is constant by nature), or along which the motor's ``angle`` is a straight line
    of time within one count (a steady speed takes a steady drive; generator E's 12-bit set values, 7 mA
    a step, stayed on one step that long while a PD controller tracked a ramp: 0.03-5 % of every record
    was masked, the slow samples a Stribeck term needs)."""
    same = np.concatenate([[False], np.diff(x) == 0.0]) & (x != np.max(x)) & (x != np.min(x)) & (x != 0.0)
    if np.mean(same & ~rail) > 0.5:        # a signal that is piecewise constant by nature
        return np.zeros(len(x), dtype=bool)
    count = lattice_step(angle) if angle is not None else 0.0
    out = np.zeros(len(x), dtype=bool)
    for a, b in _runs(same & ~rail):
        if b - a + 1 < HOLD_SAMPLES or (at_rest is not None and bool(np.all(at_rest[a:b]))):
            continue
        if angle is not None and _straight(angle[max(0, a - 1):b], count):
            continue
        out[max(0, a - 1):b] = True
    return out


def _straight(y: np.ndarray, count: float) -> bool:
    """Whether the samples ``y`` (of a uniform grid) lie on a straight line of their index within one
    ``count``, or within a float's rounding of their span where the readings lie on no lattice."""
    y = y - y[0]
    k = np.arange(len(y), dtype=float)
    line = np.polyval(np.polyfit(k, y, 1), k)
    return bool(np.max(np.abs(y - line)) <= max(count, 1e-9 * float(np.ptp(y))))


def _dead_encoder(rec: Recording, i: int, moving: np.ndarray) -> str | None:
    """What motor ``i``'s set value does while its encoder never changes and another motor moves (None
    when the encoder changes, no other motor moves, or its set value spans less than DEAD_SPAN_SHARE of a
    moving motor's: a parked motor holding against a varying load): such a motor's inertia, damping and
    friction fit to zero and every other effect's share is judged against a silent column."""
    pos = np.asarray(rec[f"motor_pos_{i + 1}"], dtype=float)
    if np.ptp(pos) > 0.0:
        return None
    for prefix, unit in (("current_cmd", "A"), ("motor_torque", "N m")):
        col = f"{prefix}_{i + 1}"
        if col not in rec:
            continue
        span = float(np.ptp(np.asarray(rec[col], dtype=float)))
        driven = [float(np.ptp(np.asarray(rec[f"{prefix}_{j + 1}"], dtype=float))) for j in range(moving.shape[1])
                  if j != i and moving[:, j].any() and f"{prefix}_{j + 1}" in rec]
        if driven and span >= DEAD_SPAN_SHARE * max(driven):
            return f"{col} spans {span:.3g} {unit}"
    return None


#: a still motor's set value must span this share of a moving motor's before its encoder counts as dead
DEAD_SPAN_SHARE = 0.25


def _pct(share: float) -> str:
    """A share in per cent; one below 0.1 % with two significant digits (a few samples of a 2 kHz log are
    not "0.0 %")."""
    if share >= 0.001:
        return f"{100 * share:.1f} %"
    return np.format_float_positional(100 * share, precision=2, fractional=False, trim="-") + " %"


def screen(rec: Recording, v_eps: float, current_limit: float | None = None, label: str = "data") -> Screening:
    """Screen ``rec`` (see the module docstring); ``v_eps`` sets the speed that counts as moving,
    ``current_limit`` (A, from the config) the amplifier limit; ``label`` starts every warning."""
    n = len(rec)
    t = np.asarray(rec["t"], dtype=float)
    dt = rec.dt
    good = np.ones(n, dtype=bool)
    out = Screening(good)
    duration = float(t[-1] - t[0]) + dt
    if duration < MIN_RECORD_S:
        out.unusable = True
        out.warnings.append(f"{label}: the record is {duration:.2f} s long, too short to diagnose "
                            f"(at least {MIN_RECORD_S:g} s): nothing is named")
    elif duration < SHORT_RECORD_S:
        out.warnings.append(f"{label}: the record is short ({duration:.1f} s): weak effects may be "
                            "missed")
    gaps = np.flatnonzero(np.diff(t) > GAP_FACTOR * dt)
    if gaps.size:
        reach = max(1, int(round(MASK_S / dt)))
        for g in gaps:
            good[max(0, g - reach):g + reach + 2] = False
        longest = float(np.max(np.diff(t)[gaps]))
        out.warnings.append(f"{label}: {gaps.size} time gap(s) (dropped samples), the longest "
                            f"{1e3 * longest:.0f} ms: the samples around them are masked")
    motors = [c for c in ("motor_pos_1", "motor_pos_2") if c in rec]
    at_rest = {}
    angles = {}
    still = None
    if motors:
        from ankle_rt.diagnosis.signals import Smoother
        vel = Smoother.for_period(dt).fast_derivative(np.column_stack([rec[c] for c in motors]))
        v99 = float(np.percentile(np.abs(vel), 99))
        moving = np.abs(vel) > max(5.0 * v_eps, 0.01 * v99)
        for i, c in enumerate(motors):
            pos = np.asarray(rec[c], dtype=float)
            at_rest[f"current_cmd_{i + 1}"] = np.concatenate([[True], np.diff(pos) == 0.0]) | ~moving[:, i]
            angles[f"current_cmd_{i + 1}"] = pos
        still = np.logical_and.reduce([at_rest[f"current_cmd_{i + 1}"] for i in range(len(motors))])
    inputs = [c for c in ("current_cmd_1", "current_cmd_2", "motor_torque_1", "motor_torque_2") if c in rec]
    gauges = [c for c in ("sg_torque_dp", "sg_torque_ie") if c in rec]
    for col in inputs + gauges:
        x = np.asarray(rec[col], dtype=float)
        is_current = col.startswith("current")
        if is_current and current_limit is not None:
            # the configured amplifier peak says where the current stops following: a flat extreme below
            # it is the controller's own clamp, which the amplifier delivers
            rail = np.abs(x) >= 0.999 * current_limit
        else:
            rail = _flat_at_extreme(x) | (_clipped_noisy(x, still) if col in gauges else False)
        held = _held(x, rail, at_rest.get(col), angles.get(col))
        what = "set current" if is_current else ("motor torque" if col in inputs else "strain gauge")
        if rail.any():
            level = float(np.max(np.abs(x[rail])))
            reason = ("at the amplifier's limit: the applied current need not follow the set value" if col in inputs
                      else "reads exactly zero: disconnected or dead?" if level == 0.0
                      else "clipped at the end of its range")
            out.warnings.append(f"{label}: {what} {col} flat at +/-{level:.4g} in {_pct(float(np.mean(rail)))} "
                                f"of the samples ({reason}); those samples are masked")
        if held.any():
            out.warnings.append(f"{label}: {what} {col} holds the same value for {HOLD_SAMPLES}+ samples in "
                                f"{_pct(float(np.mean(held)))} of the record (held or repeated samples); masked")
        good &= ~(rail | held)
    if motors:
        share = float(np.mean(moving))
        if share < MOVING_SHARE:
            out.warnings.append(f"{label}: the motors move in only {_pct(share)} of the record: too little "
                                "motion to separate friction, load and inertia well")
        for i, c in enumerate(motors):
            m = moving[:, i]
            if (dead := _dead_encoder(rec, i, moving)) is not None:
                out.warnings.append(f"{label}: {c} never changes while {dead} and the other motor moves: a "
                                    "dead or disconnected encoder (or a seized motor); nothing is named")
                out.unusable = True
            if m.sum() < 10:
                continue
            fwd = float(np.mean(vel[m, i] > 0.0))
            if min(fwd, 1.0 - fwd) < ONE_WAY_SHARE:
                out.warnings.append(f"{label}: {c} moves in one direction only ({_pct(max(fwd, 1 - fwd))} of "
                                    "its motion): direction-dependent friction and a load offset cannot be told "
                                    "from the Coulomb term, so neither is tried; shapes of the commanded "
                                    "torque are left out of the adequacy test")
                out.skip |= {"asymmetric_friction", "torque_offset"}
                out.one_way = True
    usable = float(np.mean(_reach_of_masks(good, dt)))
    if usable < MIN_USABLE:
        out.warnings.append(f"{label}: only {_pct(usable)} of the record is free of the artefacts above: too "
                            "little to diagnose, nothing is named")
        out.unusable = True
        out.good[:] = True
    elif np.mean(good) < 0.5:
        out.warnings.append(f"{label}: {_pct(1.0 - float(np.mean(good)))} of the samples are masked: the "
                            "diagnosis rests on the rest")
    return out


def _reach_of_masks(good: np.ndarray, dt: float) -> np.ndarray:
    """Samples not within the filter's reach of a masked sample (what the regressions can use)."""
    reach = int(round(0.06 / dt)) + 2
    bad = np.convolve((~good).astype(float), np.ones(2 * reach + 1), mode="same") > 0.5
    return ~bad


#: strain-gauge drift: the time shapes must remove this share of the cable baseline's residual ...
DRIFT_REDUCTION = 0.2
#: ... and span this many times the RMS of what is left (the noise floor)
DRIFT_SIZE = 5.0


def strain_gauge_drift(cable) -> list[float] | None:
    """Peak-to-peak drift (N m, per ankle axis) of the strain gauges' offset over the record, when the
    cable channel's residual follows slow shapes of time strongly; else None. The cable law has no slow
    time dependence (the catch-all's stretch shapes stand in for any cable effect while testing), so a
    residual that follows time is the gauges', not the cables'."""
    from ankle_rt.diagnosis.candidates import EncoderScale, catch_all_cable, time_columns
    from ankle_rt.diagnosis.regression import fit
    from ankle_rt.diagnosis.selection import ChannelModels

    C, groups = catch_all_cable(ChannelModels(cable))
    shapes = C[:, [j for j, g in enumerate(groups) if g != "time (drift)"]]
    # the joint-angle columns of an encoder scale mismatch too: slow motion would read as a drift
    y, Xb = cable.target(), np.hstack([cable.baseline_design(), shapes, EncoderScale().design(cable, 0.0).X])
    T = time_columns(cable)
    base = fit(y, Xb, covariance=False)
    full = fit(y, np.hstack([Xb, T]), covariance=False)
    if base.rss <= 0.0 or 1.0 - full.rss / base.rss < DRIFT_REDUCTION:     # 0: nothing left to explain
        return None
    drift = (T @ full.coef[Xb.shape[1]:]).reshape(cable.m, -1)
    span = np.ptp(drift, axis=1)
    if float(np.max(span)) < DRIFT_SIZE * math.sqrt(full.rss / len(y)):
        return None
    return [float(s) for s in span]


#: a strain-gauge zero offset is reported (and corrected) when it exceeds this (N m) ...
GAUGE_OFFSET_NM = 0.05
#: ... and this many of its standard deviations
GAUGE_OFFSET_SD = 5.0


def strain_gauge_offset(cable) -> np.ndarray | None:
    """Zero offsets (N m per ankle axis [DP, IE]) of the strain gauges when significant, else None. A
    joint torque reaches the gauges only through the cable stretch the ankle encoders measure, so a
    constant the gauges read beyond the cable law (with the odd dead-zone and hardening shapes a cable
    effect would add) is the gauges' own offset, not a load: a load stretches the cables."""
    from ankle_rt.diagnosis.candidates import CABLE_CANDIDATES
    from ankle_rt.diagnosis.regression import effective_samples, fit

    shapes = [c.design(cable, nl).X for c in CABLE_CANDIDATES for nl in OFFSET_SHAPES.get(c.nonlinear, ())]
    X = np.hstack([cable.baseline_design()] + shapes)
    f = fit(cable.target(), X)
    cov = f.covariance(effective_samples(f.residual, cable.m))
    idx = [2, 5]                       # the offset column of each axis in the cable baseline
    off = f.coef[idx]
    sd = np.sqrt(np.maximum(np.diag(cov)[idx], 0.0))
    if not np.any((np.abs(off) > GAUGE_OFFSET_NM) & (np.abs(off) > GAUGE_OFFSET_SD * sd)):
        return None
    return off


#: the cable candidates' shapes that stand in for any cable effect (and an encoder scale mismatch) while
#: an offset is measured, by the name of the form's nonlinear parameter: a shared slack half-width (m), a
#: stiffening exponent, none (the scale columns); a form whose value is no such number (a pair of widths'
#: code, a taut-stretch slack) takes no part
OFFSET_SHAPES = {"half_width": (1e-4, 4e-4, 1.5e-3), "exponent": (2.0, 3.0), None: (0.0,)}
