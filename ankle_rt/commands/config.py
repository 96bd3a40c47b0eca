"""``ankle-rt config check FILE``: validate a configuration completely and print what it would run.

Checks everything ``ankle-rt run`` would check before the first cycle, without touching hardware:
the schema (every key, type and range, across includes), the controller (built-in or plugin, with
its parameters), the reference profile and the safety layer, and the backend's own configuration.
A hardware backend is configured against its in-process device emulator (the same one the
``bench-*.yaml`` configs use) instead of the serial port or CAN bus, so the ESCON maps, sensor
calibration, link or bus load and the bridge's answer to its CONFIG frame are all checked.

Exit code: 0 the config is valid; 2 it is not (the error names the file and the key); 1 the backend
could not be configured even against the emulator.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import sys
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("config", help="check a configuration file")
    sub = p.add_subparsers(dest="config_command", required=True, metavar="CMD")
    check = sub.add_parser("check", help="validate a config completely and print what it would run",
                           description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    check.add_argument("config", nargs="?", metavar="FILE", help="config file (default: the shipped config/sim.yaml)")
    check.set_defaults(handler=check_cmd)


def emulated(cfg):
    """A copy of ``cfg`` whose hardware backend talks to its in-process lockstep emulator."""
    out = cfg.deep_copy()
    if out["backend"] == "serial":
        out["serial"]["emulator"] = "lockstep"
    elif out["backend"] == "canopen":
        out["canopen"].update(emulator="lockstep", interface="virtual", channel="ankle-rt-config-check")
    return out


def describe(cfg) -> list[str]:
    """What the config would run, one fact per line."""
    from ankle_rt.references import angle_params
    from ankle_rt.service.protocol import GAIT_PHASES

    c, ref, loop, rt = cfg["controller"], cfg["reference"], cfg["loop"], cfg["loop"]["realtime"]
    backend = cfg["backend"]
    if backend == "serial":
        s = cfg["serial"]
        backend += (" (in-process lockstep emulator)" if s["emulator"] == "lockstep"
                    else f" on {s['port']} at {s['baudrate']} bit/s")
    elif backend == "canopen":
        co = cfg["canopen"]
        backend += (" (in-process lockstep emulator)" if co["emulator"] == "lockstep"
                    else f" on {co['interface']}:{co['channel']} at {co['bitrate']} bit/s, node {co['io_node_id']}")
    if c["type"] == "pd":
        gains = c[c["pd_gains"] + "_gains"]
        controller = f"pd, {c['pd_gains']}_gains kp {gains['kp']:g} N m/rad, kd {gains['kd']:g} N m s/rad"
    elif c["type"] == "impedance":
        controller = "impedance, " + ", ".join(f"{k} {v:g}" if isinstance(v, (int, float)) else f"{k} {v}"
                                             for k, v in c["impedance"].items())
    elif c["type"] == "gait_phase":
        g = c["gait_phase"]
        controller = "gait_phase, " + "; ".join(
            f"{p.replace('_', ' ')} K {g[p]['stiffness_dp']:g} B {g[p]['damping_dp']:g} theta_0 "
            f"{math.degrees(g[p]['equilibrium_dp']):.3g} deg" for p in GAIT_PHASES) + " (DP)"
    else:
        controller = f"{c['type']} (plugin), params {dict(c['params'])}"
    ff = c["friction_ff"]
    if ff["enabled"]:
        shaping = [f"x{ff['fraction']:g}" if ff["fraction"] < 1.0 else "",
                   f"fade {ff['fade_velocity']:g} rad/s" if ff["fade_velocity"] > 0.0 else "",
                   f"error band {ff['error_band']:g} N m" if ff["error_band"] > 0.0 else ""]
        controller += f"; friction feed-forward on ({', '.join([ff['model'], *filter(None, shaping)])})"
    profile = ref["profile"]
    angles = angle_params(profile)
    params = ", ".join(f"{k} {math.degrees(v):.3g} deg" if k in angles else f"{k} {v}"
                       for k, v in ref.get(profile, {}).items())
    amp, safety = cfg["amplifier"], cfg["safety"]
    log = cfg["logging"]
    service = cfg["service"]
    duration = loop["duration_s"]
    return [
        f"backend:     {backend}",
        f"loop:        {c['rate_hz']} Hz, {'until stopped' if not duration else f'{duration:g} s'}; real time: "
        f"SCHED_FIFO priority {rt['priority'] or 'off'}, cpus {rt['cpus'] or 'any'}, "
        f"memory locked {'yes' if rt['lock_memory'] else 'no'}",
        f"controller:  {controller}",
        f"reference:   {profile}" + (f" ({params})" if params else ""),
        f"safety:      ankle range +/-{cfg['limits']['ankle_range_deg']:g} deg, current peak "
        f"{amp['current_limit_peak']:g} A / continuous {amp['current_limit_continuous']:g} A, "
        f"{'activates itself after the tare' if safety['auto_activate'] else 'waits for ankle-rt ctl activate'}",
    ] + _torque_loop_lines(cfg) + [
        "logging:     " + (f"on, into {log['directory']}" if log["enabled"] else "off"),
        "service:     " + (_socket_line(cfg) if service["enabled"] else "no command socket"),
    ] + ([_lsl_line(cfg)] if cfg["lsl"]["enabled"] else [])


def _torque_loop_lines(cfg) -> list[str]:
    """The joint-torque loop under the impedance or gait-phase controller, its notches where the loop runs
    them: moved from the cable they are placed for (``notch_cable_stiffness``) to the configured one; its
    clamps, the set-value noise it makes of the gauges' noise, the least damping the impedance controller renders
    (passivity), per-axis torque filters, lags and motor-rate damping."""
    from ankle_rt.analysis import gain_set_loop, gain_set_noise_a
    from ankle_rt.config_schema import torque_loop_cutoffs
    from ankle_rt.gain_margin import MAX_NOISE_SHARE
    from ankle_rt.lag import Lag
    from ankle_rt.loop_setup import rate_from_encoders, torque_feedback
    from ankle_rt.notch import AXES, PREFIXES, Notch, cable_scale
    from ankle_rt.params import PlantParams
    from ankle_rt.passivity import least_rendered_damping

    c = cfg["controller"]
    if c["type"] not in ("impedance", "gait_phase") or not torque_feedback(cfg):
        return []
    tl, k = c["torque_loop"], cfg["transmission"]["cable_stiffness"]
    notches = "; ".join(
        f"{prefix} " + ", ".join(f"{a.upper()} {hz:.4g} Hz ({prefix}_hz_{a} {tl[f'{prefix}_hz_{a}']:g})" if hz > 0.0
                                 else f"{a.upper()} none" for a, hz in zip(AXES, notch.hz))
        for prefix, notch in zip(PREFIXES, Notch.all_from_config(tl, k)) if prefix == "notch" or any(notch.hz))
    lines = [f"torque loop: kp {tl['kp_dp']:g} / {tl['kp_ie']:g}; {notches}: placed for notch_cable_stiffness "
             f"{tl['notch_cable_stiffness']:g} N/m, x{cable_scale(tl, k):.4g} for transmission.cable_stiffness {k:g}",
             f"             max correction DP {tl['max_correction_dp']:g} / IE {tl['max_correction_ie']:g} N m; "
             f"sensor noise at rest {gain_set_noise_a(cfg, {})[0]:.2f} A RMS per motor (model; at most "
             f"{MAX_NOISE_SHARE * cfg['safety']['oscillation_rms_a']:.2f})",
             f"             torque rate from the {tl['torque_rate_source']}"
             + (f" (the gauges below DP {tl['torque_rate_crossover_hz_dp']:g} / IE {tl['torque_rate_crossover_hz_ie']:g} Hz)"
                if rate_from_encoders(tl) else "")]
    if c["type"] == "impedance":      # the gait phases' impedances are each checked when the controller is built
        least = least_rendered_damping(PlantParams.from_config(cfg), gain_set_loop(cfg, {}))
        lines.append("             least damping rendered DP {:+.3g} / IE {:+.3g} N m s/rad over cable x0.7-1.3 "
                     "(model; >= 0: passive)".format(*(a.damping for a in least)))
    lag, cutoffs = Lag.from_config(tl), torque_loop_cutoffs(tl)
    lags = ", ".join(f"{a.upper()} {hz:g} Hz x{b:g}" if on else f"{a.upper()} none"
                     for a, hz, b, on in zip(AXES, lag.hz, lag.boost, lag.on))
    lines.append(f"             torque filter DP {cutoffs[0]:g} / IE {cutoffs[1]:g} Hz; lag {lags}; motor-rate damping "
                 + ", ".join(f"{a.upper()} {tl[f'motor_rate_damping_{a}']:g} N m s/rad above "
                             f"{tl[f'motor_rate_damping_hz_{a}']:g} Hz" for a in AXES))
    return lines


def _lsl_line(cfg) -> str:
    """The Lab Streaming Layer streams, and whether pylsl is there to publish them."""
    from ankle_rt.log.lsl import EVENTS_NAME, STREAM_NAME, pylsl_available

    missing = "" if pylsl_available() else "; pylsl is NOT installed here: pip install 'ankle-rt[lab]'"
    return (f"lsl:         streams {STREAM_NAME} and {EVENTS_NAME} (source_id {cfg['lsl']['source_id']}) in real "
            f"time{missing}")


def _socket_line(cfg) -> str:
    """The socket this host resolves now; for ``auto`` also the service's, which systemd creates only
    at start (``config check`` runs before it, so the two differ in the deploy steps)."""
    from ankle_rt.service.link import SERVICE_RUNTIME_DIR, socket_path

    path = socket_path(cfg)
    service_path = SERVICE_RUNTIME_DIR / "control.sock"
    if cfg["service"]["socket_path"] != "auto" or path == service_path:
        return f"command socket {path}"
    return f"command socket {path} here; {service_path} under the systemd service (socket_path: auto)"


def check_cmd(args: argparse.Namespace) -> int:
    from ankle_rt.backend import BackendError
    from ankle_rt.clock import SimClock
    from ankle_rt.config import ConfigError, load_config
    from ankle_rt.daemon import Daemon
    from ankle_rt.paths import default_config_path

    path = Path(args.config) if args.config else default_config_path()
    try:
        cfg = load_config(path)
        with contextlib.redirect_stdout(io.StringIO()):   # the backends' start-up reports (bus load table)
            daemon = Daemon(emulated(cfg), SimClock())    # controller, reference, safety, backend configuration
        daemon.close()
    except ConfigError as exc:
        print(f"ankle-rt config check: {exc}", file=sys.stderr)
        print(f"{path}: INVALID", file=sys.stderr)
        return 2
    except BackendError as exc:
        print(f"ankle-rt config check: backend {cfg['backend']!r}: {exc}", file=sys.stderr)
        print(f"{path}: the backend cannot be configured", file=sys.stderr)
        return 1
    print(f"{path}: valid")
    print("\n".join("  " + line for line in describe(cfg)))
    if cfg["backend"] != "sim":
        print("  (checked against the device emulator; the device itself is checked when `ankle-rt run` opens it)")
    return 0
