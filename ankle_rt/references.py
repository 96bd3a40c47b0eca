"""Ankle reference profiles: hold, step, sine, chirp, a gait-like DP/IE stride, and a CSV file.

A profile maps the time since its start, ``tau`` (s, negative before its ``start_s``), to ankle
angles (rad, [DP, IE]) written into a preallocated array. Step, sine, chirp and gait move
*relative to the reference at the moment they start* (so starting one from a live daemon never
jumps); hold and CSV are absolute. All evaluation is plain-float arithmetic on tables built once.

The time base is the backend's sample time (``Estimate.t``), the same clock the simulator's
disturbances (``sim.disturbances``) use, so a configured experiment lines up with them exactly.
"""

from __future__ import annotations

import bisect
import math
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ankle_rt.float_buffer import float_buffer
from ankle_rt.schema import ConfigError, Field, Section, non_negative, positive, validate
from ankle_rt.interchange import InterchangeError, read_columns

DEG = math.pi / 180.0


class Profile:
    """Base: ``value(tau)`` returns (dp, ie) rad. ``relative`` profiles are added to the start point."""

    relative = True

    def begin(self, start: tuple[float, float]) -> None:
        """Called once when the profile starts, with the reference (rad) it starts from."""

    def value(self, tau: float) -> tuple[float, float]:
        raise NotImplementedError

    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((DP min, max), (IE min, max)) rad that ``value`` can reach, so a command can be refused
        before it would drive the ankle beyond its range (relative profiles: offsets)."""
        raise NotImplementedError


class Hold(Profile):
    """Hold the ankle at (dp, ie) rad."""

    relative = False

    def __init__(self, dp: float = 0.0, ie: float = 0.0):
        self.dp, self.ie = dp, ie

    def value(self, tau: float) -> tuple[float, float]:
        return self.dp, self.ie

    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return (self.dp, self.dp), (self.ie, self.ie)


class RampTo(Profile):
    """Move linearly from the current reference to (dp, ie) rad in ``ramp_s`` s, then hold."""

    relative = False

    def __init__(self, dp: float, ie: float, ramp_s: float):
        self.dp, self.ie, self.ramp = dp, ie, ramp_s
        self.start = (dp, ie)

    def begin(self, start: tuple[float, float]) -> None:
        self.start = start

    def value(self, tau: float) -> tuple[float, float]:
        if tau >= self.ramp:
            return self.dp, self.ie
        f = tau / self.ramp if tau > 0.0 else 0.0
        s0, s1 = self.start
        return s0 + f * (self.dp - s0), s1 + f * (self.ie - s1)

    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The target; the ramp from a reference already in range stays between the two."""
        return (self.dp, self.dp), (self.ie, self.ie)


class Step(Profile):
    """Steps of ``dp`` / ``ie`` rad at ``start_s`` (the paper's section 7: 10 deg DP, 5 deg IE)."""

    def __init__(self, dp: float, ie: float, start_s: float = 0.0):
        self.dp, self.ie, self.start = dp, ie, start_s

    def value(self, tau: float) -> tuple[float, float]:
        return (self.dp, self.ie) if tau >= self.start else (0.0, 0.0)

    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return (min(0.0, self.dp), max(0.0, self.dp)), (min(0.0, self.ie), max(0.0, self.ie))


class Sine(Profile):
    """``A sin(2 pi f (tau - start))`` per axis from ``start_s`` on; IE lags DP by ``ie_phase`` rad."""

    def __init__(self, amplitude_dp: float, amplitude_ie: float, frequency_hz: float, start_s: float = 0.0,
                 ie_phase: float = 0.0):
        self.a0, self.a1, self.w, self.start = amplitude_dp, amplitude_ie, 2 * math.pi * frequency_hz, start_s
        self.phase = ie_phase

    def value(self, tau: float) -> tuple[float, float]:
        x = tau - self.start
        if x < 0.0:
            return 0.0, 0.0
        return self.a0 * math.sin(self.w * x), self.a1 * math.sin(self.w * x - self.phase)

    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return (-abs(self.a0), abs(self.a0)), (-abs(self.a1), abs(self.a1))


class Chirp(Profile):
    """Linear chirp from ``f0_hz`` to ``f1_hz`` over ``duration_s`` (then zero): an identification sweep."""

    def __init__(self, amplitude_dp: float, amplitude_ie: float, f0_hz: float, f1_hz: float, duration_s: float,
                 start_s: float = 0.0):
        self.a0, self.a1, self.f0, self.start, self.duration = amplitude_dp, amplitude_ie, f0_hz, start_s, duration_s
        self.k = (f1_hz - f0_hz) / duration_s

    def value(self, tau: float) -> tuple[float, float]:
        x = tau - self.start
        if x < 0.0 or x > self.duration:
            return 0.0, 0.0
        s = math.sin(2.0 * math.pi * (self.f0 * x + 0.5 * self.k * x * x))
        return self.a0 * s, self.a1 * s

    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return (-abs(self.a0), abs(self.a0)), (-abs(self.a1), abs(self.a1))


# A plausible level-walking ankle cycle (heel strike at phase 0, toe-off near 0.62), after the
# textbook gait curves: (phase, DP deg, IE deg); DP positive = dorsiflexion, IE positive = inversion.
GAIT_KEYPOINTS = (
    (0.00, 0.0, 2.0), (0.07, -5.0, -1.0), (0.30, 5.0, -3.0), (0.45, 10.0, -2.0), (0.55, 2.0, 2.0),
    (0.62, -15.0, 5.0), (0.72, -8.0, 3.0), (0.85, 2.0, 1.0), (1.00, 0.0, 2.0),
)


def periodic_spline(points: Sequence[Sequence[float]], n: int) -> list[list[float]]:
    """Periodic cubic Hermite interpolation (Catmull-Rom tangents) of key points ``(phase, y1, y2,
    ...)`` (phase in [0, 1], last point = first) sampled at n+1 phases; one list per column y."""
    pts = list(points[:-1])
    ext = [(pts[-1][0] - 1.0, *pts[-1][1:])] + pts + [(p[0] + 1.0, *p[1:]) for p in pts[:2]]
    x = np.array([p[0] for p in ext])
    out = []
    for col in range(1, len(points[0])):
        y = np.array([p[col] for p in ext])
        vals = []
        for g in np.arange(n) / n:
            i = int(np.searchsorted(x, g, side="right")) - 1      # ext[i] <= g < ext[i+1], 1 <= i
            h = x[i + 1] - x[i]
            u = (g - x[i]) / h
            m0 = (y[i + 1] - y[i - 1]) / (x[i + 1] - x[i - 1]) * h
            m1 = (y[i + 2] - y[i]) / (x[i + 2] - x[i]) * h
            vals.append((2 * u**3 - 3 * u**2 + 1) * y[i] + (u**3 - 2 * u**2 + u) * m0
                        + (-2 * u**3 + 3 * u**2) * y[i + 1] + (u**3 - u**2) * m1)
        vals.append(vals[0])
        out.append([float(v) for v in vals])
    return out


def _periodic_table(points: tuple[tuple[float, float, float], ...], n: int) -> tuple[list[float], list[float]]:
    """:func:`periodic_spline` of (phase, DP deg, IE deg) key points; DP and IE in rad."""
    dp, ie = periodic_spline(points, n)
    return [v * DEG for v in dp], [v * DEG for v in ie]


class Gait(Profile):
    """A gait-like DP/IE cycle repeated every ``stride_s`` from ``start_s`` on, scaled by ``scale``."""

    TABLE_SIZE = 1000

    def __init__(self, stride_s: float, scale: float = 1.0, start_s: float = 0.0):
        self.stride, self.start = stride_s, start_s
        dp, ie = _periodic_table(GAIT_KEYPOINTS, self.TABLE_SIZE)
        self.dp = [scale * v for v in dp]
        self.ie = [scale * v for v in ie]
        self.dp0, self.ie0 = self.dp[0], self.ie[0]

    def value(self, tau: float) -> tuple[float, float]:
        x = tau - self.start
        if x < 0.0:
            return 0.0, 0.0
        pos = (x / self.stride) % 1.0 * self.TABLE_SIZE
        i = int(pos)
        f = pos - i
        dp, ie = self.dp, self.ie
        return (dp[i] + f * (dp[i + 1] - dp[i]) - self.dp0, ie[i] + f * (ie[i + 1] - ie[i]) - self.ie0)

    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return ((min(self.dp) - self.dp0, max(self.dp) - self.dp0), (min(self.ie) - self.ie0, max(self.ie) - self.ie0))

    def rates(self) -> list[tuple[float, float]]:
        """(DP, IE) rate (rad/s) over each segment of the stride's table: what the loop must follow."""
        per_s = self.TABLE_SIZE / self.stride
        return [((self.dp[i + 1] - self.dp[i]) * per_s, (self.ie[i + 1] - self.ie[i]) * per_s)
                for i in range(self.TABLE_SIZE)]


class CsvProfile(Profile):
    """Absolute references from a CSV with columns ``t`` (s), ``ref_dp``, ``ref_ie`` (rad), linearly
    interpolated and held at the last row. Bad files raise InterchangeError naming column and row.

    Loading reads a regular file of at most :data:`MAX_PROFILE_BYTES` and computes everything the
    loop needs (tables as plain lists, the reach) up front: the daemon has it parsed in a child
    process and hands it to the loop ready (never a file read in the loop thread)."""

    relative = False

    COLUMNS = ("t", "ref_dp", "ref_ie")

    def __init__(self, path: str | Path):
        def require(header: list[str]) -> None:
            for name in self.COLUMNS:
                if name not in header:
                    raise InterchangeError("required column missing", path, name, 0)

        data = read_columns(path, self.COLUMNS, require, min_rows=1, limit_bytes=MAX_PROFILE_BYTES)
        self.t, self.dp, self.ie = data["t"], data["ref_dp"], data["ref_ie"]
        self._bounds = ((min(self.dp), max(self.dp)), (min(self.ie), max(self.ie)))

    @classmethod
    def from_columns(cls, t: Sequence[float], dp: Sequence[float], ie: Sequence[float],
                     bounds: tuple[tuple[float, float], tuple[float, float]]) -> "CsvProfile":
        """A profile from columns already read and checked (by a child process:
        :mod:`ankle_rt.service.profile_process`), as lists or ``array('d')``; ``bounds`` as
        :meth:`bounds` returns them."""
        profile = cls.__new__(cls)
        profile.t, profile.dp, profile.ie, profile._bounds = t, dp, ie, bounds
        return profile

    def value(self, tau: float) -> tuple[float, float]:
        t = self.t
        i = bisect.bisect_right(t, tau)
        if i == 0:
            return self.dp[0], self.ie[0]
        if i >= len(t):
            return self.dp[-1], self.ie[-1]
        f = (tau - t[i - 1]) / (t[i] - t[i - 1])
        return (self.dp[i - 1] + f * (self.dp[i] - self.dp[i - 1]),
                self.ie[i - 1] + f * (self.ie[i] - self.ie[i - 1]))

    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return self._bounds


MAX_PROFILE_BYTES = 64 << 20
"""Largest reference CSV accepted (64 MiB, about 2 hours of 1 kHz references)."""


PROFILES: dict[str, Callable[..., Profile]] = {
    "hold": Hold, "step": Step, "sine": Sine, "chirp": Chirp, "gait": Gait, "csv": CsvProfile,
}

_ANGLE = 0.7   # rad (40 deg): the largest amplitude a profile accepts; the safety limit still applies
_LONGEST_S = 86400.0   # s: the latest start and longest duration a profile accepts


def _angle(doc: str, default: float = ...) -> Field:  # type: ignore[assignment]
    return Field(float, doc, default=default, low=-_ANGLE, high=_ANGLE)


# Parameters of each profile (SI: rad, s, Hz), shared by the config's reference section and the
# start_profile command, so both check the same names and ranges.
PROFILE_PARAMS: dict[str, Section] = {
    "hold": Section({"dp": _angle("rad DP", 0.0), "ie": _angle("rad IE", 0.0)}, optional=True),
    "step": Section({
        "dp": _angle("rad, DP step size", 10 * DEG), "ie": _angle("rad, IE step size", 5 * DEG),
        "start_s": non_negative("s after the profile starts", default=0.5, high=_LONGEST_S),
    }, optional=True),
    "sine": Section({
        "amplitude_dp": _angle("rad", 5 * DEG), "amplitude_ie": _angle("rad", 0.0),
        "frequency_hz": Field(float, "Hz", default=1.0, low=0.0, low_open=True, high=50.0),
        "start_s": non_negative("s", default=0.0, high=_LONGEST_S),
        "ie_phase": Field(float, "rad, IE lag behind DP", default=0.0, low=-2 * math.pi, high=2 * math.pi),
    }, optional=True),
    "chirp": Section({
        "amplitude_dp": _angle("rad", 2 * DEG), "amplitude_ie": _angle("rad", 0.0),
        "f0_hz": Field(float, "Hz at the start", default=0.1, low=0.0, high=100.0),
        "f1_hz": Field(float, "Hz at the end", default=10.0, low=0.0, high=100.0),
        "duration_s": positive("s", default=10.0, high=_LONGEST_S), "start_s": non_negative("s", default=0.0, high=_LONGEST_S),
    }, optional=True),
    "gait": Section({
        "stride_s": Field(float, "s per stride", default=1.1, low=0.3, high=10.0),
        "scale": Field(float, "scale of the DP/IE angles of the stride", default=1.0, low=0.0, high=2.0),
        "start_s": non_negative("s", default=0.0, high=_LONGEST_S),
    }, optional=True),
    "csv": Section({"path": Field(str, "CSV with columns t (s), ref_dp, ref_ie (rad)", default="")}, optional=True),
}


def angle_params(profile: str) -> set[str]:
    """The parameters of ``profile`` that are angles (their schema gives them in rad): what the
    command line shows and takes in degrees."""
    return {key for key, spec in PROFILE_PARAMS[profile].fields.items() if getattr(spec, "doc", "").startswith("rad")}


def validate_profile_params(name: str, params: Mapping[str, Any], source: str = "command") -> dict[str, Any]:
    """The checked parameters of profile ``name`` (defaults filled in). Bad names or values raise
    ConfigError naming the key (``params.<key>``)."""
    if name not in PROFILES:
        raise ConfigError(f"unknown profile {name!r} (expected one of: {', '.join(PROFILES)})", source, "name")
    checked = validate(dict(params), PROFILE_PARAMS[name], lambda _p: source, ("params",))
    if name == "csv" and not checked["path"]:
        raise ConfigError("a CSV file is needed", source, "params.path")
    return checked


def make_profile(name: str, params: Mapping[str, Any], source: str = "command") -> Profile:
    """Build profile ``name`` from SI parameters (see :func:`validate_profile_params`). A CSV profile
    reads its file here: the daemon does that in its background loader, never in the loop thread."""
    return PROFILES[name](**validate_profile_params(name, params, source))


class ReferenceGenerator:
    """The loop's ankle reference: the active profile, started at an absolute sample time."""

    def __init__(self, profile: Profile, t0: float = 0.0):
        # rad [DP, IE], refreshed by update(); controllers read ``ref``, the cycle the same two
        # entries as plain floats through the memoryview ``values``
        self.values, self.ref = float_buffer(2)
        self.base = (0.0, 0.0)
        self.profile = profile
        self.t0 = t0
        self.pending: Profile | None = None
        self.max_step = math.inf
        """rad per update the reference may move (inf: unlimited): set for commanded references (by
        the daemon) and configured CSV and hold ones (:func:`reference_from_config`), so neither a
        command, a file nor a hold's approach can make the reference jump or outrun the motors."""
        profile.begin(self.base)

    def start(self, profile: Profile) -> None:
        """Switch to ``profile`` at the next update (relative profiles start from the current reference)."""
        self.pending = profile

    def update(self, t: float) -> None:
        """Refresh ``ref`` for sample time ``t`` (s)."""
        if self.pending is not None:
            self.profile, self.pending = self.pending, None
            self.t0 = t
            self.base = (float(self.ref[0]), float(self.ref[1]))
            self.profile.begin(self.base)
        p = self.profile
        dp, ie = p.value(t - self.t0)
        if p.relative:
            dp += self.base[0]
            ie += self.base[1]
        step, ref = self.max_step, self.values
        if step != math.inf:         # rate limit (a NaN passes through: the safety layer faults on it)
            r0, r1 = ref[0], ref[1]
            dp = r0 + step if dp > r0 + step else (r0 - step if dp < r0 - step else dp)
            ie = r1 + step if ie > r1 + step else (r1 - step if ie < r1 - step else ie)
        ref[0] = dp
        ref[1] = ie


def reference_from_config(cfg: Mapping[str, Any]) -> ReferenceGenerator:
    """The configured profile (``reference.profile`` and its section), starting at sample time 0.
    A relative CSV path is taken relative to the config file."""
    r = cfg["reference"]
    name = r["profile"]
    params = dict(r[name])
    source = getattr(cfg, "source", "config")
    if name == "csv" and params["path"] and not Path(params["path"]).is_absolute() and Path(source).exists():
        params["path"] = str(Path(source).resolve().parent / params["path"])
    try:
        profile = make_profile(name, params, source)
    except ConfigError as exc:
        raise ConfigError(exc.message, source, f"reference.{name}.{exc.key.split('.')[-1]}") from None
    except InterchangeError as exc:      # the CSV file itself is bad: say which file, column and row
        raise ConfigError(str(exc), source, "reference.csv.path") from None
    generator = ReferenceGenerator(profile)
    # the absolute profiles (a CSV file, whose rate cannot be checked like a formula's, and a hold,
    # approached from wherever the ankle is over reference.ramp_s, which may be 0) are limited as a
    # commanded reference is
    if not profile.relative:
        generator.max_step = max_reference_step(cfg)
    return generator


def max_reference_step(cfg: Mapping[str, Any]) -> float:
    """rad per cycle a commanded or configured absolute (CSV, hold) reference may move:
    ``reference.max_rate_rad_s`` over one period of ``controller.rate_hz``."""
    return cfg["reference"]["max_rate_rad_s"] / cfg["controller"]["rate_hz"]
