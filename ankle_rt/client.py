"""A Python client of the running daemon, for experiment scripts (docs/service.md, "Scripting experiments").

::

    from ankle_rt.client import AnkleClient

    with AnkleClient.connect("/etc/ankle-rt/config.yaml") as ankle:   # the socket of that config
        ankle.activate(tare_timeout_s=5)          # waits for the strain-gauge tare
        ankle.set_reference(math.radians(10), 0.0, ramp_s=0.5)
        ankle.set_gains(kp=90.0, kd=5.0)          # any gain name the running controller takes
        data = ankle.record(duration_s=2.0, interval_s=0.02)   # name -> numpy array
    # leaving the block deactivates the ankle if this client activated it

Everything is in SI units (angles in rad), as on the wire. One connection carries every request
(reopened when the daemon closed it for idling). A refusal raises :class:`CommandRefused`, whose
``field`` names what was wrong (``dp``, ``kp``, ``params.frequency_hz``, ``cmd`` for a command refused
in the current state); no daemon, no permission or no reply within ``timeout_s`` raise
:class:`DaemonUnreachable`. The framing is :mod:`ankle_rt.service.protocol`'s.

Samples come from ``status`` requests, one per ``interval_s`` (a request waits for the daemon's next
poll, every ``service.poll_period_s`` = 10 ms by default, so fewer than 100 samples/s): enough to
watch and script an experiment. Every cycle is in the run log and, with ``lsl.enabled``, on the Lab
Streaming Layer (docs/lab.md).
"""

from __future__ import annotations

import math
import select
import socket
import time
from pathlib import Path
from typing import Any, Iterator, Mapping, Sequence

import numpy as np

from ankle_rt.service.protocol import CommandError, decode_reply, encode_request

SAMPLE_FIELDS: tuple[str, ...] = (
    "t", "state", "est_ankle_dp", "est_ankle_ie", "ref_dp", "ref_ie", "motor_pos_1", "motor_pos_2",
    "motor_vel_1", "motor_vel_2", "sg_torque_dp", "sg_torque_ie", "current_cmd_1", "current_cmd_2")
"""The fields of a sample (log record names, docs/design.md; SI: s, rad, rad/s, N m, A). ``state`` is
the safety state's name; every other field is a float (NaN when the daemon sent null)."""


class DaemonUnreachable(ConnectionError):
    """No daemon answered on the socket (not running, no permission, no reply in time)."""


class CommandRefused(CommandError):
    """The daemon refused a request; ``field`` names what was wrong, ``message`` why."""


def socket_path_of(config: "str | Path | Mapping[str, Any] | None" = None) -> Path:
    """The daemon's socket as ``ankle-rt ctl`` finds it: ``service.socket_path`` of ``config`` (a config
    file or a loaded config), else the automatic path (docs/service.md)."""
    from ankle_rt.config_schema import SERVICE
    from ankle_rt.service.link import socket_path

    if config is None:
        return socket_path({"service": {"socket_path": SERVICE.fields["socket_path"].default}})
    if isinstance(config, (str, Path)):
        from ankle_rt.config import load_config
        config = load_config(config)
    return socket_path(config)


class AnkleClient:
    """A connection to the daemon on the Unix socket ``path``; ``timeout_s`` bounds every reply."""

    def __init__(self, path: str | Path, timeout_s: float = 5.0, *, deactivate_on_exit: bool = True):
        self.path = Path(path)
        self.timeout_s = timeout_s
        self.deactivate_on_exit = deactivate_on_exit
        self.activated = False   # this client activated the ankle (leaving a ``with`` block deactivates it)
        self._sock: socket.socket | None = None
        self._buf = b""

    @classmethod
    def connect(cls, config: "str | Path | Mapping[str, Any] | None" = None, *, socket_path: str | Path | None = None,
                timeout_s: float = 5.0, deactivate_on_exit: bool = True) -> "AnkleClient":
        """Connect to the daemon of ``config`` (file or loaded config; None: the automatic path), or
        at ``socket_path``. Raises DaemonUnreachable when nothing listens there."""
        client = cls(socket_path if socket_path is not None else socket_path_of(config), timeout_s,
                     deactivate_on_exit=deactivate_on_exit)
        client._open()
        return client

    # -- the connection ------------------------------------------------------------------------------
    def _open(self) -> socket.socket:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.settimeout(self.timeout_s)
        try:
            sock.connect(str(self.path))
        except (FileNotFoundError, ConnectionRefusedError):
            sock.close()
            raise DaemonUnreachable(f"no daemon is listening on {self.path} (is it running? `systemctl status "
                                    "ankle-rt`, or start one with `ankle-rt run`)") from None
        except PermissionError:
            sock.close()
            raise DaemonUnreachable(f"permission denied on {self.path}: the socket is for the service's user and "
                                    "group (add yourself to group ankle-rt)") from None
        except OSError as exc:
            sock.close()
            raise DaemonUnreachable(f"cannot connect to {self.path}: {exc.strerror or exc}") from None
        self._sock, self._buf = sock, b""
        return sock

    def _live_socket(self) -> socket.socket:
        """The open connection, reopened if the daemon closed it (it drops clients idle for
        ``service.client_timeout_s``): a closed peer reads as end of stream before we send."""
        sock = self._sock
        if sock is not None and select.select([sock], [], [], 0.0)[0]:
            try:
                closed = sock.recv(1, socket.MSG_PEEK) == b""
            except OSError:
                closed = True
            if closed:
                self.close()
                sock = None
        return sock if sock is not None else self._open()

    def request(self, cmd: str, **fields: Any) -> dict[str, Any]:
        """Send one request and return the reply's data (without ``ok``). Raises CommandRefused (the
        daemon's refusal), CommandError (a field that cannot be sent: nothing is sent) or
        DaemonUnreachable."""
        line = encode_request(cmd, **fields)
        kept = self._sock
        sock = self._live_socket()
        try:
            self._exchange(sock, line)
        except (ConnectionResetError, BrokenPipeError, EOFError):
            self.close()
            if sock is not kept or self._buf:
                raise DaemonUnreachable(f"the daemon on {self.path} closed the connection without a reply") from None
            # a kept connection the daemon dropped as idle as the request went out: it drops a client
            # only before reading its request, so nothing was handled; once more on a new connection
            try:
                self._exchange(self._open(), line)
            except (ConnectionResetError, BrokenPipeError, EOFError):
                self.close()
                raise DaemonUnreachable(f"the daemon on {self.path} closed the connection without a reply") from None
        reply_line, self._buf = self._buf.split(b"\n", 1)
        try:
            reply = decode_reply(reply_line)
        except ValueError:
            self.close()
            raise DaemonUnreachable(f"the reply from {self.path} is not a JSON object: {reply_line[:80]!r}") from None
        if not reply.pop("ok", False):
            raise CommandRefused(str(reply.get("field")), str(reply.get("error")))
        return reply

    def _exchange(self, sock: socket.socket, line: bytes) -> None:
        """Send ``line`` and read until a whole reply line is buffered. Raises ConnectionResetError,
        BrokenPipeError or EOFError (the daemon closed the connection: the caller decides), else
        DaemonUnreachable."""
        try:
            sock.sendall(line)
            while b"\n" not in self._buf:
                chunk = sock.recv(65536)
                if not chunk:
                    raise EOFError
                self._buf += chunk
        except socket.timeout:
            self.close()
            raise DaemonUnreachable(f"no reply from {self.path} within {self.timeout_s:g} s") from None
        except (ConnectionResetError, BrokenPipeError):
            raise
        except OSError as exc:
            self.close()
            raise DaemonUnreachable(f"cannot talk to the daemon on {self.path}: {exc.strerror or exc}") from None

    def close(self) -> None:
        """Close the connection (the daemon keeps running)."""
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self) -> "AnkleClient":
        return self

    def __exit__(self, *exc: object) -> None:
        try:
            if self.deactivate_on_exit and self.activated:
                try:
                    self.deactivate()
                except (DaemonUnreachable, CommandRefused):
                    pass   # gone, or no longer active (fault): the ankle is not driven either way
        finally:
            self.close()

    # -- commands ----------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        """The daemon's status (docs/service.md: state, fault, estimates, gains, loop statistics)."""
        return self.request("status")

    def state(self) -> str:
        """``configured``, ``active``, ``fault`` or ``safe``."""
        return str(self.status()["state"])

    def activate(self, tare_timeout_s: float = 0.0) -> None:
        """Enable the amplifiers (gains ramp in). Until the strain gauges are tared the daemon refuses;
        this retries for up to ``tare_timeout_s`` s before raising that refusal."""
        deadline = time.monotonic() + tare_timeout_s
        while True:
            try:
                self.request("activate")
                break
            except CommandRefused as exc:
                if "tared" not in exc.message or time.monotonic() >= deadline:
                    raise
                time.sleep(0.05)
        self.activated = True

    def deactivate(self) -> None:
        """Zero the set values and disable the amplifiers."""
        self.request("deactivate")
        self.activated = False

    def reset(self) -> None:
        """Acknowledge a fault (fault -> safe)."""
        self.request("reset")

    def stop(self) -> None:
        """Shut the daemon down (safe state first, log flushed)."""
        self.request("stop")
        self.activated = False

    def set_reference(self, dp_rad: float, ie_rad: float, ramp_s: float | None = None) -> None:
        """Ramp the ankle reference to (dp, ie) rad over ``ramp_s`` s (None: the configured ramp)."""
        fields: dict[str, float] = {"dp": float(dp_rad), "ie": float(ie_rad)}
        if ramp_s is not None:
            fields["ramp"] = float(ramp_s)
        self.request("set_reference", **fields)

    def set_gains(self, phase: str | None = None, **gains: float) -> None:
        """Change the running controller's gains (ramped, bumpless), by name: ``kp``, ``kd``,
        ``stiffness_dp``, ... (docs/service.md), each within ``controller.gain_limits``. For the
        gait-phase controller ``phase`` names the phase whose parameters change (``equilibrium_dp``
        and ``equilibrium_ie`` rad too)."""
        fields: dict[str, float | str] = {name: float(value) for name, value in gains.items()}
        if phase is not None:
            fields["phase"] = phase
        self.request("set_gains", **fields)

    def gains(self) -> dict[str, float]:
        """The running controller's gains, name -> value (SI)."""
        return dict(self.status().get("gains") or {})

    def start_profile(self, name: str, **params: float | str) -> dict[str, Any]:
        """Start a reference profile (``hold``, ``step``, ``sine``, ``chirp``, ``gait``, ``csv``) with
        its config keys as ``params`` (SI; a csv ``path`` is made absolute, the daemon reads it)."""
        if name == "csv" and isinstance(params.get("path"), (str, Path)):
            params["path"] = str(Path(params["path"]).resolve())
        return self.request("start_profile", name=name, params=params)

    def controllers(self) -> dict[str, Any]:
        """``{"controllers": {name: "module:attribute"}, "current": name}``: built-ins and plugins."""
        return self.request("list_controllers")

    def set_controller(self, name: str, **params: float | str | Sequence[float]) -> None:
        """Replace the controller by ``name`` with ``params`` (its ``controller.params``: numbers,
        strings, lists of numbers), validated like the config. Refused while active (deactivate first)."""
        self.request("set_controller", type=name,
                     params={k: list(v) if isinstance(v, (tuple, list, np.ndarray)) else v for k, v in params.items()})

    # -- samples -----------------------------------------------------------------------------------
    def samples(self, interval_s: float = 0.02, duration_s: float | None = None,
                count: int | None = None) -> Iterator[dict[str, Any]]:
        """Yield one sample (SAMPLE_FIELDS) per ``interval_s`` until ``duration_s`` has passed or
        ``count`` samples came (both None: until the caller stops iterating)."""
        end = None if duration_s is None else time.monotonic() + duration_s
        n = 0
        next_due = time.monotonic()
        while (count is None or n < count) and (end is None or time.monotonic() < end):
            yield sample_of(self.status())
            n += 1
            next_due += interval_s
            time.sleep(max(0.0, next_due - time.monotonic()))

    def record(self, duration_s: float, interval_s: float = 0.02) -> dict[str, np.ndarray]:
        """Samples for ``duration_s`` s as columns: name -> numpy array (``state`` as strings)."""
        return columns_of(list(self.samples(interval_s, duration_s=duration_s)))


def _floats(values: Any, scale: float = 1.0) -> tuple[float, float]:
    a, b = values if values else (None, None)
    return (math.nan if a is None else a * scale, math.nan if b is None else b * scale)


def sample_of(status: Mapping[str, Any]) -> dict[str, Any]:
    """A status reply as one sample: SAMPLE_FIELDS, SI units (the status' degrees converted to rad)."""
    rad = math.pi / 180.0
    sample: dict[str, Any] = {"t": math.nan if status.get("t") is None else float(status["t"]),
                              "state": str(status.get("state"))}
    for (a, b), key, scale in ((("est_ankle_dp", "est_ankle_ie"), "ankle_deg", rad),
                               (("ref_dp", "ref_ie"), "reference_deg", rad),
                               (("motor_pos_1", "motor_pos_2"), "motor_pos_rad", 1.0),
                               (("motor_vel_1", "motor_vel_2"), "motor_vel_rad_s", 1.0),
                               (("sg_torque_dp", "sg_torque_ie"), "sg_torque_nm", 1.0),
                               (("current_cmd_1", "current_cmd_2"), "current_a", 1.0)):
        sample[a], sample[b] = _floats(status.get(key), scale)
    return sample


def columns_of(samples: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Samples as columns: name -> numpy array (float64; ``state`` as a string array)."""
    return {name: np.array([s[name] for s in samples], dtype=str if name == "state" else float)
            for name in SAMPLE_FIELDS}
