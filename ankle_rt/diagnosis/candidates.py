"""The named candidate effects as blocks of regressors, and the catch-all block.

A candidate adds columns to the baseline regression of its channel (coefficients shared by the
motors or ankle axes, as the simulator's effect is) and may have one nonlinear parameter searched on a
grid (Stribeck velocity, delay, slack width, cogging period). ``parameters`` turns the fitted
coefficients into the simulator effect's parameters (docs/design.md vocabulary = the effect's ``cause``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from ankle_rt.diagnosis.signals import RELAXATION_S, CableChannel, MotorChannel, lagged

if TYPE_CHECKING:
    from ankle_rt.diagnosis.selection import ChannelModels

Channel = MotorChannel | CableChannel
#: a catch-all: the generic columns of a channel's models and the group each column correlates with
CatchAll = Callable[["ChannelModels"], tuple[np.ndarray, list[str]]]


@dataclass
class Design:
    """One candidate at one value of its nonlinear parameter: extra columns, and the left side when the
    candidate changes it (a delay shifts the torque)."""

    X: np.ndarray
    y: np.ndarray | None = None

    @property
    def nbytes(self) -> int:
        return self.X.nbytes + (0 if self.y is None else self.y.nbytes)


class Candidate:
    cause: str = ""
    channel: str = "motor"
    nonlinear: str | None = None     # name of the grid-searched parameter
    integer: bool = False            # the nonlinear parameter is an integer (refined on the grid only)
    nonlinear_count: int = 1         # physical values the nonlinear parameter stands for (a criterion's k)
    calibration: bool = False        # a sensor / calibration finding: reported, never a cause or a sim effect
    #: fixed settings of the simulator effect this form stands for (several forms may share a cause; a
    #: channel names at most one form per cause)
    form: dict[str, str] = {}
    #: a richer form of the same effect tried once this one is chosen (e.g. cogging with a harmonic)
    upgrade: "Candidate | None" = None
    #: the effect must show while the motors move, not only beside their rests (selection._shown_in_motion)
    in_motion: bool = False
    #: ... and also where they neither rest nor reverse, mid-stroke (selection._not_in_motion)
    mid_stroke: bool = False

    def applies(self, ch: Channel) -> bool:
        """Only where there is a value of the nonlinear parameter to search (coarse joint encoders leave a
        dead zone's grid empty)."""
        return bool(self.grid(ch))

    def grid(self, ch: Channel) -> list[float]:
        return [0.0]

    def search_grid(self, ch: Channel, residual: np.ndarray, design: Callable[[float], Design]) -> list[float]:
        """Values of the nonlinear parameter to score, given the current model's residual (stacked);
        ``design(value)`` gives the candidate's (cached) design at a value."""
        return self.grid(ch)

    def linked(self, other: "Candidate") -> bool:
        """Whether ``other``'s nonlinear value, when it is in the model, is one of this candidate's too (the
        same physical quantity: a slack): it is then scored beside the grid, so a search one parameter at
        a time can reach the point where both agree."""
        return False

    def design(self, ch: Channel, nl: float) -> Design:
        raise NotImplementedError

    def nonlinear_values(self, nl: float) -> dict[str, float]:
        """The nonlinear parameter at ``nl`` as the report names it (nothing for a linear form)."""
        return {self.nonlinear: nl} if self.nonlinear else {}

    def parameters(self, coef: np.ndarray, cov: np.ndarray, nl: float, nl_sd: float,
                   ch: Channel, base_coef: np.ndarray) -> dict[str, tuple[float, float]]:
        """Effect parameters as {name: (value, standard deviation)} from the candidate's coefficients
        ``coef`` (covariance ``cov``) and the baseline's coefficients of the same extended fit."""
        raise NotImplementedError

    def rejection(self, params: dict[str, tuple[float, float]], coef: np.ndarray,
                  base_coef: np.ndarray) -> str | None:
        """Why fitted ``params`` (from the candidate's ``coef`` beside the baseline's ``base_coef``)
        cannot be a simulator effect (None: they can): a non-finite value, or one outside the effect's
        physical range. A rejected candidate is dropped, never written."""
        bad = [k for k, (v, _) in params.items() if not math.isfinite(v)]
        return f"non-finite {', '.join(bad)}" if bad else None

    def refusal(self, coef: np.ndarray, cov: np.ndarray, nl: float, nl_sd: float, ch: Channel,
                base_coef: np.ndarray) -> str | None:
        """:meth:`rejection` of the parameters these fitted ``coef`` (their ``cov``) give at ``nl``."""
        return self.rejection(self.parameters(coef, cov, nl, nl_sd, ch, base_coef), coef, base_coef)

    def holding(self, ch: Channel, coef: np.ndarray) -> float | np.ndarray:
        """The friction this block adds near zero speed with its coefficients ``coef`` (N m, one number or
        per sample and motor): what it holds a resting motor with beside the nominal Coulomb level
        (core._holding, signals.stuck). A torque constant through a rest (a load, cogging at that angle, a
        Coulomb asymmetry, which shifts the band both ways alike) and a sharper Coulomb transition (the
        same level) hold nothing: 0."""
        return 0.0

    def implausible(self, coef: np.ndarray, nl: float, ch: Channel, base_coef: np.ndarray) -> str | None:
        """Why the fitted shape contradicts the physics the effect stands for (None: it does not): the
        block then fits something outside the vocabulary, and the selection drops it so that the
        catch-all can see the remainder. ``coef`` are the block's coefficients beside the baseline's
        ``base_coef`` in the chosen model."""
        return None


def _sd(cov: np.ndarray, i: int) -> float:
    return float(np.sqrt(max(cov[i, i], 0.0)))


class Stribeck(Candidate):
    """Friction above the Coulomb level at low speed, ``a exp(-|w / vs|^e) tanh(w / v_eps)``: the shape
    exponent e is a form (2 Gaussian here; measured curves take 0.5-2), vs on a grid."""

    cause = "stribeck"
    nonlinear = "stribeck_velocity"
    exponent = 2.0

    def grid(self, ch):
        v99 = float(np.percentile(np.abs(ch.vel), 99))
        return list(np.geomspace(2.0 * ch.v_eps, max(0.3 * v99, 4.0 * ch.v_eps), 18))

    def design(self, ch, nl):
        # ch.step_mean(lambda v, sign: np.exp(-np.abs(v / nl) ** self.exponent) * sign), cached
        return Design(ch.filt(ch.stribeck_mean(nl, self.exponent))[:, None])

    def holding(self, ch, coef):
        """The static excess: at speeds above v_eps and far below vs the term is its whole excess."""
        return float(coef[0])

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return {"static_excess": (float(coef[0]), _sd(cov, 0)), "stribeck_velocity": (nl, nl_sd),
                "exponent": (self.exponent, 0.0)}

    def implausible(self, coef, nl, ch, base_coef):
        """A Stribeck excess makes the friction fall with speed from the breakaway toward the Coulomb
        level. Where its steepest descent does not outweigh the fitted viscous slope D_i of any motor, the
        fitted friction rises with speed everywhere: the block fits the curvature of a drag growing with
        speed (v |v|, outside the vocabulary), not a breakaway. (The Coulomb level is not checked: beside a
        sharper transition block the baseline's tanh column holds only part of it.)"""
        e = self.exponent
        x = (e - 1.0) / e                   # (v / vs)^e where d/dv exp(-|v / vs|^e) is steepest
        steepest = float(coef[0]) * e * x ** ((e - 1.0) / e) * math.exp(-x) / nl
        viscous = base_coef[1:3 * ch.m:3]
        if np.any(steepest > viscous):
            return None
        return (f"the fitted friction rises with speed everywhere (the excess {float(coef[0]):.3g} N m over "
                f"vs = {nl:.3g} falls by at most {steepest:.3g} N m s/rad, the viscous slopes are "
                f"{', '.join(f'{d:.3g}' for d in viscous)} N m s/rad): not a breakaway")


class StribeckExponential(Stribeck):
    """The Stribeck form with an exponential decay (e = 1): a sharper breakaway and a longer tail than
    the Gaussian, which leaves a remainder at every reversal when it is fitted the Gaussian way."""

    exponent = 1.0


class AsymmetricFriction(Candidate):
    """Direction-dependent friction ``dc |tanh(w / v_eps)| + dv |w|``, coefficients shared by the motors."""

    cause = "asymmetric_friction"
    per_motor = False

    def applies(self, ch):
        return not self.per_motor or ch.m > 1

    def design(self, ch, nl):
        shapes = [ch.step_mean(lambda v, sign: np.abs(sign)), np.abs(ch.vel)]
        if self.per_motor:
            return Design(np.hstack([ch.per_column(ch.sm.smooth(x)) for x in shapes]))
        return Design(np.column_stack([ch.filt(x) for x in shapes]))

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        k = ch.m if self.per_motor else 1
        out = {}
        for i in range(k):
            suffix = "" if i == 0 else f"_{i + 1}"
            out["coulomb_asymmetry" + suffix] = (float(coef[i]), _sd(cov, i))
            out["viscous_asymmetry" + suffix] = (float(coef[k + i]), _sd(cov, k + i))
        return out


class AsymmetricFrictionPerMotor(AsymmetricFriction):
    """Direction-dependent friction of its own size per motor (two motors never share their friction):
    with a shared coefficient the motors' difference reads as a load offset on each (``torque_offset``)."""

    per_motor = True


class LoadDependentFriction(Candidate):
    cause = "load_dependent_friction"

    def applies(self, ch):
        return bool(np.any(ch.tc))

    def design(self, ch, nl):
        return Design(ch.filt(np.abs(ch.tc) * ch.sign)[:, None])

    def holding(self, ch, coef):
        """mu |tc| with the cable torque the motor feels through the rest (filtered, every sample)."""
        return float(coef[0]) * np.abs(ch.sm.smooth(ch.tc, weigh=False))

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return {"coefficient": (float(coef[0]), _sd(cov, 0))}


class Cogging(Candidate):
    """Torque ripple periodic in the motor angle, with its own phase and amplitude per motor (two motors
    never share a rotor position) and a second harmonic: ``a_i sin(n theta_i) + b_i cos(n theta_i) +
    c_i sin(2 n theta_i) + d_i cos(2 n theta_i)`` per motor i, n periods per revolution (2 pi of the
    position unit) shared by the motors.

    The count is found without a prior by the residual's spectrum in the angle domain: the residual is
    taken back through the filter (its adjoint: the zero-phase filter again) to the raw samples, binned
    onto a uniform grid of each motor's angle modulo 2 pi and Fourier-transformed, which gives its
    projection on every integer count at once (per speed band, each band weighted by the taper the
    regressor gives a ripple at that speed); each count's projection is normalised by the variance it
    would have were the residual noise, and the motors' powers are added (their phases differ). The
    strongest peaks are screened by the share of the residual their own filtered columns explain, and the
    best of them, with their neighbours, scored by the regression. Rotor cogging through the gearbox
    (e.g. 6, 14 or 24 periods per motor turn x 81 = 486, 1134, 1944) is found where the motion is slow
    enough for the ripple to stay in the pass band."""

    cause = "cogging"
    nonlinear = "periods_per_rev"
    integer = True

    def applies(self, ch) -> bool:
        """Only where the travel holds MIN_COGGING_PERIODS periods of a count it may search (a motor that
        does not move leaves no count at all)."""
        n_min, n_max = self.count_range(ch)
        return n_min <= n_max

    def count_range(self, ch) -> tuple[int, int]:
        """(fewest, most) periods per revolution searched: at least MIN_COGGING_PERIODS in the travel
        (fewer cannot be told from a spring or preload); at most where the ripple leaves the pass band at
        the slowest tenth of the motion, and never fewer than MIN_COGGING_SEARCH; never more than the
        encoder resolves (COUNTS_PER_PERIOD counts a period, when the config gives its counts: where the
        motors stick, the slowest tenth is at rest and the pass-band bound alone reached 500 000, a period
        below one count that fitted the residual of the rests)."""
        span = max(float(np.ptp(ch.pos)), 1e-12)
        n_min = max(1, math.ceil(2.0 * np.pi * MIN_COGGING_PERIODS / span))
        v_slow = float(np.percentile(np.abs(ch.vel[ch.rows]), 10))
        n_fast = 2.0 * np.pi * ch.sm.cutoff_hz / max(v_slow, 1e-12)
        n_max = int(min(max(n_fast, MIN_COGGING_SEARCH, n_min + 300), MAX_COGGING_BINS // 8))
        if ch.counts_per_rev:
            n_max = min(n_max, max(n_min, ch.counts_per_rev // COUNTS_PER_PERIOD))
        return n_min, n_max

    def grid(self, ch):
        n_min, n_max = self.count_range(ch)
        return [float(n) for n in np.unique(np.geomspace(n_min, n_max, 40).round())]

    def search_grid(self, ch, residual, design):
        """Integer counts worth a regression: the angle-domain spectrum's strongest peaks (see the class
        docstring) with their neighbours, and the config's prior when it gives one."""
        n_min, n_max = self.count_range(ch)
        power = self.angle_power(ch, residual, n_max, ~ch.resting)
        power[:n_min] = 0.0
        peaks = np.flatnonzero((power[1:-1] > power[:-2]) & (power[1:-1] >= power[2:])) + 1
        screened = peaks[np.argsort(power[peaks])[::-1][:COGGING_SCREENED]]
        # the exact share of the residual each screened count's filtered sin/cos pair explains
        explained = []
        for n in screened:
            X = design(float(n)).X
            g = X.T @ residual
            explained.append(float(g @ np.linalg.lstsq(X.T @ X, g, rcond=None)[0]))
        best = screened[np.argsort(explained)[::-1][:COGGING_PEAKS]]
        picks = {int(n) for p in best for n in range(p - 1, p + 2) if n_min <= n <= n_max}
        if ch.cogging_prior:
            picks.add(int(round(ch.cogging_prior)))
        return [float(n) for n in sorted(picks)]

    def implausible(self, coef, nl, ch, base_coef):
        """A ripple at a count no rotating part has (:meth:`rotor_count`) fits something else that
        repeats along the travel: a stride-locked remainder in walking, a rest's holding torque. It is
        left to the catch-all, never replaced by a neighbouring count the search did not prefer (searched
        on the rotor's counts only, the search found such neighbours that fitted a remainder: generator D
        seeds 124, 127, 719, 729 named cogging at 1538 and 6477 periods where there was none)."""
        n = int(round(nl))
        if self.rotor_count(ch, n) or (ch.cogging_prior and n == round(ch.cogging_prior)):
            return None
        return (f"{n} periods per output turn is no whole number per motor turn ({n / ch.gear_ratio:.2f} x the "
                f"gear ratio {ch.gear_ratio:g}): not a rotor's cogging")

    @staticmethod
    def rotor_count(ch, n: int) -> bool:
        """Whether a ripple fixed to a rotating part can have ``n`` periods per output turn. Behind a gearbox
        of ratio G (``ch.gear_ratio``) a ripple of more than G periods per output turn turns faster than the
        output and is the rotor's: a whole number N of periods per motor turn, N G per output turn as the
        motor encoders read it (N G / f where they read f x the angle: ``ch.motor_scales``), within
        ROTOR_COUNT_TOLERANCE or one period (a gearbox's true ratio may differ a little from the configured
        one). Fewer than G periods may be the output's own (a pulley, the sheath). Without a known ratio:
        every count. On generator D's records the free search named cogging at 2170 and 2402 periods (26.8
        and 29.7 per motor turn) where there was none, at 0.05-3 % of the residual."""
        gear = ch.gear_ratio
        if not gear or n < gear:
            return True
        return any(abs(n - lattice * round(n / lattice)) <= max(1.0, ROTOR_COUNT_TOLERANCE * n)
                   for lattice in (gear / f for f in ch.motor_scales))

    @classmethod
    def angle_power(cls, ch, residual: np.ndarray, n_max: int, weight: np.ndarray) -> np.ndarray:
        """Per integer count 0..n_max: the power of the stacked ``residual``'s projection on the tapered
        ``weight x sin / cos(n theta)`` of each motor (``weight``: samples x motors), normalised by its
        variance were the residual noise, the motors' powers added (see the class docstring)."""
        full = np.zeros((ch.n_samples, ch.m))
        full[ch.rows] = residual.reshape(ch.m, -1).T
        back = ch.sm.smooth(full)                                # adjoint of "filter, keep rows"
        power = np.zeros(n_max + 1)
        for i, bands in enumerate(cls._angle_bands(ch, n_max)):
            spectrum = np.zeros(n_max + 1, dtype=complex)
            variance = np.zeros(n_max + 1)
            for sel, w, n_b, bins, idx in bands:
                r = back[sel, i] * weight[sel, i]
                spectrum[: n_b + 1] += w[: n_b + 1] * np.fft.rfft(np.bincount(idx, weights=r, minlength=bins))[: n_b + 1]
                variance += 0.5 * w ** 2 * float(r @ r)
            power += np.abs(spectrum) ** 2 / np.maximum(variance, 1e-300)
        return power

    @classmethod
    def _angle_bands(cls, ch, n_max: int) -> list[list[tuple]]:
        """Per motor, the speed bands :meth:`angle_power` transforms, each (its samples, the taper per count
        0..n_max at its speed, the highest count it keeps, its grid size, each sample's grid bin): they
        depend on the motion alone, not on the residual, and are kept on the channel per n_max."""
        cache = ch.__dict__.setdefault("_angle_bands", {})
        if n_max in cache:
            return cache[n_max]
        turn = np.mod(ch.pos, 2.0 * np.pi) / (2.0 * np.pi)      # fraction of a revolution, 0..1
        speed = np.abs(ch.vel)
        # speed bands, within which the taper of a count's ripple is nearly one number
        edges = np.unique(np.quantile(speed, np.linspace(0.0, 1.0, SPEED_BANDS + 1)))
        band = np.clip(np.searchsorted(edges, speed, side="right") - 1, 0, len(edges) - 2)
        counts = np.arange(n_max + 1, dtype=float)
        out = []
        for i in range(ch.m):
            bands = []
            for b in range(len(edges) - 1):
                sel = band[:, i] == b
                if not sel.any():
                    continue
                v_b = float(np.sqrt(max(edges[b], 1e-12) * max(edges[b + 1], 1e-12)))
                w = cls.taper(ch, counts * v_b)
                # the taper is zero beyond n_b: this band's grid need only resolve counts up to n_b
                # (a fast band's transform is short; only the slowest bands need the full grid)
                if not w.any():
                    continue
                n_b = int(np.flatnonzero(w)[-1])
                bins = 1 << int(math.ceil(math.log2(8 * max(n_b, 1))))
                idx = np.minimum((turn[sel, i] * bins).astype(np.int64), bins - 1)
                bands.append((np.flatnonzero(sel), w, n_b, bins, idx))
            out.append(bands)
        cache[n_max] = out
        return out

    @staticmethod
    def taper(ch, angular_rate: np.ndarray) -> np.ndarray:
        """Weight of the ripple at ``angular_rate`` = n |v| (rad/s of ripple phase): 1 well inside what
        the sampled data resolve, 0 where it nears the Nyquist rate (a ripple there is aliased in the
        sampled angle and in the measured acceleration alike, and beyond the filter's pass band anyway)."""
        f1 = min(TAPER_START * ch.sm.cutoff_hz, 0.15 / ch.dt)
        f2 = min(TAPER_END * ch.sm.cutoff_hz, 0.3 / ch.dt)
        # 0.5 (1 + cos(pi x)), x = clip((|rate| / 2 pi - f1) / (f2 - f1), 0, 1), in one buffer; the cosine
        # only inside the transition: at x = 0 it is 1 and at x = 1 it is 0, exactly (cos 0 = 1, cos pi = -1)
        x = np.abs(angular_rate)
        x /= 2.0 * np.pi
        x -= f1
        x /= f2 - f1
        np.clip(x, 0.0, 1.0, out=x)
        out = (x == 0.0).astype(float)
        mid = ~((x == 0.0) | (x == 1.0))
        if mid.any():
            out[mid] = 0.5 * (1.0 + np.cos(np.pi * x[mid]))
        return out

    #: harmonics in the regressor: the count is searched and selected on the fundamental alone (a second
    #: harmonic's columns let wrong counts fit aliased residue); :data:`upgrade` then adds the second
    #: harmonic where it earns its place (selection._with_richer_forms)
    harmonics = 1

    def design(self, ch, nl):
        m, k = ch.m, ch.n_rows
        waves = np.empty((ch.n_samples, 2 * self.harmonics * m))   # w sin, w cos per harmonic, motor after motor
        moving = ~ch.resting
        for h in range(1, self.harmonics + 1):
            ang = h * nl * ch.pos
            w = self.taper(ch, h * nl * ch.vel) * moving          # a stuck motor's static friction holds it
            j = 2 * (h - 1) * m
            np.multiply(w, np.sin(ang), out=waves[:, j:j + m])
            np.multiply(w, np.cos(ang), out=waves[:, j + m:j + 2 * m])
        filtered = ch.sm.smooth(waves)                            # one filter pass for all
        # each wave's column per motor (ch.per_column of each wave, side by side)
        X = np.zeros((k * m, waves.shape[1]))
        for j in range(waves.shape[1]):
            i = j % m
            X[i * k:(i + 1) * k, j] = filtered[ch.rows, j]
        return Design(X)

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        m = ch.m
        out: dict[str, tuple[float, float]] = {"periods_per_rev": (nl, 0.0)}
        harmonic = []
        for i in range(m):
            amp, amp_sd, ph = _sine(coef, cov, i, i + m)
            suffix = "" if i == 0 else f"_{i + 1}"
            out["amplitude" + suffix] = (amp, amp_sd)
            out["phase" + suffix] = (ph, amp_sd / max(amp, 1e-300))
            if self.harmonics > 1:
                harmonic.append(_sine(coef, cov, i + 2 * m, i + 3 * m))
        if not harmonic:
            return out
        out["harmonic_amplitude"] = (float(np.mean([h[0] for h in harmonic])),
                                     float(np.sqrt(np.mean([h[1] ** 2 for h in harmonic]))))
        for i, (h, h_sd, q) in enumerate(harmonic):
            out["harmonic_phase" + ("" if i == 0 else f"_{i + 1}")] = (q, h_sd / max(h, 1e-300))
        return out


class CoggingHarmonic(Cogging):
    """Cogging with its second harmonic (2 n periods per revolution, its own phase per motor): the richer
    form a chosen cogging term is tried in, never searched for its count."""

    harmonics = 2


Cogging.upgrade = CoggingHarmonic()


def _sine(coef: np.ndarray, cov: np.ndarray, i_sin: int, i_cos: int) -> tuple[float, float, float]:
    """(amplitude, its sd, phase) of ``s sin(x) + c cos(x)`` = A sin(x + phase) from coefficients i_sin, i_cos."""
    s, c = float(coef[i_sin]), float(coef[i_cos])
    amp = float(np.hypot(s, c))
    g = np.array([s, c]) / max(amp, 1e-300)
    sub = cov[np.ix_([i_sin, i_cos], [i_sin, i_cos])]
    return amp, float(np.sqrt(max(g @ sub @ g, 0.0))), float(np.arctan2(c, s))


class TorqueOffset(Candidate):
    """A constant load torque on each motor (gravity, preload): one column per motor. Unlike
    asymmetric friction it keeps its sign through a reversal and may differ between the motors."""

    cause = "torque_offset"

    def design(self, ch, nl):
        return Design(ch.constants())

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return {f"torque_{i + 1}": (float(coef[i]), _sd(cov, i)) for i in range(len(coef))}


class TorqueConstantScale(Candidate):
    """A torque-constant (or current-sensing) calibration error per motor, not a physical effect: with the
    true constant ``scale`` x the configured one, ``scale tau = J a + D w + kc s + tc``, i.e. the left side
    ``tau - tc`` gains ``(1 / scale - 1) tc`` (J, D, kc absorb the rest). Seen only where the strain gauges
    measure the cable torque independently of the current."""

    cause = "torque_constant"
    calibration = True

    def applies(self, ch):
        return bool(np.any(ch.tc))

    def design(self, ch, nl):
        return Design(ch.per_column(ch.L_tc))

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return {f"scale_{i + 1}": (1.0 / (1.0 + float(coef[i])), _sd(cov, i) / (1.0 + float(coef[i])) ** 2)
                for i in range(len(coef))}

    def rejection(self, params, coef, base_coef):
        off = [f"{v:.3g}" for v, _ in params.values() if not SCALE_RANGE[0] < v < SCALE_RANGE[1]]
        if off:
            return f"torque-constant scale {', '.join(off)} outside {SCALE_RANGE[0]:g}-{SCALE_RANGE[1]:g}: no calibration error"
        return super().rejection(params, coef, base_coef)


class CoulombTransition(Candidate):
    """The Coulomb friction turning sharper than the config's assumed smoothing v_eps (a baseline parameter,
    not an effect): a second Coulomb column ``c_i tanh(SHARPER w / v_eps)`` per motor. A real transition is
    as sharp as the data say; one left at the simulator's v_eps is extra friction at low speed that read
    as a Stribeck term at its grid edge (generator C). Selected like an effect, so it and a Stribeck term
    compete for what the data show near rest; reported as the fitted ``friction_smoothing_velocity``
    (the two columns folded into one tanh, :func:`folded_coulomb`), never as a cause."""

    cause = "coulomb_transition"
    calibration = True

    def design(self, ch, nl):
        v_eps = ch.v_eps
        return Design(ch.per_column(ch.sm.smooth(ch.step_mean(lambda v, _: np.tanh(SHARPER * v / v_eps)))))

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        out = {}
        for i in range(len(coef)):
            kc, c = float(base_coef[2 + 3 * i]), float(coef[i])
            width = folded_coulomb(kc, c, ch.v_eps)[1]
            d_width = ch.v_eps * kc * (SHARPER - 1.0) / (kc + SHARPER * c) ** 2 if kc + SHARPER * c else math.inf
            out[f"smoothing_velocity_{i + 1}"] = (width, abs(d_width) * _sd(cov, i))
        return out

    def rejection(self, params, coef, base_coef):
        if any(c <= 0.0 for c in coef):
            return "a smoother transition than configured (negative sharp Coulomb term): not a sharper one"
        return super().rejection(params, coef, base_coef)


#: the sharp Coulomb column's transition is this many times sharper than v_eps (near the speed resolution
#: of a 21 ms Savitzky-Golay velocity at 1 kHz: 0.0025 rad/s for the nominal 0.01)
SHARPER = 4.0


def folded_coulomb(kc: float, kc_sharp: float, v_eps: float) -> tuple[float, float]:
    """(Coulomb level, smoothing velocity) of one tanh equal to ``kc tanh(v / v_eps) + kc_sharp tanh(SHARPER
    v / v_eps)`` in level and in slope at rest: what the simulator's single Coulomb term can take (the
    width bounded to the two columns')."""
    total = kc + kc_sharp
    slope = kc + SHARPER * kc_sharp
    if total <= 0.0 or slope <= 0.0:
        return kc, v_eps
    return total, float(np.clip(v_eps * total / slope, v_eps / SHARPER, SHARPER * v_eps))


class EncoderScale(Candidate):
    """A scale mismatch between the motor and the ankle encoders (a calibration, not an effect): with the
    motor angles read f x too large, the measured stretch is phi' = f phi + (f - 1) theta_j, so the cable
    law gains a column of the joint angle per axis, ``tau_j = K' phi' + c theta_j`` with f = 1 - c / K'.
    Only the ratio of the two encoders' scales shows (either may be off)."""

    cause = "encoder_scale"
    channel = "cable"
    calibration = True

    def design(self, ch, nl):
        return Design(ch.per_column(ch.sm.smooth(ch.joint)))

    def _beside_baseline(self, ch: CableChannel) -> np.ndarray:
        """The cable baseline's coefficients fitted with the scale columns."""
        X = np.hstack([ch.baseline_design(), self.design(ch, 0.0).X])
        return np.linalg.lstsq(X, ch.target(), rcond=None)[0]

    def ratios(self, ch: CableChannel) -> np.ndarray:
        """The scale ratio per axis fitted beside the cable baseline alone (before any effect is chosen)."""
        coef = self._beside_baseline(ch)
        with np.errstate(divide="ignore", invalid="ignore"):      # silent gauges (no stiffness): nan, no ratio
            return 1.0 - coef[-2:] / coef[[0, 3]]

    def stiffness(self, ch: CableChannel) -> tuple[np.ndarray, np.ndarray]:
        """The cable stiffness per axis (N m/rad) fitted beside the scale columns, and the spring term's
        size against the gauge torque's (sd of K x stretch over sd of the torque): a motor-encoder scale
        error tilts the measured stretch, which can turn the baseline's own stiffness negative (0.9 on
        generator D's seed 112: -2152 N m/rad on DP); a gauge of the wrong sign turns it negative either way."""
        k = self._beside_baseline(ch)[[0, 3]]
        size = np.abs(k) * np.std(ch.L_phi, axis=0) / np.maximum(np.std(ch.L_tau_j, axis=0), 1e-300)
        return k, size

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        K = base_coef[[0, 3]]
        return {f"motor_to_ankle_scale_{a}": (1.0 - float(coef[i] / K[i]), _sd(cov, i) / abs(float(K[i])))
                for i, a in enumerate(("dp", "ie"))}

    def rejection(self, params, coef, base_coef):
        off = [f"{v:.3g}" for v, _ in params.values() if not ENCODER_SCALE_RANGE[0] < v < ENCODER_SCALE_RANGE[1]]
        if off:
            return (f"encoder scale ratio {', '.join(off)} outside {ENCODER_SCALE_RANGE[0]:g}-"
                    f"{ENCODER_SCALE_RANGE[1]:g}: no calibration error")
        return super().rejection(params, coef, base_coef)


class Delay(Candidate):
    cause = "delay"
    nonlinear = "delay"
    #: a command's latency shifts the whole torque, mid-stroke too; a sticking motor's breakaway lags the
    #: torque at its rests and at the brief sticks of its reversals, shorter than any rest the stuck test judges
    in_motion = True
    mid_stroke = True

    def grid(self, ch):
        return list(np.arange(0.25e-3, 25.01e-3, 0.5e-3))

    def design(self, ch, nl):
        return Design(np.zeros((len(ch.target()), 0)), ch.target(nl))

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return {"delay": (nl, nl_sd)}


class Backlash(Candidate):
    """Slack as a dead zone per ankle axis: the spring term K dz(phi_a) with dz +/- half_width / R_axis."""

    cause = "backlash"
    channel = "cable"
    nonlinear = "half_width"
    form = {"per": "axis"}

    def grid(self, ch):
        """10 um-2 mm of cable (:data:`BACKLASH_WIDTHS`), from one count of the joint encoders at the longer
        lever: a narrower dead zone is below what the measured stretch resolves and fits its quantisation
        error, which the spring term carries and the gauges do not (a fixed part of a count where the foot
        comes back to rest at one angle: :meth:`implausible`; generator D seed 116, 12-bit joint encoders
        in walking, a 10 um dead zone explained 41 % of the cable residual)."""
        floor = ch.joint_step * float(np.max(ch.geometry.levers))
        return [float(v) for v in BACKLASH_WIDTHS if v >= floor]

    def linked(self, other):
        return isinstance(other, TautHardening)

    def widths(self, nl: float) -> np.ndarray:
        """The dead zone's half-width per axis [DP, IE] (m of cable) at the nonlinear value ``nl``."""
        return np.array([nl, nl])

    def clipped(self, ch, half_width: float) -> np.ndarray:
        """The stretch inside the dead zone per axis (samples x axes): the spring force it takes away / K."""
        b = self.widths(half_width) / ch.geometry.levers
        return np.clip(ch.phi, -b, b)

    def design(self, ch, nl):
        return Design(ch.per_column(ch.sm.smooth(self.clipped(ch, nl))))

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return {"half_width": (nl, nl_sd)}

    def implausible(self, coef, nl, ch, base_coef):
        """A taut cable with slack carries its spring force less the fitted step, -coef x half_width at each
        axis' lever. The measured stretch is known to a joint-encoder count only: where the foot comes back
        to rest at the same angle, its quantisation error is a fixed offset of up to half a count, which
        reads as such a step between loaded and unloaded. A step no larger than what half a count of
        stretch carries is that error, not slack."""
        step = -np.asarray(coef) * self.widths(nl) / ch.geometry.levers
        count = np.abs(base_coef[[0, 3]]) * ch.joint_step / 2.0
        if not np.any((step > 0.0) & (step <= count)):     # a negative step is no slack (rejection)
            return None
        return (f"the dead zone's step ({', '.join(f'{v:.3g}' for v in step)} N m per axis) is no larger than "
                f"what half a count of the joint encoders carries ({', '.join(f'{v:.3g}' for v in count)} N m): "
                "their quantisation error, not slack")

    def rejection(self, params, coef, base_coef):
        # slack takes the spring force away inside the dead zone: coefficient -K per axis; a positive one
        # is a spring that saturates (a clipped gauge), not slack
        share = -np.asarray(coef) / base_coef[[0, 3]]
        if np.any(share < SLACK_SHARE[0]) or np.any(share > SLACK_SHARE[1]):
            return (f"the dead zone takes {', '.join(f'{v:.2f}' for v in share)} x the stiffness per axis "
                    f"(slack: {SLACK_SHARE[0]:g}-{SLACK_SHARE[1]:g}; below 0 a saturating spring, e.g. a clipped gauge)")
        return super().rejection(params, coef, base_coef)


class AxisBacklash(Backlash):
    """Slack as a dead zone per ankle axis, each axis with a width of its own (``half_width`` for DP,
    ``half_width_ie`` for IE, m of cable): two axes' play need not be one length of cable (a joint's own
    play; generator E's dead zones of 4 and 3 mrad left a remainder of 97 % of the catch-all's beside the
    shared width, named `unknown`). The pair is coded in one integer, DP index x WIDTH_CODE + IE index into
    :data:`BACKLASH_WIDTHS`, resolved on that grid only; each axis' width is screened on its own (the axes'
    columns are apart), and the best few of each scored in pairs."""

    nonlinear = "half_widths"
    integer = True
    nonlinear_count = 2

    def linked(self, other):
        return False                     # two widths: no one slack to move together with

    def widths(self, nl):
        i, j = divmod(int(round(nl)), WIDTH_CODE)
        return BACKLASH_WIDTHS[[i, j]]

    def nonlinear_values(self, nl):
        w = self.widths(nl)
        return {"half_width": float(w[0]), "half_width_ie": float(w[1])}

    def _indices(self, ch) -> list[int]:
        """The indices into BACKLASH_WIDTHS of the widths :meth:`Backlash.grid` searches."""
        return [int(np.searchsorted(BACKLASH_WIDTHS, w)) for w in super().grid(ch)]

    def grid(self, ch):
        index = self._indices(ch)
        return [float(WIDTH_CODE * i + j) for i in index for j in index]

    def search_grid(self, ch, residual, design):
        """Per axis, the widths whose column alone explains most of ``residual`` beyond the baseline's span;
        their pairs."""
        index = self._indices(ch)
        Q = np.linalg.qr(ch.baseline_design())[0]
        explained = np.zeros((2, len(index)))
        for k, i in enumerate(index):
            X = design(float(WIDTH_CODE * i + i)).X                       # both axes at width i
            X = X - Q @ (Q.T @ X)
            for a in range(2):
                explained[a, k] = float(X[:, a] @ residual) ** 2 / max(float(X[:, a] @ X[:, a]), 1e-300)
        best = [np.asarray(index)[np.argsort(explained[a])[::-1][:AXIS_WIDTHS_SCORED]] for a in range(2)]
        return [float(WIDTH_CODE * i + j) for i in best[0] for j in best[1]]

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        # resolved on the grid only: the sd is half a grid step
        step = (BACKLASH_WIDTHS[1] / BACKLASH_WIDTHS[0] - 1.0) / 2.0
        return {k: (v, v * step) for k, v in self.nonlinear_values(nl).items()}


class CableBacklash(Backlash):
    """Slack as a dead zone on each cable's own stretch r (R phi)_i: per axis a the spring term loses
    (R^T clip(R phi, +/- half_width / r))_a / (R^T R)_aa, which is phi_a inside both dead zones."""

    form = {"per": "cable"}

    def clipped(self, ch, half_width):
        R, r = cable_map(ch)
        b = half_width / r
        c = np.clip(ch.phi @ R.T, -b, b)
        return (c @ R) / np.sum(R * R, axis=0)


def cable_map(ch: CableChannel) -> tuple[np.ndarray, float]:
    """(R, r): each cable's stretch is r (R phi)_i m; a law g per cable reaches axis a as
    K_a (R^T g)_a / (R^T R)_aa (R^T R is diagonal: the cables pull symmetrically)."""
    R = np.linalg.inv(ch.geometry.R_inv)
    return R, float(ch.geometry.levers[0] / R[0, 0])            # r: the pulley radius, m


class GearBacklash(Candidate):
    """A gap between a motor's rotor and its cable pulley (gear backlash), in the load channel of a record
    without joint angles (:class:`signals.LoadChannel`). The motor encoder reads the rotor, the cable
    pulls on the pulley, and the pulley lies against the side of the gap its cable's torque pushes it to:
    the pulley's angle is the rotor's less g sign(tc_i). While the load changes sign the rotor crosses the
    gap with no change of the cable torque. Per axis the spring law then loses K' (R^-1 g s)_a, s_i a
    smoothed sign of the cable torque motor i feels as the spring law predicts it (:attr:`load_hat`); the
    coefficient per axis is -K'_a g. The smoothing (a fraction of each motor's 99th-percentile predicted
    torque) is searched; quasi-statically the gap is the simulator's backlash per cable with half_width =
    r g (r the pulley radius), a dead zone of g in each motor's angle."""

    cause = "backlash"
    channel = "load"
    nonlinear = "sign_width"
    form = {"per": "cable"}

    def applies(self, ch):
        return hasattr(ch, "load_hat")

    def grid(self, ch):
        return list(np.geomspace(0.02, 0.32, 5))

    def design(self, ch, nl):
        scale = np.maximum(np.percentile(np.abs(ch.load_hat), 99, axis=0), 1e-12)
        side = np.tanh(ch.load_hat / (nl * scale)) @ ch.geometry.R_inv.T      # g sign(tc_i) at the axes / g
        return Design(ch.per_column(ch.sm.smooth(side)))

    def gaps(self, coef: np.ndarray, base_coef: np.ndarray) -> np.ndarray:
        """The gap's half-width g per axis (rad of motor angle at the output): -coefficient / K'."""
        return -np.asarray(coef) / base_coef[[0, 3]]

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        _, r = cable_map(ch)
        K = base_coef[[0, 3]]
        g = self.gaps(coef, base_coef)
        sd = np.sqrt(np.maximum(np.diag(cov)[:2], 0.0)) / np.abs(K)
        return {"half_width": (r * float(np.mean(g)), r * float(np.sqrt(np.sum(sd ** 2))) / 2.0)}

    def rejection(self, params, coef, base_coef):
        g = self.gaps(coef, base_coef)
        if np.any(g <= 0.0):
            return (f"the fitted gap is {', '.join(f'{v:.3g}' for v in g)} rad per axis: the load would lead the "
                    "rotor (not a gap)")
        return super().rejection(params, coef, base_coef)


class HardeningStiffness(Candidate):
    """Monotone stiffening of the cables: force k s (1 + (|s| / s_h)^(e - 1)), e on a grid (3: cubic,
    2: k s (1 + |s| / s0), 4), joint-torque correction K phi (R |phi| / s_h)^(e - 1) per axis."""

    cause = "stiffness_nonlinear"
    channel = "cable"
    nonlinear = "exponent"
    integer = True

    def grid(self, ch):
        return [2.0, 3.0, 4.0]

    def exponent(self, nl: float) -> float:
        return nl

    def shape(self, ch, nl: float) -> np.ndarray:
        """The correction / K per axis for s_h = 1 m (samples x axes): z |R_axis z|^(e - 1), z the stretch."""
        return ch.phi * np.abs(ch.geometry.levers * ch.phi) ** (self.exponent(nl) - 1.0)

    def design(self, ch, nl):
        return Design(ch.filt(self.gain(ch, nl) * self.shape(ch, nl))[:, None])

    def gain(self, ch, nl: float) -> np.ndarray:
        """The column's factor per axis: the nominal K (both axes scale with the one cable stiffness k, so
        one shared coefficient (k_true / k_nominal) / s_h^(e - 1) fits both, whatever k is)."""
        return ch.geometry.K

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        # the extended fit's own K (coefficients of phi) gives k_true / k_nominal
        ratio = float(np.mean(ch.geometry.K / base_coef[[0, 3]]))
        return self.law(float(coef[0]) * ratio, _sd(cov, 0) * ratio, nl, nl_sd)

    def law(self, c: float, sd: float, nl: float, nl_sd: float) -> dict[str, tuple[float, float]]:
        """The effect's parameters from the stiffening coefficient ``c`` = hardening_stretch^(1 - e) (its sd)."""
        e = self.exponent(nl)
        shape = {"exponent": (e, 0.0), **self.slack(nl, nl_sd)}
        if c <= 0.0:
            return {"hardening_stretch": (float("inf"), float("inf")), **shape}
        p = e - 1.0
        s = c ** (-1.0 / p)
        return {"hardening_stretch": (s, s * sd / (p * c)), **shape}

    def slack(self, nl: float, nl_sd: float) -> dict[str, tuple[float, float]]:
        """The slack parameter of the form (none: the law acts on the whole stretch)."""
        return {}

    def implausible(self, coef, nl, ch, base_coef):
        """A cable that hardens within less than one count of the joint encoders (at the longer lever, as
        :meth:`Backlash.grid`) hardens where the measured stretch resolves nothing: the term fits their
        quantisation or what a light free foot leaves below one count (generator E: a hardening stretch
        of 4e-6 rad, 1/23 of a count, beside cogging and beside a Stribeck term)."""
        floor = getattr(ch, "joint_step", 0.0) * float(np.max(ch.geometry.levers))
        zero = np.zeros((len(coef), len(coef)))
        s_h = self.parameters(coef, zero, nl, 0.0, ch, base_coef)["hardening_stretch"][0]
        if not s_h < floor:
            return None
        return (f"it hardens within {s_h:.3g} m of cable stretch, less than one count of the joint encoders "
                f"({floor:.3g} m): below what the measured stretch resolves")

    def rejection(self, params, coef, base_coef):
        if not math.isfinite(params["hardening_stretch"][0]):
            return "the fitted stiffening term is zero or negative (a linear or softening cable, not a hardening one)"
        return super().rejection(params, coef, base_coef)


class TautHardening(HardeningStiffness):
    """Stiffening of a cable with slack: the force law acts on the taut stretch beyond the dead zone,
    z = phi - clip(phi, +/- slack / R_axis) per axis, k z (1 + |z| / s0) (exponent 2). With the law on the
    whole stretch beside a dead zone, the dead zone's width absorbs the stiffening (a slack 25 % too wide
    explained 98.5 % and left nothing the plain form could fit). The slack is searched on the backlash
    grid with the dead zone in, so it settles where the cable goes taut."""

    nonlinear = "slack"
    integer = False
    form = {"per": "axis"}

    def grid(self, ch):
        return Backlash().grid(ch)

    def linked(self, other):
        return isinstance(other, Backlash) and not isinstance(other, AxisBacklash)     # one slack, not two

    def exponent(self, nl):
        return 2.0

    def shape(self, ch, nl):
        b = nl / ch.geometry.levers
        z = ch.phi - np.clip(ch.phi, -b, b)
        return z * np.abs(ch.geometry.levers * z)

    def slack(self, nl, nl_sd):
        return {"slack": (nl, nl_sd)}


class CableTautHardening(TautHardening):
    """The taut-stretch stiffening on each cable's own stretch (beside backlash per cable): the law on
    z_i = s_i - clip(s_i, +/- slack / r), s = R phi, mapped back to the axes (:func:`cable_map`)."""

    form = {"per": "cable"}

    def shape(self, ch, nl):
        R, r = cable_map(ch)
        s = ch.phi @ R.T
        z = s - np.clip(s, -nl / r, nl / r)
        return ((z * np.abs(r * z)) @ R) / np.sum(R * R, axis=0)


class LoadHardening(HardeningStiffness):
    """Stiffening of the cables seen through a linear load in series (:class:`signals.LoadChannel`): the
    spring law of the motor angles stiffens. To first order in the correction, a cable law ``K phi_c
    (1 + a |R phi_c|^p)`` behind a load that takes the rest of the motor angle gives ``K' phi (1 + a
    (K' / K)^(p + 1) |R phi|^p)`` per axis, K' the cable and the load in series (the load channel's
    stiffness), K the configured cable's: with that factor in each axis' column the one coefficient is
    the cable's own a (the axes' loads differ, so their series factors do)."""

    channel = "load"

    def gain(self, ch, nl):
        p = self.exponent(nl) - 1.0
        return ch.stiffness * (ch.stiffness / ch.geometry.K) ** (p + 1.0)

    def parameters(self, coef, cov, nl, nl_sd, ch, base_coef):
        return self.law(float(coef[0]), _sd(cov, 0), nl, nl_sd)


MOTOR_CANDIDATES: tuple[Candidate, ...] = (Stribeck(), StribeckExponential(), AsymmetricFriction(),
                                           AsymmetricFrictionPerMotor(), LoadDependentFriction(), Cogging(), Delay(),
                                           TorqueOffset(), TorqueConstantScale(), CoulombTransition())
CABLE_CANDIDATES: tuple[Candidate, ...] = (Backlash(), AxisBacklash(), CableBacklash(), HardeningStiffness(), TautHardening(),
                                           CableTautHardening(), EncoderScale())
#: the load channel (a linear load on the foot, no joint angles or too coarse ones): what a motor-side gap and a
#: stiffening cable leave in the spring law of the motor angles
LOAD_CANDIDATES: tuple[Candidate, ...] = (GearBacklash(), LoadHardening())

MIN_COGGING_PERIODS = 2.0
#: the dead zones' half-widths searched, m of cable (:meth:`Backlash.grid`)
BACKLASH_WIDTHS = np.geomspace(1e-5, 2e-3, 28)
WIDTH_CODE = 100                   # AxisBacklash's pair code: DP index x WIDTH_CODE + IE index
assert len(BACKLASH_WIDTHS) <= WIDTH_CODE
AXIS_WIDTHS_SCORED = 3             # per axis, the widths whose pairs AxisBacklash scores
SCALE_RANGE = (0.5, 2.0)           # plausible torque-constant calibration scales (true / configured)
ENCODER_SCALE_RANGE = (0.8, 1.25)  # plausible motor / ankle encoder scale ratios
SLACK_SHARE = (0.3, 2.0)           # share of the axis stiffness a dead zone may take away (ideal slack: 1)
ROTOR_COUNT_TOLERANCE = 0.001      # a rotor ripple's count within 0.1 % of N x gear ratio (Cogging.rotor_count)
MIN_COGGING_SEARCH = 2500          # periods per revolution searched at least (rotor cogging x gearbox)
COUNTS_PER_PERIOD = 8              # encoder counts a cogging period must span to be measured
MAX_COGGING_BINS = 1 << 22         # angle-domain grid points per revolution, at most
SPEED_BANDS = 16                   # speed bands of the angle-domain spectrum
TAPER_START, TAPER_END = 3.0, 6.0  # x the filter's cut-off: the cogging regressor's taper (Cogging.taper)
COGGING_SCREENED = 40              # angle-spectrum peaks whose filtered columns are built
COGGING_PEAKS = 4                  # ... of which the best explaining are scored by the regression
DELAY_LAGS_S = (0.001, 0.002, 0.004, 0.007, 0.011, 0.016, 0.022)


def _time_shapes(ch: Channel) -> list[np.ndarray]:
    """Slow shapes of time over the record (Legendre-like, per column): a drift."""
    t = ch.t - ch.t[0]
    u = (2.0 * t / max(float(t[-1]), 1e-12) - 1.0)[:, None] * np.ones((1, ch.m))
    return [u, 1.5 * u ** 2 - 0.5, 2.5 * u ** 3 - 1.5 * u]


def time_columns(ch: Channel) -> np.ndarray:
    """The slow time shapes, one set per motor or axis (block diagonal): a sensor offset drifting."""
    return np.hstack([ch.per_column(ch.sm.smooth(u)) for u in _time_shapes(ch)])


#: the motor catch-all's friction rippling with the motor angle (:func:`periodic_friction`)
PERIODIC_FRICTION_GROUP = "position (periodic friction)"


def periodic_friction(ch: MotorChannel, residual: np.ndarray) -> np.ndarray:
    """Friction rippling along the travel (an eccentric pulley, a sheath or bearing that drags more at
    some angles): ``sign(w_i) (a_i sin(n theta_i) + b_i cos(n theta_i))`` per motor, its sign following
    the motion, so not cogging. The count is the peak of the direction-weighted angle spectrum of the
    baseline ``residual`` (stacked, the channel's baseline fit's: :attr:`ChannelModels.baseline`) over
    cogging's counts (:meth:`Cogging.angle_power`); two columns per motor at one count. Without them such
    a ripple (20-60 periods per output turn, generator D) was `none`: the catch-all's slow position shapes
    span only 1-3 periods of the travel."""
    cogging = Cogging()
    if not cogging.applies(ch):
        return np.zeros((ch.n_rows * ch.m, 0))
    n_min, n_max = cogging.count_range(ch)
    moving = ~ch.resting
    power = Cogging.angle_power(ch, residual, n_max, moving * ch.sign)
    n = n_min + int(np.argmax(power[n_min:]))
    w = Cogging.taper(ch, n * ch.vel) * moving * ch.sign
    filtered = ch.sm.smooth(np.hstack([w * np.sin(n * ch.pos), w * np.cos(n * ch.pos)]))
    return np.hstack([ch.per_column(filtered[:, :ch.m]), ch.per_column(filtered[:, ch.m:])])


def catch_all_motor(models: ChannelModels) -> tuple[np.ndarray, list[str]]:
    """Generic columns for the motor channel (``models.ch``) and what each correlates with: a torque FIR
    (latency, dynamics), torque-constant nonlinearity, velocity and cable-torque shapes, slow position
    dependence (spring, preload, slow harmonics, friction varying along the travel), slow drift in time
    (also of the friction: temperature) and an offset. No low-speed shapes beyond the named Stribeck
    block: near zero speed the residual carries the friction-transition error of any velocity estimate,
    which must not read as an unnamed effect."""
    ch = models.ch
    now = ch.torque()
    cols = [ch.torque(lag) - now for lag in DELAY_LAGS_S]
    groups = ["latency (torque history)"] * len(cols)
    tau = ch.tau / max(float(np.max(np.abs(ch.tau))), 1e-12)
    v99 = max(float(np.percentile(np.abs(ch.vel), 99)), 1e-12)
    v = ch.vel / v99
    raw = [(tau * np.abs(tau), "torque level"), (tau ** 3, "torque level"), (v * np.abs(v), "velocity"),
           (v ** 3, "velocity"), (np.abs(v), "velocity"),
           (ch.step_mean(lambda w, sign: np.abs(sign)), "velocity")]
    if np.any(ch.tc):
        tcs = ch.tc / max(float(np.max(np.abs(ch.tc))), 1e-12)
        # no tc |tc| beside tau |tau|: where the motor torque nearly balances the cable torque at a steady
        # level (slow one-way motion) their difference is ~2 |tau| (tau - tc), the left side itself
        raw += [(x, "load (cable torque)") for x in (tcs, np.abs(tcs), np.abs(tcs) * ch.sign)]
    span = max(float(np.ptp(ch.pos)), 1e-12)
    p = (ch.pos - ch.pos.mean(axis=0)) / span
    raw += [(p, "position"), (p * np.abs(p), "position"), (p * ch.sign, "position"),
            (p * p * ch.sign, "position")]
    for n in (1, 2, 3):
        ang = 2 * np.pi * n * ch.pos / span
        raw += [(np.sin(ang), "position"), (np.cos(ang), "position")]
    for u in _time_shapes(ch):
        raw += [(u, "time (drift)"), (u * ch.sign, "time (drift)")]
    raw.append((np.ones_like(ch.pos), "offset"))
    cols += [ch.filt(r) for r, _ in raw]
    groups += [g for _, g in raw]
    ripple = periodic_friction(ch, models.baseline.residual)
    groups += [PERIODIC_FRICTION_GROUP] * ripple.shape[1]
    return np.column_stack(cols + [ripple]), groups


def without_groups(catch_all: CatchAll, dropped: set[str]) -> CatchAll:
    """``catch_all`` without the columns of the ``dropped`` groups."""
    def restricted(models: ChannelModels) -> tuple[np.ndarray, list[str]]:
        X, groups = catch_all(models)
        keep = [j for j, g in enumerate(groups) if g not in dropped]
        return X[:, keep], [groups[j] for j in keep]
    return restricted


#: in slow one-directional closed-loop motion the commanded torque mostly carries the controller's reaction
#: to noise and varies little: shapes of it can rebuild the left side (tau - tc) and fit the noise
INPUT_GROUPS = {"torque level", "latency (torque history)"}


#: the cable catch-all's stretch-history columns (a linear load's own dynamics in the load channel's baseline)
RELAXATION_GROUP = "stretch history (relaxation)"


def catch_all_cable(models: ChannelModels) -> tuple[np.ndarray, list[str]]:
    """Generic columns for the cable channel (``models.ch``, per axis) and what each correlates with: even
    and odd stretch shapes, rate-dependent terms, soft dead zones, and a slow drift in time."""
    ch = models.ch
    scale = np.maximum(np.percentile(np.abs(ch.phi), 99, axis=0), 1e-12)
    p = ch.phi / scale
    d = ch.L_dphi / np.maximum(np.percentile(np.abs(ch.L_dphi), 99, axis=0), 1e-12)
    raw = [(p * np.abs(p), "stretch"), (p ** 3, "stretch"), (p ** 5, "stretch"), (np.tanh(4 * p), "stretch"),
           (np.tanh(d / 0.05), "stretch rate"), (d * np.abs(d), "stretch rate"), (p * np.abs(d), "stretch rate"),
           (np.clip(p, -0.1, 0.1), "stretch"), (np.clip(p, -0.3, 0.3), "stretch")]
    raw += [(p - lagged(p, ch.dt, tc), RELAXATION_GROUP) for tc in RELAXATION_S]
    raw += [(u, "time (drift)") for u in _time_shapes(ch)]
    X = np.hstack([ch.per_column(ch.sm.smooth(r)) for r, _ in raw])
    return X, [g for _, g in raw for _axis in range(ch.m)]
