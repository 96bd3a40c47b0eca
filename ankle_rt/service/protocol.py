"""The command protocol of the daemon: JSON lines over a Unix-domain socket.

One request per line, one reply line per request, UTF-8, at most :data:`MAX_LINE_BYTES` bytes
including the newline. A request is a JSON object whose ``"cmd"`` names the command; the other keys
are its fields, in SI units (angles in rad, gains as the controller uses them)::

    {"cmd": "status"}
    {"cmd": "activate"}                                   {"cmd": "deactivate"}
    {"cmd": "reset"}                                      {"cmd": "stop"}
    {"cmd": "set_reference", "dp": 0.17, "ie": -0.05, "ramp": 1.0}
    {"cmd": "set_gains", "kp": 90.0, "kd": 5.0}
    {"cmd": "start_profile", "name": "sine", "params": {"amplitude_dp": 0.1, "freq_hz": 0.5}}
    {"cmd": "list_controllers"}                           {"cmd": "set_controller", "type": "impedance"}

Replies are ``{"ok": true, ...data}`` or ``{"ok": false, "error": MESSAGE, "field": FIELD}``.
``field`` names what was wrong: a request key (``"dp"``, ``"params.freq_hz"``), ``"cmd"`` for the
command itself (unknown, or refused in the current state) and ``"line"`` for the line as a whole
(too long, not UTF-8, not JSON, not an object). Every check happens here, before the daemon sees the
command, so a bad request can never reach the controller: parsing either returns a complete, valid
command or raises :class:`CommandError`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Union

from ankle_rt.command_limits import DEFAULT_MAX_GAINS, GAIN_FIELDS, gain_maxima, gain_problem, reference_problem
from ankle_rt.jsonout import finite_or_none

MAX_LINE_BYTES = 4096
"""Longest accepted request line in bytes, newline included."""

PROFILE_NAMES = ("hold", "step", "sine", "chirp", "gait", "csv")  # = references.PROFILES (tested); no numpy import here
MAX_PROFILE_PARAMS = 16
MAX_STRING_CHARS = 256


class CommandError(ValueError):
    """A request was rejected. ``field`` names the offending key (see the module docstring)."""

    def __init__(self, field: str, message: str):
        self.field = field
        self.message = message
        super().__init__(f"field '{field}': {message}")


@dataclass(frozen=True)
class CommandLimits:
    """The ranges requests are checked against, taken from the daemon's configuration."""

    reference_limit_rad: float = math.radians(40.0)
    """|dp| and |ie| references must not exceed this (rad); the ankle's software range."""
    max_ramp_s: float = 60.0
    """Longest accepted reference ramp (s)."""
    max_gains: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_MAX_GAINS))
    """Largest value of each gain field a set_gains request may ask for (controller.gain_limits)."""

    @classmethod
    def from_config(cls, cfg: Mapping[str, Any]) -> "CommandLimits":
        return cls(reference_limit_rad=math.radians(cfg["limits"]["ankle_range_deg"]),
                   max_gains=gain_maxima(cfg["controller"]["gain_limits"]))


class Pending:
    """A reply that is not ready yet (a profile file being loaded off the loop thread): the server
    holds the client's later requests and calls ``poll()`` on each of its polls until it returns the
    reply data (or raises CommandError). ``poll`` must not block."""

    def __init__(self, poll: Callable[[], "dict | None"]):
        self.poll = poll


@dataclass(frozen=True)
class Status:
    """Report the daemon's state, estimates, references and loop statistics."""


@dataclass(frozen=True)
class Activate:
    """configured/safe -> active: enable the amplifiers (gains ramp in: soft start)."""


@dataclass(frozen=True)
class Deactivate:
    """active -> safe: zero the set values and disable the amplifiers."""


@dataclass(frozen=True)
class ResetFault:
    """fault -> safe: acknowledge a fault; the only way out of the fault state."""


@dataclass(frozen=True)
class Stop:
    """Shut the daemon down cleanly, as SIGTERM does: safe state first, log flushed, exit 0."""


@dataclass(frozen=True)
class SetReference:
    """Hold the ankle at (dp, ie) rad, reached by a linear ramp of ``ramp`` s (None: the daemon's default)."""

    dp: float
    ie: float
    ramp: float | None = None


# set_gains for the gait_phase controller: which phase's parameters change, and its equilibrium angles
PHASE_FIELDS: dict[str, str] = {
    "phase": "gait phase whose parameters change (gait_phase controller: early_stance, late_stance, "
             "early_swing, late_swing, safe)",
    "equilibrium_dp": "rad, the phase's DP equilibrium angle (within the ankle range)",
    "equilibrium_ie": "rad, the phase's IE equilibrium angle (within the ankle range)",
}
GAIT_PHASES = ("early_stance", "late_stance", "early_swing", "late_swing", "safe")
"""= ankle_rt.control.gait_phase.PHASES (tested)."""


@dataclass(frozen=True)
class SetGains:
    """Change controller gains at run time (bumpless). Only the given fields change (None = keep)."""

    kp: float | None = None
    kd: float | None = None
    stiffness_dp: float | None = None
    stiffness_ie: float | None = None
    damping_dp: float | None = None
    damping_ie: float | None = None
    kp_dp: float | None = None
    kp_ie: float | None = None
    ki_dp: float | None = None
    ki_ie: float | None = None
    torque_rate_dp: float | None = None
    torque_rate_ie: float | None = None
    phase: str | None = None
    equilibrium_dp: float | None = None
    equilibrium_ie: float | None = None

    def given(self) -> dict[str, Any]:
        """The fields the request set, name -> value."""
        return {name: getattr(self, name) for name in (*GAIN_FIELDS, *PHASE_FIELDS) if getattr(self, name) is not None}


@dataclass(frozen=True)
class StartProfile:
    """Start a reference profile by name. ``params`` are the profile's own keys (numbers in SI
    units, or strings such as a CSV path); the daemon checks their names and ranges and names
    a bad one as ``params.<key>``."""

    name: str
    params: Mapping[str, float | str] = field(default_factory=dict)


@dataclass(frozen=True)
class ListControllers:
    """Name the built-in and installed plugin controllers, and the running one."""


@dataclass(frozen=True)
class SetController:
    """Replace the running controller by ``type`` (a built-in or plugin name) with ``params`` (its
    ``controller.params``), validated like the config. Refused while active."""

    type: str
    params: Mapping[str, float | str | list[float]] = field(default_factory=dict)


Command = Union[Status, Activate, Deactivate, ResetFault, Stop, SetReference, SetGains, StartProfile,
                ListControllers, SetController]

_NO_FIELDS = {"status": Status, "activate": Activate, "deactivate": Deactivate, "reset": ResetFault, "stop": Stop,
              "list_controllers": ListControllers}
COMMAND_NAMES = (*_NO_FIELDS, "set_reference", "set_gains", "start_profile", "set_controller")


def _number(obj: Any, key: Any, where: str | None = None) -> float:
    """A finite JSON number (not a boolean) as float."""
    where = where or key
    value = obj[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CommandError(where, f"expected a number, got {_short(value)}")
    try:
        number = float(value)
    except OverflowError:
        raise CommandError(where, "number out of range") from None
    if not math.isfinite(number):
        raise CommandError(where, "expected a finite number")
    return number


def _short(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _check_keys(obj: Mapping[str, Any], allowed: tuple[str, ...], required: tuple[str, ...] = ()) -> None:
    for key in obj:
        if key != "cmd" and key not in allowed:
            expected = f"expected one of: {', '.join(allowed)}" if allowed else "this command takes no fields"
            raise CommandError(str(key), f"unknown field ({expected})")
    for key in required:
        if key not in obj:
            raise CommandError(key, "missing")


def _angle(obj: Mapping[str, Any], key: str, limits: CommandLimits) -> float:
    value = _number(obj, key)
    problem = reference_problem(value, limits.reference_limit_rad)
    if problem:
        raise CommandError(key, problem)
    return value


def _set_reference(obj: Mapping[str, Any], limits: CommandLimits) -> SetReference:
    _check_keys(obj, ("dp", "ie", "ramp"), required=("dp", "ie"))
    ramp = None
    if "ramp" in obj:
        ramp = _number(obj, "ramp")
        if not 0.0 <= ramp <= limits.max_ramp_s:
            raise CommandError("ramp", f"must be between 0 and {limits.max_ramp_s:g} s, got {ramp:g}")
    return SetReference(_angle(obj, "dp", limits), _angle(obj, "ie", limits), ramp)


def _set_gains(obj: Mapping[str, Any], limits: CommandLimits) -> SetGains:
    names = tuple(GAIN_FIELDS)
    _check_keys(obj, names + tuple(PHASE_FIELDS))
    values: dict[str, Any] = {}
    for name in names:
        if name in obj:
            value = _number(obj, name)
            problem = gain_problem(name, value, limits.max_gains)
            if problem:
                raise CommandError(name, problem)
            values[name] = value
    for name in ("equilibrium_dp", "equilibrium_ie"):
        if name in obj:
            values[name] = _angle(obj, name, limits)
    if not values:
        raise CommandError("cmd", f"set_gains needs at least one of: {', '.join(names + ('equilibrium_dp', 'equilibrium_ie'))}")
    if "phase" in obj:
        if obj["phase"] not in GAIT_PHASES:
            raise CommandError("phase", f"unknown phase {_short(obj['phase'])} (expected one of: {', '.join(GAIT_PHASES)})")
        values["phase"] = obj["phase"]
    elif "equilibrium_dp" in values or "equilibrium_ie" in values:
        raise CommandError("phase", "equilibrium angles belong to a gait phase: give phase too")
    return SetGains(**values)


def _string(obj: Mapping[str, Any], key: str, where: str | None = None) -> str:
    """A JSON string of at most MAX_STRING_CHARS characters."""
    where = where or key
    value = obj[key]
    if not isinstance(value, str):
        raise CommandError(where, f"expected a string, got {_short(value)}")
    if len(value) > MAX_STRING_CHARS:
        raise CommandError(where, f"string longer than {MAX_STRING_CHARS} characters")
    return value


def _params(obj: Mapping[str, Any], lists: bool = False) -> dict[str, Any]:
    """The optional ``params`` object: at most MAX_PROFILE_PARAMS numbers or strings (with ``lists``
    also lists of at most MAX_PROFILE_PARAMS numbers, e.g. [DP, IE] pairs), named params.KEY."""
    raw = obj.get("params", {})
    if not isinstance(raw, dict):
        raise CommandError("params", f"expected an object, got {_short(raw)}")
    if len(raw) > MAX_PROFILE_PARAMS:
        raise CommandError("params", f"at most {MAX_PROFILE_PARAMS} parameters")
    params: dict[str, Any] = {}
    for key, value in raw.items():
        where = f"params.{key}"
        if isinstance(value, str):
            params[key] = _string(raw, key, where)
        elif lists and isinstance(value, list):
            if len(value) > MAX_PROFILE_PARAMS:
                raise CommandError(where, f"at most {MAX_PROFILE_PARAMS} numbers")
            params[key] = [_number(value, i, f"{where}[{i}]") for i in range(len(value))]
        else:
            params[key] = _number(raw, key, where)
    return params


def _start_profile(obj: Mapping[str, Any]) -> StartProfile:
    _check_keys(obj, ("name", "params"), required=("name",))
    name = obj["name"]
    if name not in PROFILE_NAMES:
        raise CommandError("name", f"unknown profile {_short(name)} (expected one of: {', '.join(PROFILE_NAMES)})")
    return StartProfile(name, _params(obj))


def _set_controller(obj: Mapping[str, Any]) -> SetController:
    _check_keys(obj, ("type", "params"), required=("type",))
    return SetController(_string(obj, "type"), _params(obj, lists=True))


def parse_command(line: bytes, limits: CommandLimits | None = None) -> Command:
    """Parse and check one request line (with or without its newline).

    Raises :class:`CommandError` naming the field for anything malformed or out of range; never
    raises anything else, whatever the bytes.
    """
    limits = limits or CommandLimits()
    if len(line) > MAX_LINE_BYTES:
        raise CommandError("line", f"longer than {MAX_LINE_BYTES} bytes")
    try:
        text = line.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CommandError("line", f"not valid UTF-8 (byte {exc.start})") from None
    try:
        obj = json.loads(text)  # NaN/Infinity parse, then fail the finiteness check naming their field
    except RecursionError:
        raise CommandError("line", "not valid JSON (nested too deeply)") from None
    except ValueError as exc:
        raise CommandError("line", f"not valid JSON ({exc})") from None
    if not isinstance(obj, dict):
        raise CommandError("line", f"expected a JSON object like {{\"cmd\": \"status\"}}, got {_short(obj)}")
    if "cmd" not in obj:
        raise CommandError("cmd", "missing (the command name)")
    name = obj["cmd"]
    if not isinstance(name, str):
        raise CommandError("cmd", f"expected a string, got {_short(name)}")
    if name in _NO_FIELDS:
        _check_keys(obj, ())
        return _NO_FIELDS[name]()
    if name == "set_reference":
        return _set_reference(obj, limits)
    if name == "set_gains":
        return _set_gains(obj, limits)
    if name == "start_profile":
        return _start_profile(obj)
    if name == "set_controller":
        return _set_controller(obj)
    raise CommandError("cmd", f"unknown command {_short(name)} (expected one of: {', '.join(COMMAND_NAMES)})")


def format_reply(ok: bool, **data: Any) -> bytes:
    """One reply line: ``{"ok": ok, ...data}`` + newline. NaN/inf become null."""
    return json.dumps({"ok": ok, **finite_or_none(data)}, allow_nan=False, separators=(",", ":")).encode() + b"\n"


def encode_request(cmd: str, **fields: Any) -> bytes:
    """One request line (the client's side): ``{"cmd": cmd, ...fields}`` + newline, refused here
    (CommandError naming the field) when a number is not finite or the line is too long."""
    try:
        line = json.dumps({"cmd": cmd, **fields}, allow_nan=False, separators=(",", ":")).encode() + b"\n"
    except ValueError:
        bad = next((k for k, v in fields.items() if isinstance(v, float) and not math.isfinite(v)), "params")
        raise CommandError(bad, "expected a finite number") from None
    if len(line) > MAX_LINE_BYTES:
        raise CommandError("line", f"longer than {MAX_LINE_BYTES} bytes")
    return line


def decode_reply(line: bytes) -> dict[str, Any]:
    """A reply line as a dict; ValueError when it is not a JSON object."""
    reply = json.loads(line)
    if not isinstance(reply, dict):
        raise ValueError(f"not a JSON object: {line[:80]!r}")
    return reply


def error_reply(exc: CommandError) -> bytes:
    """The reply line for a rejected request."""
    return format_reply(False, error=exc.message, field=exc.field)
