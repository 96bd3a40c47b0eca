"""Issue 10's figures: bad inputs tried and crashes per parser, the largest current ever commanded in
the property run, and what loading a 12 MB reference profile costs the real-time loop.

    python benchmarks/bench_fuzz.py [--inputs 100000] [--sequences 40] [--profile-mb 12] [--seed N]

1. Every parser (config, interchange CSV, serial frames, CAN frames, command lines) gets ``--inputs``
   seeded bad inputs (tests/fuzz_inputs.py; the CI suite runs 10^4 of the same): prints inputs tried,
   refused with the parser's own error, and crashes (any other exception; must be 0).
2. The current property: ``--sequences`` random configs x random command sequences (hostile gains,
   jumps, profiles, NaN sensor samples) through the daemon in lockstep; prints the largest current ever
   written to an amplifier and its ratio to that run's configured peak (must be <= 1).
3. The profile stall: the daemon runs on the monotonic clock at 1 kHz (sim backend, ACTIVE), and a
   client sends ``start_profile csv`` with a ``--profile-mb`` file through the socket; prints the
   cycles missed (overruns, skipped deadlines) and the worst cycle latency while the file loads, next
   to the same figures for a run without the load (the machine's own noise). Timing figures on a
   shared machine are disturbed by other load; rerun on a quiet one.

Exits 1 if any parser crashed or a current exceeded its limit; prints figures, asserts nothing else.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))      # the seeded inputs live in tests/ (shared with the CI suite)

import numpy as np  # noqa: E402

from ankle_rt.config import load_config  # noqa: E402
from tests import fuzz_inputs as fuzz  # noqa: E402


def parsers(n: int, seed: int, tmp: Path) -> list[fuzz.FuzzResult]:
    cfg = load_config(ROOT / "config" / "sim.yaml")
    runs = [("config", lambda: fuzz.fuzz_config(n, seed)),
            ("csv", lambda: fuzz.fuzz_csv(n, seed, tmp, cfg)),
            ("serial", lambda: fuzz.fuzz_serial(n, seed)),
            ("can", lambda: fuzz.fuzz_can(n, seed, f"bench-fuzz-{seed}")),
            ("commands", lambda: fuzz.fuzz_commands(n, seed))]
    results = []
    for name, run in runs:
        t0 = time.perf_counter()
        result = run()
        print(f"{result.line()}   ({time.perf_counter() - t0:.1f} s)", flush=True)
        results.append(result)
    return results


def write_profile(path: Path, megabytes: float) -> int:
    """A slow, small-amplitude reference CSV of about ``megabytes`` MB; returns its rows."""
    rows = int(megabytes * 1e6 / 29.7)           # "%.6f" rows of a slow sine: ~29.7 bytes each
    t = np.arange(rows) * 0.001
    data = np.column_stack([t, 0.05 * np.sin(0.5 * t), 0.02 * np.sin(0.3 * t)])
    np.savetxt(path, data, delimiter=",", fmt="%.6f", header="t,ref_dp,ref_ie", comments="")
    return rows


def realtime_run(profile: Path | None, seconds: float, tmp: Path, priority: int = 0) -> dict:
    """Run the daemon for ``seconds`` on the monotonic clock (the loop thread at SCHED_FIFO
    ``priority`` when > 0 and permitted); with ``profile``, a client starts it through the socket
    after 1 s. Returns the loop figures while the load ran (or over the same window without it)."""
    from ankle_rt.realtime import apply_realtime
    from ankle_rt.service.loader import normal_scheduling

    from ankle_rt.clock import MonotonicClock
    from ankle_rt.daemon import Daemon
    from ankle_rt.service.link import ServiceLink

    cfg = load_config(ROOT / "config" / "sim.yaml")
    cfg["loop"]["max_consecutive_overruns"] = 1_000_000      # measure, do not fault
    cfg["sim"]["disturbances"] = []
    clock = MonotonicClock(spin_ns=cfg["loop"]["realtime"]["spin_us"] * 1000)
    daemon = Daemon(cfg, clock)
    sock_path = tmp / f"bench-{time.monotonic_ns()}.sock"
    daemon.service = ServiceLink(cfg, daemon.handle, path=sock_path, environ={})
    window: dict = {}

    def client() -> None:
        time.sleep(1.0)
        window["before"] = (daemon.loop.stats.overruns, daemon.loop.stats.skipped)
        window["t0"] = time.monotonic_ns()
        try:
            if profile is not None:
                with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
                    s.settimeout(60.0)
                    s.connect(str(sock_path))
                    s.sendall(json.dumps({"cmd": "start_profile", "name": "csv", "params": {"path": str(profile)}})
                              .encode() + b"\n")
                    data = b""
                    while not data.endswith(b"\n"):
                        data += s.recv(4096)
                window["reply"] = json.loads(data)
            else:
                time.sleep(1.0)
        except OSError as exc:
            window["reply"] = f"client failed: {exc}"
        finally:
            window["t1"] = time.monotonic_ns()
            window["after"] = (daemon.loop.stats.overruns, daemon.loop.stats.skipped)

    worker = threading.Thread(target=client)
    worker.start()
    starts, latency = [], []
    cycle = daemon.cycle

    def timed(t_start_ns: int) -> None:
        cycle(t_start_ns)
        starts.append(t_start_ns)
        latency.append(clock.now_ns() - t_start_ns)
    granted = apply_realtime({**cfg["loop"]["realtime"], "priority": priority}) if priority else []
    try:
        daemon.loop.run(timed, round(seconds * 1e9))
    finally:
        normal_scheduling()
        worker.join()
        state = daemon.safety.state
        daemon.close()
    t = np.array(starts)
    lat = np.array(latency)[(t >= window["t0"]) & (t <= window["t1"])] * 1e-3
    lat = lat if lat.size else np.zeros(1)
    return {"overruns": window["after"][0] - window["before"][0], "skipped": window["after"][1] - window["before"][1],
            "load_s": (window["t1"] - window["t0"]) * 1e-9, "max_cycle_us": float(lat.max()),
            "p999_cycle_us": float(np.percentile(lat, 99.9)), "state": state.name,
            "reply": window.get("reply"), "scheduling": "; ".join(granted) or "normal scheduling"}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--inputs", type=int, default=100_000, help="bad inputs per parser (default 10^5)")
    parser.add_argument("--sequences", type=int, default=40, help="config x command sequences in the property run")
    parser.add_argument("--profile-mb", type=float, default=12.0)
    parser.add_argument("--seed", type=int, default=20261123)
    parser.add_argument("--priority", type=int, default=50,
                        help="also measure the stall with the loop thread at this SCHED_FIFO priority (0: only normal)")
    args = parser.parse_args()
    failed = False
    shm = Path("/dev/shm")
    with tempfile.TemporaryDirectory(dir=shm if shm.is_dir() and os.access(shm, os.W_OK) else None) as tmp_name:
        tmp = Path(tmp_name)
        print(f"1. bad inputs per parser (seed {args.seed})")
        results = parsers(args.inputs, args.seed, tmp)
        tried, crashes = sum(r.tried for r in results), sum(len(r.crashes) for r in results)
        print(f"   total: {tried} bad inputs tried, {crashes} crashes")
        failed |= crashes > 0

        print(f"2. current property: {args.sequences} random configs x command sequences through the daemon")
        t0 = time.perf_counter()
        ratio, current, prop = fuzz.current_property(args.sequences, 3000, args.seed)
        print(f"   {prop.line()}   ({time.perf_counter() - t0:.1f} s)")
        print(f"   largest current ever commanded: {current:.3f} A = {ratio:.4f} x the configured peak limit")
        failed |= ratio > 1.0 or bool(prop.crashes)

        profile = tmp / "big.csv"
        rows = write_profile(profile, args.profile_mb)
        size = profile.stat().st_size / 1e6
        print(f"3. loop stall while loading a {size:.1f} MB profile ({rows} rows), real clock, 1 kHz, ACTIVE")
        for priority in sorted({0, args.priority}):
            quiet = realtime_run(None, 4.0, tmp, priority)
            loaded = realtime_run(profile, 6.0, tmp, priority)
            print(f"   loop thread: {loaded['scheduling']}")
            print(f"   without a load: {quiet['overruns']} overruns, {quiet['skipped']} missed cycles, worst cycle "
                  f"{quiet['max_cycle_us']:.0f} us (p99.9 {quiet['p999_cycle_us']:.0f} us)")
            print(f"   loading:        {loaded['overruns']} overruns, {loaded['skipped']} missed cycles, worst cycle "
                  f"{loaded['max_cycle_us']:.0f} us (p99.9 {loaded['p999_cycle_us']:.0f} us); load took "
                  f"{loaded['load_s']:.2f} s; reply {loaded['reply']}; final state {loaded['state'].lower()}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
