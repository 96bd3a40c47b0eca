"""``ankle-rt ctl``: command a running daemon over its Unix socket (see docs/service.md).

Exit codes: 0 the daemon accepted the command, 1 it replied with an error, 3 no daemon could be
reached (not running, no permission, no reply)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from ankle_rt.client import AnkleClient, DaemonUnreachable, socket_path_of
from ankle_rt.command_limits import GAIN_FIELDS
from ankle_rt.references import angle_params
from ankle_rt.service.protocol import GAIT_PHASES, PHASE_FIELDS, PROFILE_NAMES, CommandError

EQUILIBRIA = ("equilibrium_dp", "equilibrium_ie")   # ctl gains' angles: degrees on the command line
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
    status = sub.add_parser("status", help="state, estimates, references, loop statistics",
                            description="Print the daemon's status as key: value lines; angles in degrees "
                                        "(motor positions in deg, velocities in deg/s) unless --rad is given.")
    status.add_argument("--rad", action="store_true", help="angles in rad (velocities in rad/s), as on the wire")
    sub.add_parser("activate", help="enable the amplifiers (gains ramp in)")
    sub.add_parser("deactivate", help="zero the set values and disable the amplifiers")
    sub.add_parser("reset", help="acknowledge a fault (fault -> safe)")
    sub.add_parser("stop", help="shut the daemon down cleanly (safe state first, log flushed)")
    watch = sub.add_parser("watch", help="live view: state, fault, references, angles, currents (Ctrl-C quits)",
                           description="Ask the daemon for its status every --interval s and redraw it (on a "
                                       "terminal; otherwise one block per refresh). Angles in degrees. Ends on "
                                       "Ctrl-C, after --count refreshes, or when the daemon goes away (exit 3).")
    watch.add_argument("--interval", type=float, default=0.5, metavar="S", help="s between refreshes (default 0.5)")
    watch.add_argument("--count", type=int, default=0, metavar="N", help="stop after N refreshes (default: never)")
    ref = sub.add_parser("ref", help="set the ankle reference",
                         description="Set the ankle reference. DP and IE are in DEGREES (converted to rad on "
                                     "the wire) unless --rad is given.")
    ref.add_argument("dp", type=float, help="dorsi-plantarflexion angle, degrees (rad with --rad)")
    ref.add_argument("ie", type=float, help="inversion-eversion angle, degrees (rad with --rad)")
    ref.add_argument("--rad", action="store_true", help="DP and IE are given in rad")
    ref.add_argument("--ramp", type=float, help="s to ramp linearly to the new reference")
    gains = sub.add_parser("gains", help="change controller gains at run time (bumpless; SI units, a gait phase's "
                                             "equilibria in degrees)")
    for name, doc in GAIN_FIELDS.items():
        gains.add_argument("--" + name.replace("_", "-"), dest=name, type=float, help=doc)
    gains.add_argument("--phase", choices=GAIT_PHASES, help=PHASE_FIELDS["phase"] + "; the other options then "
                                                               "set that phase's stiffness, damping and equilibrium")
    for name in EQUILIBRIA:
        gains.add_argument("--" + name.replace("_", "-"), dest=name, type=float,
                           help=PHASE_FIELDS[name].replace("rad, ", "DEGREES (rad with --rad), ", 1))
    gains.add_argument("--rad", action="store_true", help="--equilibrium-dp / --equilibrium-ie are given in rad")
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
    sub.add_parser("controllers", help="list the built-in and installed plugin controllers, and the running one")
    controller = sub.add_parser("controller", help="switch the controller (refused while active)",
                                description="Replace the running controller by NAME (a built-in or an installed "
                                            "plugin, see `ctl controllers`) with KEY=VALUE as its controller.params "
                                            "(numbers, strings, or comma-separated numbers for a list: "
                                            "stiffness=60,30). SI units. Validated like the config; refused while "
                                            "active.")
    controller.add_argument("name", metavar="NAME")
    controller.add_argument("params", nargs="*", metavar="KEY=VALUE")
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
        req = {"cmd": "set_gains", **{k: getattr(args, k) for k in (*GAIN_FIELDS, *PHASE_FIELDS)
                                      if getattr(args, k) is not None}}
        if not args.rad:
            for key in EQUILIBRIA:
                if key in req:
                    req[key] = math.radians(req[key])
        return req
    if name == "profile":
        params = dict(_param(p) for p in args.params)
        if not args.rad:
            for key in angle_params(args.name) & params.keys():
                if isinstance(params[key], float):
                    params[key] = math.radians(params[key])
        if args.name == "csv" and isinstance(params.get("path"), str):
            params["path"] = str(Path(params["path"]).resolve())
        return {"cmd": "start_profile", "name": args.name, "params": params}
    if name == "controllers":
        return {"cmd": "list_controllers"}
    if name == "controller":
        return {"cmd": "set_controller", "type": args.name,
                "params": dict(_param(p, lists=True) for p in args.params)}
    return {"cmd": name}


def _param(text: str, lists: bool = False) -> tuple[str, float | str | list[float]]:
    """KEY=VALUE: a number, else (with ``lists``) comma-separated numbers as a list, else a string."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise SystemExit(f"ankle-rt ctl: parameter {text!r} is not KEY=VALUE")
    try:
        return key, float(value)
    except ValueError:
        pass
    if lists and "," in value:
        try:
            return key, [float(v) for v in value.split(",")]
        except ValueError:
            pass
    return key, value


def resolve_socket(args: argparse.Namespace) -> Path:
    """--socket, else service.socket_path of --config, else the automatic path."""
    return args.socket if args.socket is not None else socket_path_of(args.config)


def send(path: Path, request: dict, timeout: float) -> dict:
    """Send one request (``{"cmd": ..., fields}``) on a new connection; the reply as sent
    (``ok`` included, a refusal as ``{"ok": false, "error", "field"}``). Raises DaemonUnreachable."""
    with AnkleClient(path, timeout) as client:
        try:
            return {"ok": True, **client.request(**request)}
        except CommandError as exc:   # the daemon's refusal, or a field that cannot be sent (NaN)
            return {"ok": False, "error": exc.message, "field": exc.field}


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


# Angle fields of a status reply: wire name -> (name in degrees, name in rad, factor from the wire to
# degrees). The wire carries the ankle in degrees and the motors in rad.
STATUS_ANGLES = {"ankle_deg": ("ankle_deg", "ankle_rad", 1.0),
                 "reference_deg": ("reference_deg", "reference_rad", 1.0),
                 "motor_pos_rad": ("motor_pos_deg", "motor_pos_rad", 180.0 / math.pi),
                 "motor_vel_rad_s": ("motor_vel_deg_s", "motor_vel_rad_s", 180.0 / math.pi)}
TINY = 1e-9   # |value| printed as 0: far below any sensor's resolution (a decayed filter's 1e-84 is noise)


def status_for_people(status: dict, rad: bool = False) -> dict:
    """The status reply with every angle in degrees (``rad``: in rad), the names saying which; the
    gait phases' equilibria (rad on the wire) too."""
    out = {}
    for key, value in status.items():
        if key in STATUS_ANGLES and isinstance(value, list):
            deg_name, rad_name, to_deg = STATUS_ANGLES[key]
            scale = to_deg * (math.pi / 180.0 if rad else 1.0)
            key, value = (rad_name if rad else deg_name), [v * scale if isinstance(v, float) else v for v in value]
        elif key == "gait_phase" and isinstance(value, dict) and isinstance(value.get("params"), dict):
            value = {**value, **{part: {phase: _equilibria_for_people(params, rad) for phase, params in value[part].items()}
                                 for part in ("params", "waiting") if isinstance(value.get(part), dict)}}
        out[key] = value
    return out


def _equilibria_for_people(params: dict, rad: bool) -> dict:
    """One gait phase's parameters with its equilibrium angles named in deg (``rad``: in rad)."""
    out = {}
    for key, value in params.items():
        if key.startswith("equilibrium_") and isinstance(value, float):
            key, value = (f"{key}_rad", value) if rad else (f"{key}_deg", math.degrees(value))
        out[key] = value
    return out


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{0.0 if abs(value) < TINY else value:.6g}"
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
    if args.ctl_command == "gains" and not args.rad and field in EQUILIBRIA and getattr(args, field) is not None:
        given = getattr(args, field)
        return f" (the command line takes degrees: --{field.replace('_', '-')} {given:g} deg is {math.radians(given):.4g} rad)"
    return ""


def watch_view(status: dict, path: Path) -> list[str]:
    """The live view of one status reply (angles in degrees, SI otherwise, units named)."""
    def row(name: str, values, unit: str, scale: float = 1.0, fmt: str = "10.3f") -> str:
        cells = "".join(f"{'-':>10}" if v is None else f"{v * scale:{fmt}}" for v in values or ())
        return f"  {name:<18}{cells}  {unit}"

    deg = 180.0 / math.pi
    fault = status.get("fault") or "none"
    loop = status.get("loop") or {}
    pe = loop.get("period_error") or {}
    gains = status.get("gains") or {}
    gait = status.get("gait_phase")
    lines = [f"ankle-rt ctl watch  {path}  t = {_fmt(status.get('t'))} s   (Ctrl-C quits)",
             f"  state: {str(status.get('state', '?')).upper()}   fault: {fault}"
             + (f" ({status.get('fault_description')}, at t = {_fmt(status.get('fault_time_s'))} s)"
                if fault != "none" else ""),
             f"  {'':<18}{'DP':>10}{'IE':>10}",
             row("reference", status.get("reference_deg"), "deg"),
             row("ankle", status.get("ankle_deg"), "deg"),
             row("joint torque", status.get("sg_torque_nm"), "N m"),
             f"  {'':<18}{'motor 1':>10}{'motor 2':>10}",
             row("position", status.get("motor_pos_rad"), "deg", deg),
             row("velocity", status.get("motor_vel_rad_s"), "deg/s", deg, "10.1f"),
             row("current", status.get("current_a"), "A"),
             f"  controller: {status.get('controller', '-')}   gains: "
             + (", ".join(f"{k} {_fmt(v)}" for k, v in gains.items()) or "-"),
             *([f"  gait phase: {gait['phase']} for {_fmt(gait.get('time_in_phase_s'))} s"] if gait else []),
             f"  loop: {loop.get('cycles', '-')} cycles, {loop.get('overruns', '-')} overruns, period error p99 "
             f"{_fmt(pe.get('p99_us'))} us"]
    return lines


def watch(args: argparse.Namespace, path: Path) -> int:
    """Redraw the status until Ctrl-C, --count refreshes, or the daemon goes away."""
    import time

    tty = sys.stdout.isatty()
    shown = 0
    try:
        while True:
            try:
                status = send(path, {"cmd": "status"}, args.timeout)
            except DaemonUnreachable as exc:
                print(f"ankle-rt ctl: {exc}", file=sys.stderr)
                return EXIT_UNREACHABLE
            view = "\n".join(watch_view(status, path))
            print(("\x1b[H\x1b[2J" + view) if tty else view + "\n", flush=True)
            shown += 1
            if args.count and shown >= args.count:
                return 0
            time.sleep(max(args.interval, 0.05))
    except KeyboardInterrupt:
        return 0


def run(args: argparse.Namespace) -> int:
    path = resolve_socket(args)
    if args.ctl_command == "watch":
        return watch(args, path)
    try:
        reply = send(path, request_from_args(args), args.timeout)
    except DaemonUnreachable as exc:
        print(f"ankle-rt ctl: {exc}", file=sys.stderr)
        return EXIT_UNREACHABLE
    if args.json:
        print(json.dumps(reply))
    elif reply.get("ok"):
        body = {k: v for k, v in reply.items() if k != "ok"}
        if args.ctl_command == "status":
            body = status_for_people(body, args.rad)
        print("\n".join(format_fields(body)) if body else "ok")
    else:
        print(f"ankle-rt ctl: refused: field '{reply.get('field')}': {reply.get('error')}{_degree_note(args, reply)}",
              file=sys.stderr)
    return 0 if reply.get("ok") else EXIT_REFUSED
