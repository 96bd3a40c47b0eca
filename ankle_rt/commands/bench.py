"""``ankle-rt bench loop``: timing of the daemon's real-time loop on the simulator, the lockstep
speed of the whole stack and the daemon's own compute; ``ankle-rt bench batch``: the batch
simulator's aggregate speed (sweeps). Prints figures; it asserts nothing (timing depends on the
machine). Every time is also given in reference steps (``*_ref_steps``): units of a fixed plain-
Python RK4 step of the cable model timed in the same run (ankle_rt.timing_reference), which
travel between machines.

Real time: the configured daemon (section 7 experiment, logging on, as deployed) on the monotonic
clock for ``--duration`` s. Period error = |start-to-start period - nominal|; compute = cycle start
to cycle end (read, estimate, control, safety, write, log record; the simulated plant's step runs
inside read). A late cycle starts more than 2 periods after the previous one.
Lockstep: the same daemon on a SimClock; real-time factor = simulated s / wall-clock s; lockstep
cycle = wall time per cycle (daemon + plant), the median over slices of 50 cycles.
Daemon cycle: the daemon alone (what the prosthesis computer pays), on sensor frames recorded from
the lockstep run and replayed by a backend whose read and write cost nothing (ankle_rt.bench.replay).
"""

from __future__ import annotations

import argparse
from pathlib import Path

BATCH_GOAL = 1000.0   # aggregate real-time factor of 256 nominal plants under PD (issue 14)
GOALS = {"late_cycles": 0, "period_error_p99_us": 100.0, "compute_p99_us": 250.0, "lockstep_realtime_factor": 30.0,   # lockstep: issue 14
         "lockstep_cycle_ref_steps": 3.0, "daemon_cycle_ref_steps": 1.5}   # issue 18, measured alone on an idle machine


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
    register_impedance(sub)
    register_walk(sub)


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

    from ankle_rt import jsonout
    from ankle_rt.bench.replay import daemon_cycle_s, lockstep_cycle_s
    from ankle_rt.config import load_config
    from ankle_rt.paths import default_config_path
    from ankle_rt.timing_reference import reference_step_s

    cfg = load_config(Path(args.config) if args.config else default_config_path())
    cfg["loop"]["duration_s"] = args.duration
    if args.priority is not None:
        cfg["loop"]["realtime"]["priority"] = args.priority
    rate = cfg["controller"]["rate_hz"]
    if not args.json:
        print(f"lockstep: {args.lockstep:g} simulated s, then the daemon alone on replayed frames ...", flush=True)
    ref_s = reference_step_s()
    rtf = lockstep_speed(cfg, args.lockstep)
    slices_s = min(args.lockstep, 5.0)
    lockstep_s = lockstep_cycle_s(cfg, slices_s)
    daemon_s = daemon_cycle_s(cfg, slices_s)
    if not args.json:
        print(f"real time: {args.duration:g} s at {rate} Hz on the simulator ...", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        stats, notes = realtime_run(cfg, args.duration, Path(tmp))
    ref_s = 0.5 * (ref_s + reference_step_s())    # before and after: the machine's load may change
    ref_us = ref_s * 1e6
    pe, cp = stats["period_error"], stats["compute"]
    result = {
        "rate_hz": rate, "duration_s": args.duration, "cycles": stats["cycles"],
        "period_error_p50_us": pe["p50_us"], "period_error_p99_us": pe["p99_us"],
        "period_error_p999_us": pe["p99.9_us"], "period_error_max_us": pe["max_us"],
        "compute_p50_us": cp["p50_us"], "compute_p99_us": cp["p99_us"], "compute_p999_us": cp["p99.9_us"],
        "compute_max_us": cp["max_us"],
        "late_cycles": stats["late_cycles"], "overruns": stats["overruns"], "skipped_cycles": stats["skipped_cycles"],
        "lockstep_realtime_factor": rtf, "lockstep_sim_s": args.lockstep,
        "lockstep_cycle_us": lockstep_s * 1e6, "daemon_cycle_us": daemon_s * 1e6,
        "reference_step_us": ref_us,
        "compute_p50_ref_steps": cp["p50_us"] / ref_us, "compute_p99_ref_steps": cp["p99_us"] / ref_us,
        "compute_p999_ref_steps": cp["p99.9_us"] / ref_us, "compute_max_ref_steps": cp["max_us"] / ref_us,
        "lockstep_cycle_ref_steps": lockstep_s / ref_s, "daemon_cycle_ref_steps": daemon_s / ref_s,
        "os_settings": notes,
    }
    met = {
        "late_cycles": result["late_cycles"] <= GOALS["late_cycles"],
        "period_error_p99_us": result["period_error_p99_us"] <= GOALS["period_error_p99_us"],
        "compute_p99_us": result["compute_p99_us"] <= GOALS["compute_p99_us"],
        "lockstep_realtime_factor": result["lockstep_realtime_factor"] >= GOALS["lockstep_realtime_factor"],
        "lockstep_cycle_ref_steps": result["lockstep_cycle_ref_steps"] <= GOALS["lockstep_cycle_ref_steps"],
        "daemon_cycle_ref_steps": result["daemon_cycle_ref_steps"] <= GOALS["daemon_cycle_ref_steps"],
    }
    result["goals_met"] = met
    if args.json:
        print(jsonout.dumps(result))
        return 0
    ok = {True: "ok", False: "MISSED"}
    r = lambda us: f"{us / ref_us:.2f}"  # noqa: E731
    print(f"loop at {rate} Hz, {result['cycles']} cycles in {args.duration:g} s "
          f"({', '.join(notes) if notes else 'default OS settings'}); reference step {ref_us:.1f} us")
    print(f"  period error p50/p99/p99.9/max: {pe['p50_us']:.0f} / {pe['p99_us']:.0f} / {pe['p99.9_us']:.0f} / "
          f"{pe['max_us']:.0f} us   (goal p99 <= 100 us: {ok[met['period_error_p99_us']]})")
    print(f"  compute p50/p99/p99.9/max:      {cp['p50_us']:.0f} / {cp['p99_us']:.0f} / {cp['p99.9_us']:.0f} / "
          f"{cp['max_us']:.0f} us   (goal p99 <= 250 us: {ok[met['compute_p99_us']]})")
    print(f"                    in ref steps: {r(cp['p50_us'])} / {r(cp['p99_us'])} / {r(cp['p99.9_us'])} / "
          f"{r(cp['max_us'])}")
    print(f"  late cycles (> 2 periods): {result['late_cycles']} (goal 0: {ok[met['late_cycles']]}), "
          f"overruns {result['overruns']}, skipped deadlines {result['skipped_cycles']}")
    print(f"lockstep (daemon + simulated plant): {rtf:.1f}x real time "
          f"(goal >= {GOALS['lockstep_realtime_factor']:g}x: {ok[met['lockstep_realtime_factor']]}), "
          f"{lockstep_s * 1e6:.1f} us = {result['lockstep_cycle_ref_steps']:.2f} ref steps per cycle "
          f"(goal <= {GOALS['lockstep_cycle_ref_steps']:g}: {ok[met['lockstep_cycle_ref_steps']]})")
    print(f"daemon alone (replayed frames): {daemon_s * 1e6:.1f} us = {result['daemon_cycle_ref_steps']:.2f} ref steps "
          f"per cycle (goal <= {GOALS['daemon_cycle_ref_steps']:g}: {ok[met['daemon_cycle_ref_steps']]})")
    return 0


MAX_BATCH = 65536
"""Largest batch ``bench batch`` runs (plants; about 100 MB of state and buffers): beyond it a typo
would exhaust memory instead of measuring anything."""


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
    from ankle_rt.timing_reference import reference_step_s

    cfg = load_config(Path(args.config) if args.config else default_config_path())
    try:
        sizes = [int(s) for s in args.sizes.split(",")]
        if not sizes or min(sizes) < 1 or max(sizes) > MAX_BATCH:
            raise ValueError
    except ValueError:
        print(f"ankle-rt bench batch: --sizes must be integers from 1 to {MAX_BATCH} separated by commas, "
              f"got {args.sizes!r}",
              file=sys.stderr)
        return 2
    ref_s = reference_step_s()
    factors = {}
    for n in sizes:
        if not args.json:
            print(f"batch of {n}: {args.seconds:g} simulated s each ...", flush=True)
        factors[str(n)] = batch_speed(cfg, n, args.seconds)
    ref_s = 0.5 * (ref_s + reference_step_s())
    dt = 1.0 / cfg["controller"]["rate_hz"]
    # wall s per tick and plant = dt / aggregate real-time factor
    per_plant = {n: dt / f / ref_s for n, f in factors.items()}
    result = {"realtime_factor_by_batch": factors, "plant_cycle_ref_steps_by_batch": per_plant,
              "reference_step_us": ref_s * 1e6, "sim_s": args.seconds, "controller": cfg["controller"]["type"],
              "goal_256": BATCH_GOAL}
    if "256" in factors:
        result["plant_cycle_ref_steps"] = per_plant["256"]
        result["goal_met"] = factors["256"] >= BATCH_GOAL
    if args.json:
        print(json.dumps(result))
        return 0
    print(f"reference step {ref_s * 1e6:.1f} us (ankle_rt.timing_reference)")
    for n, f in factors.items():
        print(f"  {n:>5} plants: {f:8.0f}x real time in aggregate ({f / int(n):.1f}x per plant), "
              f"{per_plant[n]:.3f} ref steps per plant and cycle")
    if "256" in factors:
        print(f"goal >= {BATCH_GOAL:g}x at 256 plants: {'ok' if result['goal_met'] else 'MISSED'}")


# -- ankle-rt bench impedance -----------------------------------------------------------------------
IMPEDANCE_DOC = """Rendered ankle impedance on the simulator (lockstep, simulated clock): the configured impedance
controller (joint-torque feedback when strain gauges are configured) against open loop, for each
commanded DP stiffness (IE: half unless --stiffness-ie). Per axis: static torque pulses of +-1 to
+-12 N m (secant stiffness at the pulse end), sinusoidal torques of 6 and 15 N m DP (3 and 7.5 IE) at
0.5-5 Hz (dynamic stiffness Re Z and damping Im Z / w judged up to 2 Hz, apparent inertia from 5 Hz,
hysteresis = energy dissipated per cycle beyond the commanded damping's, passive = no cycle returns
net energy to the foot), a 6 N m DP / 3 N m IE torque step with the foot on rigid and on soft ground
(overshoot of the strain-gauge torque), and the stability margin of the sampled loop from the linear model (ZOH + one cycle of
delay) over cable stiffness +/-30 %, viscous friction x0.5-x2, load-dependent friction sliding with
or against the load, foot free or held. The plant: the config's effects plus --load-friction and
--stribeck (defaults: load-dependent 0.12, Stribeck 0.15 N m at 0.1 rad/s). Both controllers compensate the
plant's identified friction (--friction-ff, default identified: the plant's own friction model, the workflow
identify -> compensate; --plant-friction runs a plant with more or less friction than the model states)."""

SUMMARY_KEYS = ("stiffness_error_max_pct", "dynamic_stiffness_error_max_pct", "damping_error_max_pct",
                "torque_step_overshoot_pct", "torque_step_ideal_overshoot_pct", "torque_step_excess_pct",
                "apparent_inertia_kg_m2", "passive", "hysteresis_j_per_cycle",
                "stability_margin_db", "torque_tracking_rms_nm", "current_noise_a")
WORST = {"stiffness_error_max_pct": max, "dynamic_stiffness_error_max_pct": max, "damping_error_max_pct": max,
         "torque_step_overshoot_pct": max, "torque_step_ideal_overshoot_pct": max, "torque_step_excess_pct": max,
         "apparent_inertia_kg_m2": max, "passive": all,
         "hysteresis_j_per_cycle": max, "torque_tracking_rms_nm": max, "current_noise_a": max}


def _number(low: float, strict: bool):
    """argparse type: a finite float >= low (> low when ``strict``)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not (value > low if strict else value >= low) or value == float("inf"):
            raise argparse.ArgumentTypeError(f"must be {'>' if strict else '>='} {low:g} and finite, got {text}")
        return value
    return parse


def register_impedance(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("impedance", help="rendered stiffness, damping and hysteresis of the impedance controller",
                       description=IMPEDANCE_DOC, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", metavar="FILE", help="configuration (default: the shipped config/sim.yaml)")
    p.add_argument("--stiffness", type=_number(0.0, True), nargs="+", default=[50.0, 200.0], metavar="K",
                   help="commanded DP stiffness(es), N m/rad (default 50 200)")
    p.add_argument("--stiffness-ie", type=_number(0.0, True), metavar="K", help="IE stiffness, N m/rad (default: half of DP)")
    p.add_argument("--damping", type=_number(0.0, False), nargs=2, default=[0.5, 0.25], metavar=("B_DP", "B_IE"),
                   help="commanded damping, N m s/rad (default 0.5 0.25)")
    p.add_argument("--load-friction", type=_number(0.0, False), default=0.12, metavar="MU",
                   help="load-dependent cable friction coefficient in the plant (0: off; default 0.12)")
    p.add_argument("--stribeck", type=_number(0.0, False), nargs=2, default=[0.15, 0.1], metavar=("A", "VS"),
                   help="Stribeck excess N m and velocity rad/s in the plant (A 0: off; default 0.15 0.1)")
    p.add_argument("--friction-ff", choices=("off", "coulomb_viscous", "identified"), default="identified",
                   help="friction feed-forward of both controllers (default identified: the plant's own friction model, "
                        "what `ankle-rt identify` gives a device; off: the loop alone)")
    p.add_argument("--plant-friction", type=_number(0.0, True), default=1.0, metavar="S",
                   help="the simulated plant's Coulomb, Stribeck, asymmetric and load-dependent friction x S, the "
                        "controllers' friction model (the feed-forward's) kept: does compensation go active on a "
                        "device with less friction than stated (default 1)")
    p.add_argument("--friction-study", action="store_true",
                   help="also run both controllers with each friction feed-forward (what the identified model buys)")
    p.add_argument("--quick", action="store_true", help="fewer pulses and sines (a smoke run)")
    p.add_argument("--plot", metavar="PNG", nargs="?", const="impedance-bench.png",
                   help="save the torque-angle loops against the commanded line (PNG default impedance-bench.png; "
                        "needs matplotlib)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=bench_impedance)


def plant_effects(load_friction: float, stribeck: tuple[float, float]) -> list[dict]:
    """The ``sim.effects`` entries of the bench's plant options."""
    effects: list[dict] = []
    if load_friction > 0.0:
        effects.append({"type": "load_dependent_friction", "coefficient": load_friction})
    if stribeck[0] > 0.0:
        effects.append({"type": "stribeck", "static_excess": stribeck[0], "stribeck_velocity": stribeck[1]})
    return effects


def impedance_variant(cfg, stiffness: list[float], stiffness_ie: float | None, damping: tuple[float, float],
                      effects: list[dict], *, feedback: str, friction_ff: str | None, experiment,
                      keep_loops: bool = False, plant_friction: float = 1.0) -> dict:
    """Run the bench for one controller variant over the commanded stiffnesses; its summary and runs.
    ``plant_friction``: the simulated plant's Coulomb-like friction x this (the controller's model kept)."""
    from ankle_rt.analysis import ImpedanceLoop, torque_loop_margins
    from ankle_rt.loop_setup import torque_feedback
    from ankle_rt.bench.impedance import bench_config, run_impedance, with_plant_friction
    from ankle_rt.params import PlantParams

    runs, margins = [], []
    for k in stiffness:
        c = bench_config(cfg, stiffness=(k, k / 2.0 if stiffness_ie is None else stiffness_ie), damping=damping,
                         torque_feedback=feedback, friction_ff=friction_ff, effects=effects)
        closed = torque_feedback(c)
        plant = None if plant_friction == 1.0 else with_plant_friction(c, plant_friction)
        res = run_impedance(c, experiment, keep_loops=keep_loops, plant_cfg=plant)
        mu = max([e["coefficient"] for e in c["sim"]["effects"] if e["type"] == "load_dependent_friction"] or [0.0])
        cases = torque_loop_margins(PlantParams.from_config(c), ImpedanceLoop.from_config(c, closed=closed),
                                    load_coefficient=mu)
        worst = min(cases, key=lambda m: m.gain_margin_db)
        margins.append(worst.gain_margin_db)
        runs.append({**res.to_json(), "stability_margin_db": worst.gain_margin_db, "worst_margin_case": worst.to_json(),
                     "_result": res})
    summary = {"torque_feedback": closed, "friction_ff": friction_ff or "off",
               **{key: worst(r[key] for r in runs) for key, worst in WORST.items()},
               "stability_margin_db": min(margins),
               "faults": sorted({r["fault"] for r in runs} | {s["fault"] for r in runs for s in r["steps"]})}
    return {"summary": summary, "runs": runs}


def plot_loops(variants: dict[str, dict], png: str) -> str:
    """Torque-angle loops of the first commanded stiffness, one panel per axis and frequency, each
    variant against the commanded line tau = K theta. Returns a note."""
    from ankle_rt.plotting import MISSING, pyplot

    plt = pyplot()
    if plt is None:
        return f"plot skipped: {MISSING}"
    import numpy as np

    first = next(iter(variants.values()))["runs"][0]["_result"]
    keys = [(lp["axis"], lp["freq_hz"], lp["amplitude_nm"]) for lp in first.loops]
    cols = max(1, len({f for _, f, _ in keys}))
    rows = max(1, -(-len(keys) // cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3.5 * rows), squeeze=False)
    for ax in axes.flat[len(keys):]:
        ax.set_visible(False)
    for n, key in enumerate(keys):
        axis, f, amp = key
        ax = axes.flat[n]
        for i, (name, v) in enumerate(variants.items()):
            res = v["runs"][0]["_result"]
            lp = next(lp for lp in res.loops if (lp["axis"], lp["freq_hz"], lp["amplitude_nm"]) == key)
            ax.plot(np.degrees(lp["angle"]), lp["torque"], f"C{i}", lw=0.8, label=name)
        k = first.commanded[f"stiffness_{axis}"]     # this panel's axis: the IE panels show K_ie
        lim = np.array(ax.get_xlim())
        ax.plot(lim, k * np.radians(lim), "k--", lw=0.8, label=f"commanded K_{axis} = {k:g}")
        ax.set_title(f"{axis.upper()} {amp:g} N m {f:g} Hz")
        ax.set_xlabel("ankle angle (deg)")
        ax.set_ylabel("external torque (N m)")
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return f"plot: {png}"


def bench_impedance(args: argparse.Namespace) -> int:
    import time

    from ankle_rt import jsonout
    from ankle_rt.bench.impedance import Experiment, simulated_s
    from ankle_rt.config import ConfigError, load_config
    from ankle_rt.paths import default_config_path
    from ankle_rt.timing_reference import reference_step_s
    from ankle_rt.progress import Progress

    if args.stribeck[0] > 0.0 and args.stribeck[1] <= 0.0:
        raise SystemExit("ankle-rt bench impedance: --stribeck: the velocity VS must be > 0")
    cfg = load_config(Path(args.config) if args.config else default_config_path())
    effects = plant_effects(args.load_friction, tuple(args.stribeck))
    exp = Experiment(pulses_nm=((1.0, -1.0, 12.0, -12.0), (1.0, -1.0)), sine_hz=(0.5, 5.0), sine_nm=((6.0,), (3.0,)),
                     sine_cycles=3, analysed_cycles=1) if args.quick else Experiment()
    ff = None if args.friction_ff == "off" else args.friction_ff
    plan = {"closed loop": ("auto", ff), "open loop": ("off", ff)}
    if args.friction_study:
        for name in ("coulomb_viscous", "identified"):
            plan[f"closed loop, {name} ff"] = ("auto", name)
            plan[f"open loop, {name} ff"] = ("off", name)
    variants, refused = {}, {}
    ref_s = reference_step_s()
    t0 = time.perf_counter()
    with Progress("bench impedance", len(plan)) as bar:
        for k, (name, (feedback, f)) in enumerate(plan.items()):
            if not args.json:
                print(f"{name} ...", flush=True)
            bar.update(k, name)
            try:
                variants[name] = impedance_variant(cfg, args.stiffness, args.stiffness_ie, tuple(args.damping),
                                                   effects, feedback=feedback, friction_ff=f, experiment=exp,
                                                   keep_loops=True, plant_friction=args.plant_friction)
            except ConfigError as exc:   # a study variant the controller refuses (e.g. an unstable feed-forward)
                if name == "closed loop" or (name == "open loop" and f is None):
                    raise
                refused[name] = str(exc)
                if name == "open loop":   # --friction-ff: the open-loop reference runs without it
                    variants[name] = impedance_variant(cfg, args.stiffness, args.stiffness_ie, tuple(args.damping),
                                                       effects, feedback=feedback, friction_ff=None, experiment=exp,
                                                       keep_loops=True, plant_friction=args.plant_friction)
    # wall time per simulated cycle, the lockstep runs with their analysis (and the margin checks)
    cycle_s = (time.perf_counter() - t0) / (len(plan) * len(args.stiffness) * round(simulated_s(exp) * cfg["controller"]["rate_hz"]))
    ref_s = 0.5 * (ref_s + reference_step_s())
    note = plot_loops({k: variants[k] for k in ("closed loop", "open loop")}, args.plot) if args.plot else ""
    main = variants["closed loop"]["summary"]
    result = {key: main[key] for key in SUMMARY_KEYS}
    # per commanded stiffness, open loop's hysteresis over the closed loop's; the smallest
    result["hysteresis_ratio_open_to_closed"] = min(
        o["hysteresis_j_per_cycle"] / c["hysteresis_j_per_cycle"]
        for o, c in zip(variants["open loop"]["runs"], variants["closed loop"]["runs"]))
    result.update(torque_feedback=main["torque_feedback"], faults=main["faults"],
                  commanded_stiffness_dp=args.stiffness, damping=args.damping, plant_effects=effects,
                  plant_friction_scale=args.plant_friction,
                  variants={name: {**v["summary"], "runs": [{k: r[k] for k in r if k != "_result"} for r in v["runs"]]}
                            for name, v in variants.items()},
                  refused_variants=refused, plot=note, cycle_us=cycle_s * 1e6, reference_step_us=ref_s * 1e6, cycle_ref_steps=cycle_s / ref_s)
    if args.json:
        print(jsonout.dumps(result))
        return 0
    print(f"plant: nominal + {', '.join(e['type'] for e in effects) or 'no extra effects'}; "
          f"commanded K_dp {', '.join(f'{k:g}' for k in args.stiffness)} N m/rad, damping {args.damping[0]:g} / "
          f"{args.damping[1]:g} N m s/rad")
    print(f"{'variant':32s} {'K err %':>7s} {'Kdyn err %':>10s} {'B err %':>7s} {'step os %':>9s} {'J kg m2':>7s} "
          f"{'passive':>7s} {'hyst J':>6s} {'margin dB':>9s} {'tau err':>7s} {'noise A':>7s}  faults")
    for name, v in variants.items():
        s = v["summary"]
        print(f"{name:32s} {s['stiffness_error_max_pct']:7.1f} {s['dynamic_stiffness_error_max_pct']:10.1f} "
              f"{s['damping_error_max_pct']:7.0f} {s['torque_step_overshoot_pct']:9.1f} {s['apparent_inertia_kg_m2']:7.3f} "
              f"{str(s['passive']):>7s} {s['hysteresis_j_per_cycle']:6.3f} {s['stability_margin_db']:9.1f} "
              f"{s['torque_tracking_rms_nm']:7.2f} {s['current_noise_a']:7.2f}  {','.join(s['faults'])}")
    for name, reason in refused.items():
        print(f"{name:32s} refused: {reason}")
    for name in ("closed loop", "open loop"):
        for run in variants[name]["runs"]:
            c = run["commanded"]
            print(f"{name}, K {c['stiffness_dp']:g} / {c['stiffness_ie']:g}: rendered K per pulse "
                  + "; ".join(f"{p['axis']} {p['torque_nm']:+g}: {p['stiffness']:.0f}" for p in run["pulses"]))
            print("   sines (axis N m Hz: K_dyn, B, hysteresis J): "
                  + "; ".join(f"{s['axis']} {s['amplitude_nm']:g} {s['freq_hz']:g}: {s['dynamic_stiffness']:.0f}, "
                              f"{s['damping']:.2f}, {s['hysteresis_j']:.3f}" for s in run["sines"]))
            print("   torque steps (ground: overshoot DP / IE %, an ideal renderer's, peak beyond the ideal peak): "
                  + "; ".join(f"{s['ground']}: {s['overshoot_dp_pct']:.0f} / {s['overshoot_ie_pct']:.0f}, "
                              f"{s['ideal_overshoot_dp_pct']:.0f} / {s['ideal_overshoot_ie_pct']:.0f}, "
                              f"{s['excess_dp_pct']:.0f} / {s['excess_ie_pct']:.0f}" for s in run["steps"]))
    print(f"hysteresis open loop / closed loop (worst commanded stiffness): "
          f"{result['hysteresis_ratio_open_to_closed']:.1f}x")
    print(f"wall time per simulated cycle (lockstep runs and their analysis): {cycle_s * 1e6:.1f} us = "
          f"{cycle_s / ref_s:.2f} ref steps of {ref_s * 1e6:.1f} us")
    if note:
        print(note)
    return 0


def register_walk(sub: argparse._SubParsersAction) -> None:
    from ankle_rt.bench.walk import __doc__ as walk_doc

    p = sub.add_parser("walk", help="strides on the walking scenario for several wearers and cadences",
                       description=walk_doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", metavar="FILE", help="configuration (default: the shipped config/walk.yaml, the "
                                                    "gait-phase controller)")
    p.add_argument("--masses", default="50,75,100", metavar="KG,KG,...", help="wearer masses (default 50,75,100)")
    p.add_argument("--cadences", default="slow,normal,fast", metavar="C,C,...",
                   help="cadences: slow, normal, fast (default all three)")
    p.add_argument("--strides", type=int, default=12, metavar="N",
                   help="strides analysed per wearer and cadence, after a warm-up stride (default 12)")
    p.add_argument("--plot", metavar="PNG", help="ankle moment against angle per phase, with the able-bodied curve")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=bench_walk)


def bench_walk(args: argparse.Namespace) -> int:
    from ankle_rt import jsonout
    from ankle_rt.progress import Progress
    from ankle_rt.bench.walk import default_walk_config, plot_walk, walk_bench
    from ankle_rt.gait_data import CADENCES

    try:
        masses = [float(m) for m in args.masses.split(",")]
    except ValueError:
        raise SystemExit(f"ankle-rt bench walk: --masses: expected numbers in kg, got {args.masses!r}") from None
    cadences = args.cadences.split(",")
    bad = [c for c in cadences if c not in CADENCES]
    if bad:
        raise SystemExit(f"ankle-rt bench walk: --cadences: unknown {', '.join(bad)} (expected {', '.join(CADENCES)})")
    if args.strides < 1:
        raise SystemExit("ankle-rt bench walk: --strides: must be >= 1")
    with Progress("walking", len(masses) * len(cadences)) as bar:
        result, runs = walk_bench(args.config or default_walk_config(), masses, cadences, args.strides,
                                  progress=bar.callback)
    result["plot"] = plot_walk(runs, args.plot) if args.plot else ""
    if args.json:
        print(jsonout.dumps(result))
        return 0
    print(f"{'wearer':>16s} {'strides':>7s} {'moment err %':>12s} {'angle err deg':>13s} {'push-off J/kg':>13s} "
          f"{'I rms A':>7s} {'M peak / able-bodied N m':>24s}  fault")
    for w in result["wearers"]:
        print(f"{w['mass_kg']:6g} kg {w['cadence']:>7s} {w['strides']:7d} {w['moment_rms_error_pct']:12.1f} "
              f"{w['angle_rms_error_deg']:13.1f} {w['push_off_work_j_per_kg']:13.2f} {w['current_rms_a']:7.2f} "
              f"{w['moment_peak_nm']:13.0f} / {w['moment_ab_peak_nm']:<8.0f}  {w['fault']}")
    print(f"strides {result['strides']}, faults {result['faults']}; worst stride: moment RMS error "
          f"{result['moment_rms_error_pct']:.1f} %, angle RMS error {result['angle_rms_error_deg']:.1f} deg, "
          f"current RMS {result['current_rms_a']:.2f} A; current peak {result['current_peak_a']:.1f} A; "
          f"push-off work at normal cadence (smallest wearer mean) {result['push_off_work_j_per_kg']:.2f} J/kg; "
          f"I2t headroom {result['i2t_headroom_pct']:.1f} %")
    if result["plot"]:
        print(result["plot"])
    return 0
