"""``ankle-rt run``: the control daemon in the foreground.

Real time by default (the monotonic clock, real-time settings from ``loop.realtime``, the command
socket and systemd notification); ``--fast`` runs the same loop in lockstep on a simulated clock.
SIGINT/SIGTERM (or the ``stop`` command) put the device in the safe state first, then the log is
flushed and a summary printed. With the default config/sim.yaml it reproduces the paper's section 7.

Exit code: 0 the run ended normally; 1 it ended in FAULT (the fault is named on stderr) or could not
start (backend, log, socket); 2 bad configuration or arguments.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("run", help="run the control daemon (default: the paper's section 7 on the simulator)",
                              description="Run the control daemon in the foreground until loop.duration_s has "
                                          "passed or SIGINT/SIGTERM/stop arrives; then print a summary.")
    p.add_argument("--config", metavar="FILE", help="configuration (default: the shipped config/sim.yaml)")
    p.add_argument("--duration", type=float, metavar="S", help="s to run (default: loop.duration_s; 0 = until stopped)")
    p.add_argument("--fast", action="store_true", help="lockstep on a simulated clock, as fast as possible")
    p.add_argument("--log", metavar="PATH", help="run log file (default: a timestamped name in logging.directory)")
    p.add_argument("--no-log", action="store_true", help="do not write a run log")
    p.add_argument("--socket", metavar="PATH", help="command socket (default: service.socket_path)")
    p.add_argument("--no-plot", action="store_true", help="skip the Figs 13-15 style plot next to the log")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(handler=run)


def default_log_path(directory: str) -> Path:
    return Path(directory) / time.strftime("run-%Y%m%d-%H%M%S.arlog")


def run(args: argparse.Namespace) -> int:
    import signal

    from ankle_rt.backend import BackendError
    from ankle_rt import jsonout
    from ankle_rt.clock import MonotonicClock, SimClock
    from ankle_rt.config import ConfigError, load_config
    from ankle_rt.daemon import Daemon
    from ankle_rt.log.reader import read_tail
    from ankle_rt.log.summary import SUMMARY_MAX_RECORDS, format_summary, plot_run, summarize_log
    from ankle_rt.paths import default_config_path
    from ankle_rt.progress import Progress
    from ankle_rt.realtime import apply_realtime

    config_path = Path(args.config) if args.config else default_config_path()
    cfg = load_config(config_path)
    duration = cfg["loop"]["duration_s"] if args.duration is None else args.duration
    if duration < 0:
        print("ankle-rt run: --duration must be >= 0", file=sys.stderr)
        return 2
    rt = cfg["loop"]["realtime"]
    clock = SimClock() if args.fast else MonotonicClock(spin_ns=rt["spin_us"] * 1000)
    if args.fast and duration == 0:
        print("ankle-rt run: --fast needs a duration (lockstep would never end)", file=sys.stderr)
        return 2
    notes = [] if args.fast else apply_realtime(rt)
    try:
        daemon = Daemon(cfg, clock)
    except BackendError as exc:
        print(f"ankle-rt run: backend {cfg['backend']!r} could not be opened: {exc}", file=sys.stderr)
        return 1
    log_path = None
    if cfg["logging"]["enabled"] and not args.no_log:
        log_path = Path(args.log) if args.log else default_log_path(cfg["logging"]["directory"])
        try:   # retention counts every default-named log of the directory, or a --log file's own parts
            daemon.open_log(log_path, "" if args.log else "run-*.arlog")
        except OSError as exc:
            daemon.close()
            print(f"ankle-rt run: cannot write the log {log_path}: {exc.strerror or exc}", file=sys.stderr)
            return 1
        except ConfigError:   # lsl.enabled without pylsl
            daemon.close()
            raise
    if daemon.lsl is not None:
        from ankle_rt.log.lsl import EVENTS_NAME, STREAM_NAME

        notes.append(f"lab streaming layer: streams '{STREAM_NAME}' and '{EVENTS_NAME}' (docs/lab.md)")
    elif cfg["lsl"]["enabled"]:
        notes.append("lab streaming layer: off " + ("in lockstep (--fast)" if args.fast else "(--no-log: it publishes "
                                                   "from the log writer)"))
    if not args.fast and cfg["service"]["enabled"]:
        from ankle_rt.service.link import ServiceLink
        from ankle_rt.service.server import ServiceError
        try:
            daemon.service = ServiceLink(cfg, daemon.handle, path=args.socket)
        except ServiceError as exc:
            daemon.close()
            print(f"ankle-rt run: {exc}", file=sys.stderr)
            return 1
        notes.append(f"command socket: {daemon.service.path}")

    def stop(signum, _frame):
        # Only flag it: the handler may run in the middle of a backend transaction. The loop ends
        # after the current cycle (< 1 period), and Daemon.run then deactivates before anything else.
        daemon.loop.stop()

    old = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    mode = "lockstep (--fast)" if args.fast else "real time"
    print(f"ankle-rt run: {config_path}, backend {cfg['backend']}, controller {cfg['controller']['type']}, "
          f"{cfg['controller']['rate_hz']} Hz, {mode}, "
          f"{'until stopped' if not duration else f'{duration:g} s'}; log: {log_path or 'off'}", flush=True)
    for note in notes:
        print(f"  {note}", flush=True)
    error = None
    try:
        if daemon.service is not None:
            daemon.service.ready(f"running {cfg['backend']} at {cfg['controller']['rate_hz']} Hz")
        try:
            if args.fast:   # lockstep only: a real-time loop gets no extra thread
                with Progress("run --fast", duration, poll=lambda: daemon.est.t):
                    daemon.run(duration)
            else:
                daemon.run(duration or None)
        except Exception as exc:   # e.g. a plugin controller's update raised: run() went safe (amplifiers off)
            error = f"{type(exc).__name__}: {exc}"
    finally:
        if daemon.service is not None:
            daemon.service.stopping()
        daemon.close()
        for s, h in old.items():
            signal.signal(s, h)
    if daemon.lsl is not None and daemon.lsl.error:
        print(f"WARNING: lab streaming layer stopped: {daemon.lsl.error}", file=sys.stderr)
    if error:
        print(f"ankle-rt run: the cycle raised {error}; the run ended in the safe state (amplifiers off)",
              file=sys.stderr)
    if log_path is None:
        print(f"stopped after {daemon.loop.stats.cycles} cycles (no log written)")
        return 1 if error else _exit_code(daemon)
    # Only the most recent records: a run of days must not load gigabytes after the safe state
    # (systemd's stop timeout, mlockall). The whole run's loop timing is in the live histograms.
    # With rotation, the last part (and the one before) hold the most recent records.
    log_path = daemon.recorder.path
    run_log = read_tail(log_path, SUMMARY_MAX_RECORDS)
    records = run_log.records
    summary = summarize_log(run_log)
    summary["log"] = str(log_path)
    summary["log_status"] = daemon.recorder.status()
    summary["loop_stats"] = daemon.loop.stats.summary()
    if daemon.recorder.dropped:
        summary["log_records_dropped"] = daemon.recorder.dropped
        print(f"WARNING: {daemon.recorder.dropped} log records were lost ({daemon.recorder.error or 'disk too slow'})",
              file=sys.stderr)
    if daemon.recorder.failed:
        print(f"WARNING: logging stopped: {daemon.recorder.error}", file=sys.stderr)
    plot_note = None
    if not args.no_plot and len(records):
        plot_note = plot_run(records, daemon.kt, str(log_path.with_suffix(".png")),
                             f"{config_path.name}: {cfg['backend']}, controller {cfg['controller']['type']}, reference "
                             f"{cfg['reference']['profile']}, {mode}")
    if args.json:
        print(jsonout.dumps(summary, indent=2))
    else:
        print(format_summary(summary))
        if not args.fast:
            st = summary["loop_stats"]
            scope = "loop, whole run" if "window" in summary else "loop"
            print(f"{scope} (live histograms): period error p99 {st['period_error']['p99_us']:.0f} us, "
                  f"compute p99 {st['compute']['p99_us']:.0f} us, max {st['compute']['max_us']:.0f} us")
        print(f"log: {log_path}  (ankle-rt log info / ankle-rt log export {log_path} --csv OUT.csv)")
        if plot_note:
            print(plot_note)
    return 1 if error else _exit_code(daemon)


def _exit_code(daemon) -> int:
    """1 (and the fault on stderr) when the run ended in FAULT, else 0."""
    from ankle_rt.safety import Fault, State

    safety = daemon.safety
    if safety.state != State.FAULT:
        return 0
    fault = Fault(safety.fault)
    print(f"ankle-rt run: ended in FAULT at t = {safety.fault_time:.3f} s: {fault.name} ({fault.description})",
          file=sys.stderr)
    limits = daemon.overrun_limits
    if fault == Fault.MISSED_DEADLINES and limits is daemon.cfg["sim"]:   # the simulated plant's limits tripped
        print(MISSED_DEADLINES_HINT.format(stall_s=limits["max_stall_s"], overruns=limits["max_consecutive_overruns"]),
              file=sys.stderr)
    return 1


# What to do when a simulated run in real time faults because the machine was busy. The hardware's
# limits (loop.*) are not involved: a run with a simulated plant uses sim.* (Daemon.overrun_limits).
MISSED_DEADLINES_HINT = """hint: the loop stalled (a busy machine, not the simulated device). To run the simulation anyway:
  ankle-rt run --fast ...        the same loop in lockstep on a simulated clock (no deadlines to miss, same results)
  loop.realtime.priority: 50     SCHED_FIFO for the loop (needs CAP_SYS_NICE or LimitRTPRIO; docs/service.md)
  sim.max_stall_s / sim.max_consecutive_overruns (now {stall_s:g} s / {overruns})  more tolerance for a simulated
                                 plant only; the prosthesis keeps loop.max_stall_s / loop.max_consecutive_overruns"""
