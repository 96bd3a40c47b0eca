"""``ankle-rt bench loop``: timing of the daemon's real-time loop on the simulator, and the lockstep
speed of the whole stack; ``ankle-rt bench batch``: the batch simulator's aggregate speed (sweeps).
Prints figures; it asserts nothing (timing depends on the machine).

Real time: the configured daemon (section 7 experiment, logging on, as deployed) on the monotonic
clock for ``--duration`` s. Period error = |start-to-start period - nominal|; compute = cycle start
to cycle end (read, estimate, control, safety, write, log record; the simulated plant's step runs
inside read). A late cycle starts more than 2 periods after the previous one.
Lockstep: the same daemon on a SimClock; real-time factor = simulated s / wall-clock s.
"""

from __future__ import annotations

import argparse
from pathlib import Path

BATCH_GOAL = 1000.0   # aggregate real-time factor of 256 nominal plants under PD (issue 14)
GOALS = {"late_cycles": 0, "period_error_p99_us": 100.0, "compute_p99_us": 250.0, "lockstep_realtime_factor": 20.0}


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("bench", help="benchmarks (loop timing on the simulator)")
    sub = p.add_subparsers(dest="bench_command", required=True, metavar="WHAT")
    loop = sub.add_parser("loop", help="period jitter and compute time of the real-time loop, lockstep speed",
                          description=__doc__.split("\n\n", 1)[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    loop.add_argument("--config", metavar="FILE", help="configuration (default: the shipped config/sim.yaml)")
    loop.add_argument("--duration", type=float, default=60.0, metavar="S", help="real-time run length (default 60 s)")
    loop.add_argument("--lockstep", type=float, default=20.0, metavar="S",
                      help="simulated seconds for the lockstep speed (default 20)")
    loop.add_argument("--priority", type=int, metavar="N",
                      help="SCHED_FIFO priority for the loop (default: loop.realtime.priority of the config)")
    loop.add_argument("--json", action="store_true", help="print one JSON object")
    loop.set_defaults(handler=bench_loop)
    batch = sub.add_parser("batch", help="aggregate speed of the batch simulator (sweeps) by batch size",
                           description="Runs the configured experiment (default: the section 7 step under PD) "
                                       "as batches of identical plants through the batched daemon cycle "
                                       "(ankle_rt.sweep.cycle). Real-time factor = simulated s x plants / wall s.")
    batch.add_argument("--config", metavar="FILE", help="configuration (default: the shipped config/sim.yaml)")
    batch.add_argument("--seconds", type=float, default=5.0, metavar="S", help="simulated seconds per run (default 5)")
    batch.add_argument("--sizes", default="1,16,256", metavar="N,N,...", help="batch sizes (default 1,16,256)")
    batch.add_argument("--json", action="store_true", help="print one JSON object")
    batch.set_defaults(handler=bench_batch)


def realtime_run(cfg, duration_s: float, log_dir: Path) -> tuple[dict, list[str]]:
    """Run the configured daemon in real time; return its loop statistics and the OS-setting notes."""
    from ankle_rt.clock import MonotonicClock
    from ankle_rt.daemon import Daemon
    from ankle_rt.realtime import apply_realtime

    rt = cfg["loop"]["realtime"]
    notes = apply_realtime(rt)
    daemon = Daemon(cfg, MonotonicClock(spin_ns=rt["spin_us"] * 1000))
    daemon.open_log(log_dir / "bench.arlog")
    try:
        daemon.run(duration_s)
    finally:
        daemon.close()
    stats = daemon.loop.stats
    if daemon.recorder.dropped:
        notes.append(f"log records dropped: {daemon.recorder.dropped}")
    return stats.summary(), notes


def lockstep_speed(cfg, sim_s: float) -> float:
    import time

    from ankle_rt.daemon import run_lockstep

    t0 = time.perf_counter()
    run_lockstep(cfg, sim_s)
    return sim_s / (time.perf_counter() - t0)


def bench_loop(args: argparse.Namespace) -> int:
    import tempfile

    from ankle_rt.commands import jsonout

    from ankle_rt.config import load_config
    from ankle_rt.paths import default_config_path

    cfg = load_config(Path(args.config) if args.config else default_config_path())
    cfg["loop"]["duration_s"] = args.duration
    if args.priority is not None:
        cfg["loop"]["realtime"]["priority"] = args.priority
    rate = cfg["controller"]["rate_hz"]
    if not args.json:
        print(f"lockstep: {args.lockstep:g} simulated s ...", flush=True)
    rtf = lockstep_speed(cfg, args.lockstep)
    if not args.json:
        print(f"real time: {args.duration:g} s at {rate} Hz on the simulator ...", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        stats, notes = realtime_run(cfg, args.duration, Path(tmp))
    pe, cp = stats["period_error"], stats["compute"]
    result = {
        "rate_hz": rate, "duration_s": args.duration, "cycles": stats["cycles"],
        "period_error_p50_us": pe["p50_us"], "period_error_p99_us": pe["p99_us"],
        "period_error_p999_us": pe["p99.9_us"], "period_error_max_us": pe["max_us"],
        "compute_p50_us": cp["p50_us"], "compute_p99_us": cp["p99_us"], "compute_p999_us": cp["p99.9_us"],
        "compute_max_us": cp["max_us"],
        "late_cycles": stats["late_cycles"], "overruns": stats["overruns"], "skipped_cycles": stats["skipped_cycles"],
        "lockstep_realtime_factor": rtf, "lockstep_sim_s": args.lockstep,
        "os_settings": notes,
    }
    met = {
        "late_cycles": result["late_cycles"] <= GOALS["late_cycles"],
        "period_error_p99_us": result["period_error_p99_us"] <= GOALS["period_error_p99_us"],
        "compute_p99_us": result["compute_p99_us"] <= GOALS["compute_p99_us"],
        "lockstep_realtime_factor": result["lockstep_realtime_factor"] >= GOALS["lockstep_realtime_factor"],
    }
    result["goals_met"] = met
    if args.json:
        print(jsonout.dumps(result))
        return 0
    ok = {True: "ok", False: "MISSED"}
    print(f"loop at {rate} Hz, {result['cycles']} cycles in {args.duration:g} s "
          f"({', '.join(notes) if notes else 'default OS settings'})")
    print(f"  period error p50/p99/p99.9/max: {pe['p50_us']:.0f} / {pe['p99_us']:.0f} / {pe['p99.9_us']:.0f} / "
          f"{pe['max_us']:.0f} us   (goal p99 <= 100 us: {ok[met['period_error_p99_us']]})")
    print(f"  compute p50/p99/p99.9/max:      {cp['p50_us']:.0f} / {cp['p99_us']:.0f} / {cp['p99.9_us']:.0f} / "
          f"{cp['max_us']:.0f} us   (goal p99 <= 250 us: {ok[met['compute_p99_us']]})")
    print(f"  late cycles (> 2 periods): {result['late_cycles']} (goal 0: {ok[met['late_cycles']]}), "
          f"overruns {result['overruns']}, skipped deadlines {result['skipped_cycles']}")
    print(f"lockstep (daemon + simulated plant): {rtf:.1f}x real time "
          f"(goal >= 20x: {ok[met['lockstep_realtime_factor']]})")
    return 0


def batch_speed(cfg, plants: int, sim_s: float) -> float:
    """Aggregate real-time factor of ``plants`` copies of ``cfg`` run as one batch (build excluded)."""
    import time

    from ankle_rt.sweep.cycle import BatchRun

    run = BatchRun([cfg] * plants, sim_s, getattr(cfg, "source", "config"))
    t0 = time.perf_counter()
    run.run()
    return sim_s * plants / (time.perf_counter() - t0)


def bench_batch(args: argparse.Namespace) -> int:
    import json
    import sys

    from ankle_rt.config import load_config
    from ankle_rt.paths import default_config_path

    cfg = load_config(Path(args.config) if args.config else default_config_path())
    try:
        sizes = [int(s) for s in args.sizes.split(",")]
        if not sizes or min(sizes) < 1:
            raise ValueError
    except ValueError:
        print(f"ankle-rt bench batch: --sizes must be positive integers separated by commas, got {args.sizes!r}",
              file=sys.stderr)
        return 2
    factors = {}
    for n in sizes:
        if not args.json:
            print(f"batch of {n}: {args.seconds:g} simulated s each ...", flush=True)
        factors[str(n)] = batch_speed(cfg, n, args.seconds)
    result = {"realtime_factor_by_batch": factors, "sim_s": args.seconds, "controller": cfg["controller"]["type"],
              "goal_256": BATCH_GOAL}
    if "256" in factors:
        result["goal_met"] = factors["256"] >= BATCH_GOAL
    if args.json:
        print(json.dumps(result))
        return 0
    for n, f in factors.items():
        print(f"  {n:>5} plants: {f:8.0f}x real time in aggregate ({f / int(n):.1f}x per plant)")
    if "256" in factors:
        print(f"goal >= {BATCH_GOAL:g}x at 256 plants: {'ok' if result['goal_met'] else 'MISSED'}")
    return 0
