"""``ankle-rt ctl``: command a running daemon over its Unix socket (see docs/service.md).

Exit codes: 0 the daemon accepted the command, 1 it replied with an error, 3 no daemon could be
reached (not running, no permission, no reply)."""

from __future__ import annotations

import argparse
import json
import math
import socket
import sys
from pathlib import Path

from ankle_rt.service.protocol import GAIN_FIELDS, PROFILE_NAMES

EXIT_REFUSED = 1
EXIT_UNREACHABLE = 3


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "ctl", help="command a running daemon (status, activate, ref, gains, ...)",
        description="Send one command to a running ankle-rt daemon over its Unix socket and print the reply. "
                    "Exit code 0: accepted; 1: the daemon refused it (the reply names the field); "
                    "3: no daemon reachable.")
    parser.add_argument("--socket", type=Path, help="the daemon's socket (default: service.socket_path of --config, "
                                                    "else the automatic path, see docs/service.md)")
    parser.add_argument("--config", type=Path, help="read service.socket_path from this config file")
    parser.add_argument("--timeout", type=float, default=5.0, help="s to wait for the reply (default 5)")
    parser.add_argument("--json", action="store_true", help="print the raw JSON reply")
    sub = parser.add_subparsers(dest="ctl_command", required=True, metavar="CMD")
    sub.add_parser("status", help="state, estimates, references, loop statistics")
    sub.add_parser("activate", help="enable the amplifiers (gains ramp in)")
    sub.add_parser("deactivate", help="zero the set values and disable the amplifiers")
    sub.add_parser("reset", help="acknowledge a fault (fault -> safe)")
    sub.add_parser("stop", help="shut the daemon down cleanly (safe state first, log flushed)")
    ref = sub.add_parser("ref", help="set the ankle reference",
                         description="Set the ankle reference. DP and IE are in DEGREES (converted to rad on "
                                     "the wire) unless --rad is given.")
    ref.add_argument("dp", type=float, help="dorsi-plantarflexion angle, degrees (rad with --rad)")
    ref.add_argument("ie", type=float, help="inversion-eversion angle, degrees (rad with --rad)")
    ref.add_argument("--rad", action="store_true", help="DP and IE are given in rad")
    ref.add_argument("--ramp", type=float, help="s to ramp linearly to the new reference")
    gains = sub.add_parser("gains", help="change controller gains at run time (bumpless, SI units)")
    for name, doc in GAIN_FIELDS.items():
        gains.add_argument("--" + name.replace("_", "-"), dest=name, type=float, help=doc)
    profile = sub.add_parser("profile", help="start a reference profile",
                             description="Start a reference profile. Parameters are KEY=VALUE: angles (dp, ie, "
                                         "amplitude_dp, amplitude_ie, ie_phase) in DEGREES (converted to rad on the "
                                         "wire) unless --rad is given, times in s, frequencies in Hz; non-numbers "
                                         "are passed as strings. csv: path=FILE is sent as an absolute path; the "
                                         "daemon reads it, so its user must be able to (the service sees neither "
                                         "/home nor /tmp).")
    profile.add_argument("name", choices=PROFILE_NAMES)
    profile.add_argument("params", nargs="*", metavar="KEY=VALUE")
    profile.add_argument("--rad", action="store_true", help="angles are given in rad")
    parser.set_defaults(handler=run)


def request_from_args(args: argparse.Namespace) -> dict:
    """The wire request (a JSON object, SI units) for the parsed command line."""
    name = args.ctl_command
    if name == "ref":
        scale = 1.0 if args.rad else math.pi / 180.0
        req = {"cmd": "set_reference", "dp": args.dp * scale, "ie": args.ie * scale}
        if args.ramp is not None:
            req["ramp"] = args.ramp
        return req
    if name == "gains":
        return {"cmd": "set_gains", **{k: getattr(args, k) for k in GAIN_FIELDS if getattr(args, k) is not None}}
    if name == "profile":
        params = dict(_param(p) for p in args.params)
        if not args.rad:
            for key in angle_params(args.name) & params.keys():
                if isinstance(params[key], float):
                    params[key] = math.radians(params[key])
        if args.name == "csv" and isinstance(params.get("path"), str):
            params["path"] = str(Path(params["path"]).resolve())
        return {"cmd": "start_profile", "name": args.name, "params": params}
    return {"cmd": name}


def angle_params(profile: str) -> set[str]:
    """The parameters of ``profile`` that are angles (their schema gives them in rad)."""
    from ankle_rt.references import PROFILE_PARAMS

    return {key for key, spec in PROFILE_PARAMS[profile].fields.items() if getattr(spec, "doc", "").startswith("rad")}


def _param(text: str) -> tuple[str, float | str]:
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise SystemExit(f"ankle-rt ctl: profile parameter {text!r} is not KEY=VALUE")
    try:
        return key, float(value)
    except ValueError:
        return key, value


def resolve_socket(args: argparse.Namespace) -> Path:
    from ankle_rt.config_schema import SERVICE
    from ankle_rt.service.link import socket_path

    if args.socket is not None:
        return args.socket
    if args.config is not None:
        from ankle_rt.config import load_config
        return socket_path(load_config(args.config))
    return socket_path({"service": {"socket_path": SERVICE.fields["socket_path"].default}})


class Unreachable(Exception):
    """No daemon answered on the socket."""


def send(path: Path, request: dict, timeout: float) -> dict:
    """Send one request line and return the decoded reply line."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(timeout)
    try:
        try:
            sock.connect(str(path))
        except (FileNotFoundError, ConnectionRefusedError):
            raise Unreachable(f"no daemon is listening on {path} (is it running? `systemctl status ankle-rt`, "
                              "or start one with `ankle-rt run`)") from None
        except PermissionError:
            raise Unreachable(f"permission denied on {path}: the socket is for the service's user and group "
                              "(add yourself to group ankle-rt)") from None
        sock.sendall(json.dumps(request).encode() + b"\n")
        data = b""
        while not data.endswith(b"\n"):
            chunk = sock.recv(65536)
            if not chunk:
                raise Unreachable(f"the daemon on {path} closed the connection without a reply")
            data += chunk
    except socket.timeout:
        raise Unreachable(f"no reply from {path} within {timeout:g} s") from None
    except OSError as exc:
        raise Unreachable(f"cannot talk to the daemon on {path}: {exc.strerror or exc}") from None
    finally:
        sock.close()
    try:
        return json.loads(data)
    except ValueError:
        raise Unreachable(f"the reply from {path} is not JSON: {data[:80]!r}") from None


def format_fields(data: dict, prefix: str = "") -> list[str]:
    """``key: value`` lines, nested objects flattened with dots, numbers to 6 significant digits."""
    lines = []
    for key, value in data.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            lines += format_fields(value, name + ".")
        elif isinstance(value, list):
            lines.append(f"{name}: " + ", ".join(_fmt(v) for v in value))
        else:
            lines.append(f"{name}: {_fmt(value)}")
    return lines


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if value is None:
        return "-"
    return str(value).lower() if isinstance(value, bool) else str(value)


def _degree_note(args: argparse.Namespace, reply: dict) -> str:
    """For a refused angle given in degrees: what the daemon's rad value was on the command line."""
    field = str(reply.get("field") or "")
    key = field.removeprefix("params.")
    if args.ctl_command == "profile" and not args.rad and field != key and key in angle_params(args.name):
        given = dict(_param(p) for p in args.params).get(key)
        if isinstance(given, float):
            return f" (the command line takes degrees: {key}={given:g} deg is {math.radians(given):.4g} rad)"
    return ""


def run(args: argparse.Namespace) -> int:
    path = resolve_socket(args)
    try:
        reply = send(path, request_from_args(args), args.timeout)
    except Unreachable as exc:
        print(f"ankle-rt ctl: {exc}", file=sys.stderr)
        return EXIT_UNREACHABLE
    if args.json:
        print(json.dumps(reply))
    elif reply.get("ok"):
        body = {k: v for k, v in reply.items() if k != "ok"}
        print("\n".join(format_fields(body)) if body else "ok")
    else:
        print(f"ankle-rt ctl: refused: field '{reply.get('field')}': {reply.get('error')}{_degree_note(args, reply)}",
              file=sys.stderr)
    return 0 if reply.get("ok") else EXIT_REFUSED
