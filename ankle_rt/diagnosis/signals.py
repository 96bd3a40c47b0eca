"""The two residual channels' signals, built once from a recording with one zero-phase filter.

Every regression in the diagnosis has the form ``L[y] = sum_j c_j L[x_j]``, with ``L`` one zero-phase
low-pass (Butterworth, order 2, run forwards and backwards: scipy.signal.sosfiltfilt) applied to the
measured side and to every regressor alike, so filtering never biases a coefficient. Derivatives are
plain finite differences taken before ``L``: the second difference of a motor driven by a held torque
equals dt^2 / J times the mean of the two torques around the sample (so the torque is shifted half a
sample), exactly. After filtering, rows are decimated (the pass band ends far below the decimated
Nyquist rate) to keep the regressions fast.

Motor channel (per motor i, N m at the gearbox output):
    L[tau_i(t - dt/2)] - L[tc_i] = J_i L[D2 th_i] + D_i L[D1 th_i] + kc_i L[tanh(v_i / v_eps)] + effect
where tau is the held set value, tc = R^-T tau_j the cable torque each motor feels, from the strain
gauges (zero off the cables), and v a Savitzky-Golay velocity (short window) for nonlinear regressors.
A force f(v) enters D2 th at a sample as its mean over the two steps around it, weighted by the
triangle (1 - |s|), s = (t - t_k) / dt: the nonlinear velocity regressors are that mean, with v
extrapolated linearly by the Savitzky-Golay acceleration. Sampled at t_k instead, a friction whose sign
flips within a step (a fast reversal: kc tanh(v / v_eps) turns in 2 v_eps / a, a fraction of a sample
in walking) is wrong by up to kc at the samples next to every reversal, which reads as a negative
Stribeck effect larger than a real one.
Cable channel (per ankle axis, where joint angles are measured):
    L[tau_j] = K L[phi] + K beta L[D1 phi] + offset + effect,  phi = R^-1 th_m - th_joint.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ankle_rt.interchange import InterchangeError, Recording

CUTOFF_HZ = 30.0           # pass band of L (and the highest ripple/dynamics the regressions see)
FAST_WINDOW_S = 0.021      # s, Savitzky-Golay window of the velocity that nonlinear regressors use
ORDER = 3
KERNEL_POINTS = 16         # midpoints per sample of the triangle mean of the velocity regressors
DECIMATED_RATE_HZ = 250.0  # rows kept for the regressions
EDGE_S = 0.06              # s dropped at each end (filter transients, delay shifts)
#: s a motor's encoder must stay unchanged to count as resting (stuck): generator D's sticking motors rest
#: 50-300 ms at a time, while a tanh-friction motor reversing slowly keeps its count 10-50 ms as it moves
#: (generator A's seed 1022 lost its cogging to a 10 ms threshold: the ripple shows best at reversals)
REST_S = 0.05
#: s a motor's encoder must stay unchanged for a stuck rest (see :func:`stuck`)
STUCK_REST_S = 0.01
#: share of an encoder's changes between samples that must be whole counts for its readings to lie on a
#: lattice (:func:`lattice_step`; a few rows re-interpolated by the screening are not)
LATTICE_SHARE = 0.9
#: bytes of Stribeck means a motor channel keeps (:meth:`MotorChannel.stribeck_mean`: 36 grid values of
#: 480 kB each on a 30 s record at 1 kHz with two motors)
MAX_STRIBECK_BYTES = 64 << 20
#: s, time constants of the stretch-history columns: a relaxing (viscoelastic) element in the cable
#: catch-all, a linear load's own dynamics in the load channel's baseline (:class:`LoadChannel`)
RELAXATION_S = (0.1, 0.3, 1.0, 3.0)


@functools.cache
def _sosfilt_kernel():
    """scipy's second-order-section kernel (``scipy.signal._sosfilt._sosfilt``, what ``sosfilt`` runs on its
    copy of the signals: float64 rows, states per row), None where this scipy has none by that name or where
    it does not give sosfiltfilt's own result, to the bit, on a test signal (a private name may change)."""
    from scipy.signal import butter, sosfilt_zi, sosfiltfilt
    try:
        from scipy.signal._sosfilt import _sosfilt
        sos = butter(4, 0.1, output="sos")
        x = np.sin(np.arange(400.0)[:, None] * np.array([0.05, 0.31])) + np.arange(400.0)[:, None] * 1e-3
        same = np.array_equal(_filtfilt_with(_sosfilt, sos, sosfilt_zi(sos), x), sosfiltfilt(sos, x, axis=0))
    except Exception:         # pragma: no cover - another scipy: sosfiltfilt itself
        return None
    return _sosfilt if same else None


def _filtfilt_with(kernel, sos: np.ndarray, zi: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``scipy.signal.sosfiltfilt(sos, x, axis=0)`` for samples x columns of float64 through ``kernel`` (its
    second-order-section kernel): the same arithmetic (its odd extension of its default length, its initial
    states ``zi``, the kernel run forwards and backwards over each column) and the same layout of the result,
    without sosfiltfilt's and sosfilt's copies and checks on every call (they cost more than the filter)."""
    n, c = x.shape
    ntaps = 2 * len(sos) + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    edge = 3 * ntaps
    if n <= edge:
        from scipy.signal import sosfiltfilt
        return sosfiltfilt(sos, x, axis=0)         # raises its own error
    xt = x.T
    # odd extension (scipy.signal._arraytools.odd_ext), a signal per row
    ext = np.empty((c, n + 2 * edge))
    ext[:, edge:edge + n] = xt
    ext[:, :edge] = 2 * xt[:, :1] - xt[:, edge:0:-1]
    ext[:, edge + n:] = 2 * xt[:, -1:] - xt[:, -2:-(edge + 2):-1]
    state = np.ascontiguousarray(np.moveaxis(zi[:, :, None] * ext[:, 0], -1, 0))
    kernel(sos, ext, state)                                  # forwards, in place
    back = ext[:, ::-1].copy()
    state = np.ascontiguousarray(np.moveaxis(zi[:, :, None] * back[:, 0], -1, 0))
    kernel(sos, back, state)                                 # backwards
    return back[:, ::-1][:, edge:edge + n].T


def _odd_window(seconds: float, dt: float, least: int) -> int:
    w = max(least, int(round(seconds / dt)))
    return w if w % 2 else w + 1


@dataclass
class Smoother:
    """The one zero-phase filter of the diagnosis (scipy imported lazily: analysis extra)."""

    dt: float
    cutoff_hz: float
    sos: np.ndarray
    fast_window: int
    step: int          # decimation factor
    margin: int        # rows dropped at each end
    #: per sample and column group (samples x motors) the weight every raw signal gets before L (None: all
    #: ones); the motor channel gives a stuck motor's samples weight 0, so its equation reads 0 = 0 there on
    #: both sides alike. Signals of several column groups (motor after motor, repeated) are weighed alike.
    weight: np.ndarray | None = None

    @classmethod
    def for_period(cls, dt: float) -> "Smoother":
        from scipy.signal import butter
        cutoff = min(CUTOFF_HZ, 0.2 / dt)
        sos = butter(2, cutoff, fs=1.0 / dt, output="sos")
        step = max(1, int(round(1.0 / (dt * DECIMATED_RATE_HZ))))
        return cls(dt, cutoff, sos, _odd_window(FAST_WINDOW_S, dt, ORDER + 2), step, int(round(EDGE_S / dt)) + 2)

    @property
    def min_samples(self) -> int:
        """The shortest record the diagnosis works on: both filter edges dropped and 20 rows left."""
        return 2 * self.margin + 20 * self.step

    def smooth(self, x: np.ndarray, deriv: int = 0, weigh: bool = True) -> np.ndarray:
        """L[x], or L of the first / second central difference of x (per second, per second^2); the
        samples weighed by :attr:`weight` unless ``weigh`` is False."""
        if deriv == 1:
            x = np.gradient(x, self.dt, axis=0)
        elif deriv == 2:
            d = np.zeros_like(x)
            d[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / self.dt ** 2
            x = d
        if weigh and self.weight is not None:
            x = x * np.tile(self.weight, (1, x.shape[1] // self.weight.shape[1]))
        if x.ndim != 2 or x.dtype != np.float64 or _sosfilt_kernel() is None:
            from scipy.signal import sosfiltfilt
            return sosfiltfilt(self.sos, x, axis=0)
        return _filtfilt_with(_sosfilt_kernel(), self.sos, self._zi(), x)

    def _zi(self) -> np.ndarray:
        """scipy.signal.sosfilt_zi of the filter (sections x 2), computed once."""
        zi = self.__dict__.get("_zi_cache")
        if zi is None:
            from scipy.signal import sosfilt_zi
            zi = self.__dict__["_zi_cache"] = sosfilt_zi(self.sos)
        return zi

    def fast_derivative(self, x: np.ndarray, deriv: int = 1) -> np.ndarray:
        from scipy.signal import savgol_filter
        return savgol_filter(x, self.fast_window, ORDER, deriv=deriv, delta=self.dt, axis=0, mode="interp")

    def rows(self, n: int, good: np.ndarray | None = None) -> np.ndarray:
        """Indices of the rows kept for the regressions: decimated, without the filter's edge transients,
        and (``good``: per-sample flags from the data screening) only where no masked sample lies within
        the filter's reach."""
        idx = np.arange(self.margin, n - self.margin, self.step)
        if good is None or bool(np.all(good)):
            return idx
        reach = self.margin
        bad = np.convolve((~good).astype(float), np.ones(2 * reach + 1), mode="same") > 0.5
        return idx[~bad[idx]]


def resting(pos: np.ndarray, samples: int) -> np.ndarray:
    """Per sample and motor: the encoder count stays unchanged through a run of at least ``samples``
    samples (samples x motors). A real motor sticks there: its static friction takes whatever torque holds
    it, so a torque that depends on the angle (cogging) does not move it and shows in no residual."""
    out = np.zeros(pos.shape, dtype=bool)
    for i in range(pos.shape[1]):
        same = np.r_[False, np.diff(pos[:, i]) == 0.0, False]
        edges = np.flatnonzero(np.diff(same.astype(np.int8)))      # run starts and ends, in pairs
        for a, b in zip(edges[::2], edges[1::2]):
            if b - a + 1 >= samples:
                out[a:b + 1, i] = True
    return out


def reversals(vel: np.ndarray) -> np.ndarray:
    """Per sample and motor: the velocity's sign differs from the sample before (samples x motors). Around a
    reversal the friction turns over (a motor that sticks breaks away there), whatever law describes it."""
    sign = np.sign(vel)
    out = np.zeros(vel.shape, dtype=bool)
    out[1:] = sign[1:] != sign[:-1]
    return out


def stuck(resting_: np.ndarray, net: np.ndarray, holding: float | np.ndarray) -> np.ndarray:
    """Per sample and motor: a rest (a run of ``resting_``, every count in it kept for a while: the motor
    moves at most at a creep speed) whose filtered net torque (``net``, N m: input minus cable torque) no
    friction of the level ``holding`` (N m, per sample and motor or one number) can hold: no constant c
    (a load, cogging at that angle, a Coulomb asymmetry) keeps ``net - c`` within +-holding throughout,
    i.e. max(net - holding) > min(net + holding) (a constant level: the net torque changes by more than
    2 x holding). A friction law of velocity holds at most its level near zero speed (a motor whose
    friction is such a law creeps instead); static friction holds such a rest, and its samples say
    nothing about the model."""
    out = np.zeros(resting_.shape, dtype=bool)
    level = np.broadcast_to(holding, net.shape)
    for i in range(resting_.shape[1]):
        edges = np.flatnonzero(np.diff(np.r_[0, resting_[:, i].astype(np.int8), 0]))
        for a, b in zip(edges[::2], edges[1::2]):
            if float(np.max(net[a:b, i] - level[a:b, i])) > float(np.min(net[a:b, i] + level[a:b, i])):
                out[a:b, i] = True
    return out


def lattice_step(x: np.ndarray) -> float:
    """The step of the lattice an encoder's readings lie on (one count, in their unit), 0 where they lie on
    none (an analog or interpolated signal): the smallest change between samples but for the rarest 1 %
    (a row off the lattice), where nearly every change (LATTICE_SHARE) is a whole number of it."""
    d = np.abs(np.diff(np.asarray(x, dtype=float)))
    d = d[d > 0.0]
    if not len(d):
        return 0.0
    q = float(np.percentile(d, 1.0, method="lower"))
    k = d / q
    return q if float(np.mean(np.abs(k - np.round(k)) < 0.01)) >= LATTICE_SHARE else 0.0


def lagged(x: np.ndarray, dt: float, time_constant: float) -> np.ndarray:
    """``x`` through a first-order lag of ``time_constant`` (s), started at rest at x[0]."""
    from scipy.signal import lfilter
    a = math.exp(-dt / time_constant)
    return lfilter([1.0 - a], [1.0, -a], x, axis=0, zi=a * x[:1])[0]


def shift_rows(x: np.ndarray, samples: float) -> np.ndarray:
    """x delayed by a fractional number of samples (linear interpolation; the first rows repeat)."""
    whole = int(np.floor(samples))
    frac = samples - whole
    out = np.empty_like(x)
    src = np.arange(x.shape[0]) - whole
    a = x[np.clip(src, 0, x.shape[0] - 1)]
    b = x[np.clip(src - 1, 0, x.shape[0] - 1)]
    np.multiply(a, 1.0 - frac, out=out)
    out += frac * b
    return out


@dataclass
class Geometry:
    """What the ankle plant's channels need from the config: kinematics and the nominal cable model."""

    R_inv: np.ndarray        # theta = R_inv theta_m
    R_inv_T: np.ndarray      # motor torque of an ankle torque
    K: np.ndarray            # (2,) N m/rad nominal ankle stiffness [DP, IE]
    levers: np.ndarray       # (2,) m, [R_DP, R_IE]


def require_length(rec: Recording, usable: int | None = None) -> None:
    """Refuse a record too short for the diagnosis' filters (before anything is filtered), or with
    fewer than 20 ``usable`` rows left after screening, naming the file and its length."""
    n, least = len(rec), Smoother.for_period(rec.dt).min_samples
    if n < least or (usable is not None and usable < 20):
        rows = "" if usable is None else f" ({usable} usable)"
        raise InterchangeError(f"too short for the diagnosis: {n} rows{rows}, need at least {least}",
                               rec.source, "t", n)


class _StackedChannel:
    """What both channels share: the recording's smoother, the rows kept for the regressions, and
    stacking samples x columns (motors or axes) into one vector, column after column."""

    def __init__(self, rec: Recording, good: np.ndarray | None = None):
        self.source = rec.source
        self.dt = rec.dt
        self.sm = Smoother.for_period(self.dt)
        self.n_samples = len(rec)
        self.rows = self.sm.rows(self.n_samples, good)
        self.t = np.asarray(rec["t"], dtype=float)
        #: extra baseline columns of a known sensor artefact (a strain-gauge drift), not of the physics
        self.nuisance: np.ndarray | None = None

    def with_nuisance(self, X: np.ndarray) -> np.ndarray:
        return X if self.nuisance is None else np.hstack([X, self.nuisance])

    @property
    def n_rows(self) -> int:
        return len(self.rows)

    def filt(self, x: np.ndarray) -> np.ndarray:
        """L[x] at the kept rows, stacked column after column (x: samples x columns)."""
        return self.sm.smooth(x)[self.rows].T.ravel()

    def pick(self, filtered: np.ndarray) -> np.ndarray:
        """Already-filtered samples x columns -> kept rows, stacked."""
        return filtered[self.rows].T.ravel()

    def per_column(self, filtered: np.ndarray) -> np.ndarray:
        """Already-filtered samples x columns -> one regressor per column (motor or axis), each zero
        outside its own part of the stack (block diagonal: a coefficient per motor or axis)."""
        k = self.n_rows
        X = np.zeros((k * filtered.shape[1], filtered.shape[1]))
        for i in range(filtered.shape[1]):
            X[i * k:(i + 1) * k, i] = filtered[self.rows, i]
        return X


class MotorChannel(_StackedChannel):
    """Motor-side signals of all motors in a recording (columns = motors)."""

    def __init__(self, rec: Recording, kt: float | None, geometry: Geometry | None, v_eps: float,
                 good: np.ndarray | None = None, cogging_prior: float | None = None,
                 counts_per_rev: int | None = None, coulomb: float | None = None, gear_ratio: float | None = None):
        """``coulomb``: the nominal Coulomb level (N m), the holding level of the first stuck test
        (:meth:`weigh_rests`; None: nothing is stuck); ``gear_ratio``: motor turns per output turn, when the
        positions are output angles behind that gearbox (None: unknown)."""
        super().__init__(rec, good)
        self.cogging_prior = cogging_prior      # periods per output revolution from the config, if known
        self.counts_per_rev = counts_per_rev    # motor encoder counts per output revolution, if known
        self.gear_ratio = gear_ratio
        #: the motor encoders' scale relative to the true angle, as far as known (the cable side may show it)
        self.motor_scales: tuple[float, ...] = (1.0,)
        require_length(rec, self.n_rows)
        sm = self.sm
        self.m = 2 if rec.two_motors else 1
        self.pos = np.column_stack([rec[f"motor_pos_{i}"] for i in range(1, self.m + 1)])
        self.tau = rec.motor_input(kt)
        self.tc = np.zeros_like(self.pos)
        if geometry is not None and self.m == 2:
            for col in ("sg_torque_dp", "sg_torque_ie"):
                if col not in rec:
                    raise InterchangeError("the ankle plant needs the strain-gauge torques", rec.source, col, 0)
            tau_j = np.column_stack([rec["sg_torque_dp"], rec["sg_torque_ie"]])
            self.tc = tau_j @ geometry.R_inv_T.T
        self.geometry = geometry
        self.vel = sm.fast_derivative(self.pos)
        self.resting = resting(self.pos, max(3, int(round(REST_S / self.dt))))
        self.short_rests = resting(self.pos, max(3, int(round(STUCK_REST_S / self.dt))))
        #: per stacked row: no rest of its motor (count unchanged STUCK_REST_S) within the filter's reach
        self.moving_rows = self._far_from(self.short_rests)
        #: per stacked row: no motor rests or reverses within the filter's reach (see :func:`reversals`)
        self.sliding_rows = self._far_from(self.short_rests | reversals(sm.smooth(self.pos, 1, weigh=False)))
        self._acc = sm.fast_derivative(self.pos, 2)
        s = (np.arange(KERNEL_POINTS) + 0.5) / KERNEL_POINTS * 2.0 - 1.0
        w = 1.0 - np.abs(s)
        #: the triangle's weights, and v extrapolated to each of its points: kept, since every nonlinear
        #: velocity regressor (the Stribeck grids and their refinement) is a mean over the same points
        self._kernel_w = w / w.sum()
        self._kernel_vel = [self.vel + self._acc * (sj * self.dt) for sj in s]
        self.v_eps = v_eps
        self.set_smoothing_velocity(v_eps)
        self.stuck = np.zeros_like(self.resting)
        self.coulomb = coulomb                  # N m, the nominal Coulomb level (None: no rest is judged)
        self.weigh_rests(coulomb)

    def weigh_rests(self, holding: float | np.ndarray | None) -> bool:
        """Give the stuck rests (:func:`stuck`: more than a friction of level ``holding`` holds, N m per
        sample and motor or one number; None: no rest is stuck) weight 0 in every regression of the
        channel, and filter the signals again. Left in, the holding torques read as a load offset,
        friction asymmetry, a delay or an unknown remainder. Returns whether the stuck samples changed."""
        sm = self.sm
        new = np.zeros_like(self.resting)
        if holding is not None:
            net = sm.smooth(self.tau, weigh=False) - sm.smooth(self.tc, weigh=False)
            new = stuck(self.short_rests, net, holding)
        changed = not np.array_equal(new, self.stuck)
        self.stuck = new
        sm.weight = (~new).astype(float) if new.any() else None
        self._torque: dict[float, np.ndarray] = {}
        self.L_acc = sm.smooth(self.pos, 2)
        self.L_vel = sm.smooth(self.pos, 1)
        self.L_tc = sm.smooth(self.tc)
        return changed

    def _far_from(self, mask: np.ndarray) -> np.ndarray:
        """Per stacked row: no sample of ``mask`` (samples x motors) of its motor within the filter's reach."""
        reach = self.sm.margin
        kernel = np.ones(2 * reach + 1)
        near = np.column_stack([np.convolve(mask[:, i].astype(float), kernel, mode="same") > 0.5
                                for i in range(mask.shape[1])])
        return ~near[self.rows].T.ravel()

    def constants(self) -> np.ndarray:
        """A constant per motor (one column each, :meth:`per_column`), weighed before L like every other
        signal: a load on a stuck motor is held by its static friction like the rest of its torque, so the
        stuck samples read 0 = 0 for it too. Unweighed, the column asked for the load where the left side
        is weighed out, and the load came out biased toward zero (generator D seeds 128, 132, 138: the
        remainder read as friction asymmetry and an ``unknown`` offset)."""
        return self.per_column(self.sm.smooth(np.ones((self.n_samples, self.m))))

    def remove_gauge_offset(self, offset: np.ndarray) -> None:
        """Correct the cable torque for strain-gauge zero offsets (N m per ankle axis [DP, IE])."""
        self.tc = self.tc - np.asarray(offset) @ self.geometry.R_inv_T.T
        self.L_tc = self.sm.smooth(self.tc)

    def set_smoothing_velocity(self, v_eps: float) -> None:
        """Change v_eps of the Coulomb regressor tanh(v / v_eps) (position unit/s)."""
        self.v_eps = v_eps
        #: tanh(v / v_eps) at each kernel point, the Coulomb sign the friction regressors multiply
        self._kernel_sign = [np.tanh(v / v_eps) for v in self._kernel_vel]
        self.sign = self.step_mean(lambda v, sign: sign)
        #: Stribeck means by (velocity, exponent) at this v_eps (:meth:`stribeck_mean`), least recent first
        self._stribeck: dict[tuple[float, float], np.ndarray] = {}

    def step_mean(self, force: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
        """``force(v, tanh(v / v_eps))`` as D2 th sees it at each sample: its triangle-weighted mean over
        the two steps around the sample, v extrapolated linearly (samples x motors; see the module
        docstring). The kernel's velocities and Coulomb signs are computed once, not per regressor."""
        out = np.zeros_like(self.vel)
        for v, sign, wj in zip(self._kernel_vel, self._kernel_sign, self._kernel_w):
            out += wj * force(v, sign)
        return out

    def stribeck_mean(self, vs: float, exponent: float) -> np.ndarray:
        """:meth:`step_mean` of the Stribeck shape ``exp(-|v / vs|^exponent) tanh(v / v_eps)``: the same
        operations in the same order, in one buffer instead of a new array per operation, and cached
        (MAX_STRIBECK_BYTES, least recently used dropped first). The mean is the raw signal before L, which
        the weights of the stuck rests do not touch: the motor channel's second selection, after the rests
        are weighed anew (core._select_motor), finds the grid's means of the first."""
        key = (float(vs), float(exponent))
        out = self._stribeck.pop(key, None)
        if out is None:
            out = np.zeros_like(self.vel)
            buf = np.empty_like(self.vel)
            for v, sign, wj in zip(self._kernel_vel, self._kernel_sign, self._kernel_w):
                np.divide(v, vs, out=buf)
                np.abs(buf, out=buf)
                buf **= exponent
                np.negative(buf, out=buf)
                np.exp(buf, out=buf)
                buf *= sign
                buf *= wj
                out += buf
            out.flags.writeable = False           # shared by the cache
        self._stribeck[key] = out                 # most recent last
        while len(self._stribeck) > 1 and sum(a.nbytes for a in self._stribeck.values()) > MAX_STRIBECK_BYTES:
            self._stribeck.pop(next(iter(self._stribeck)))
        return out

    def torque(self, delay_s: float = 0.0) -> np.ndarray:
        """L[tau] at the kept rows for an actuation delay (s), ZOH half sample included (stacked); the
        torque is shifted before L, which weighs the stuck samples (cached per delay)."""
        if delay_s not in self._torque:
            self._torque[delay_s] = self.pick(self.sm.smooth(shift_rows(self.tau, 0.5 + delay_s / self.dt)))
        return self._torque[delay_s]

    def measured(self) -> np.ndarray:
        """What an NRMSE is relative to: the filtered motor torque (stacked)."""
        return self.torque()

    def target(self, delay_s: float = 0.0) -> np.ndarray:
        """The regression's left side: L[tau(t - dt/2 - delay)] - L[tc] (stacked)."""
        return self.torque(delay_s) - self.pick(self.L_tc)

    def baseline_design(self) -> np.ndarray:
        """Columns J_i, D_i, kc_i for each motor i (block diagonal over motors)."""
        per = [self.L_acc, self.L_vel, self.sm.smooth(self.sign)]
        k = self.n_rows
        X = np.zeros((k * self.m, 3 * self.m))
        for i in range(self.m):
            for j, sig in enumerate(per):
                X[i * k:(i + 1) * k, 3 * i + j] = sig[self.rows, i]
        return self.with_nuisance(X)


class CableChannel(_StackedChannel):
    """Cable-side signals per ankle axis [DP, IE]; needs joint encoders and strain gauges."""

    AXES = ("dp", "ie")

    def __init__(self, rec: Recording, geometry: Geometry, good: np.ndarray | None = None,
                 joint: np.ndarray | None = None, joint_step: float = 0.0):
        """``joint``: the joint angles (samples x axes, rad) when not the recording's own columns;
        ``joint_step``: the joint encoders' count (rad, :func:`lattice_step`; 0: resolved finely)."""
        super().__init__(rec, good)
        sm = self.sm
        self.geometry = geometry
        self.joint_step = joint_step
        pos_m = np.column_stack([rec["motor_pos_1"], rec["motor_pos_2"]])
        if joint is None:
            joint = np.column_stack([rec["ankle_dp"], rec["ankle_ie"]])
        self.phi = pos_m @ geometry.R_inv.T - joint
        self.joint = joint
        self.tau_j = np.column_stack([rec["sg_torque_dp"], rec["sg_torque_ie"]])
        self.m = 2
        self.L_tau_j = sm.smooth(self.tau_j)
        self.L_phi = sm.smooth(self.phi)
        self.L_dphi = sm.smooth(self.phi, 1)

    @staticmethod
    def available(rec: Recording) -> bool:
        return all(c in rec for c in ("ankle_dp", "ankle_ie", "sg_torque_dp", "sg_torque_ie", "motor_pos_2"))

    def target(self, delay_s: float = 0.0) -> np.ndarray:
        return self.pick(self.L_tau_j)

    def measured(self) -> np.ndarray:
        return self.target()

    def history_columns(self) -> np.ndarray:
        """Linear filters of the stretch per axis (block diagonal): its second derivative and its departures
        from first-order lags of RELAXATION_S, what a foot's inertia, a rig's damping or a relaxing element
        make of it."""
        history = [self.sm.smooth(self.phi, 2)] + [self.sm.smooth(self.phi - lagged(self.phi, self.dt, tc))
                                                   for tc in RELAXATION_S]
        return np.hstack([self.per_column(h) for h in history])

    def baseline_design(self) -> np.ndarray:
        """Columns K_a, K_a beta, offset_a per axis a (block diagonal)."""
        k = self.n_rows
        X = np.zeros((2 * k, 6))
        for a in range(2):
            X[a * k:(a + 1) * k, 3 * a] = self.L_phi[self.rows, a]
            X[a * k:(a + 1) * k, 3 * a + 1] = self.L_dphi[self.rows, a]
            X[a * k:(a + 1) * k, 3 * a + 2] = 1.0
        return self.with_nuisance(X)


class LoadChannel(CableChannel):
    """The cable channel of a recording without joint angles, where the foot rests on a linear load (a
    bench rig's torsion springs): the joint angle is then itself a linear function of the gauges'
    torque, so the gauges read a spring law of the motor angles, ``L[tau_j] = K' L[phi_m] + K' beta'
    L[D1 phi_m] + offset``, phi_m = R^-1 th_m, K' the cable and the load in series. A gap between a
    rotor and its pulley (gear backlash, which the motor encoder sees from the rotor's side) leaves the
    cable torque unchanged while the rotor crosses it, so the motor angle at which the cable torque crosses
    zero moves by the gap with each change of the load's sign (:class:`candidates.GearBacklash`). With a
    free foot or walking the gauges carry no spring law of the motor angles (:attr:`linear` is False) and
    nothing is diagnosed here."""

    def __init__(self, rec: Recording, geometry: Geometry, good: np.ndarray | None = None):
        super().__init__(rec, geometry, good, joint=np.zeros((len(rec), 2)))
        # the load's own dynamics (the foot's inertia, the rig's damping, a relaxing element) are linear
        # filters of the motor angles: nuisance columns of the baseline, never a discrepancy
        self.nuisance = self.history_columns()
        Xb = self.baseline_design()
        y = self.target()
        coef = np.linalg.lstsq(Xb, y, rcond=None)[0]
        #: per axis: the share of the gauge torque's variance the spring term K' phi_m explains alone
        self.spring_share = np.zeros(2)
        for a, ya in enumerate(np.split(y, 2)):
            centred = ya - ya.mean()
            spring = coef[3 * a] * self.L_phi[self.rows, a]
            miss = centred - (spring - spring.mean())
            self.spring_share[a] = 1.0 - float(miss @ miss) / max(float(centred @ centred), 1e-300)
        self.stiffness = coef[[0, 3]]
        #: the cable torque each motor feels (samples x motors, N m) as the spring law predicts it from the
        #: motor angles (not the measured torque: a column of the left side's own noise would fit it)
        load = np.column_stack([coef[3 * a] * self.phi[:, a] + coef[3 * a + 1] * np.gradient(self.phi[:, a], self.dt)
                                + coef[3 * a + 2] for a in range(2)])
        self.load_hat = load @ geometry.R_inv_T.T

    @staticmethod
    def available(rec: Recording) -> bool:
        return (all(c in rec for c in ("sg_torque_dp", "sg_torque_ie", "motor_pos_2"))
                and not all(c in rec for c in ("ankle_dp", "ankle_ie")))

    @property
    def linear(self) -> bool:
        """The gauges read a spring law of the motor angles: on both axes a positive stiffness whose term
        explains at least LINEAR_LOAD_SHARE of the torque's variance (a bench rig: ~1; a free foot or
        walking: < 0.7 on some axis)."""
        return bool(np.all(self.stiffness > 0.0) and np.all(self.spring_share >= LINEAR_LOAD_SHARE))


#: share of the gauge torque's variance a spring law of the motor angles must explain on each axis for the
#: load channel (:class:`LoadChannel`) to be diagnosed
LINEAR_LOAD_SHARE = 0.9
