"""The run log under stress: a fuzz of mutated logs, a long run with rotation and retention, and what
rotation costs the real-time loop. Prints figures; asserts nothing.

    python benchmarks/bench_log.py [--fuzz-inputs N] [--minutes M] [--rotate-mb MB] [--keep-files K]
                                   [--realtime-s S] [--rounds R] [--priority N]
                                   [--only fuzz|rotation|timing]

fuzz      N (default 10^5) seeded mutations of a clean log (bit flips, overwritten, inserted and
          deleted bytes, truncation, header damage, swapped records), each read, summarised and
          turned into CSV columns: inputs tried, refused with LogFormatError, crashes (any other
          exception), damaged records read back as intact.
rotation  M simulated minutes (default 10) of the daemon in lockstep, logging through the real
          writer thread with rotation at MB (default 5) and K files kept (default 4): files kept,
          records written / dropped, whether the kept parts join without a gap and end at the last
          cycle. (Lockstep runs about 10x faster than real time, so the writer sees ~10x the
          real data rate: a harder test of "no record lost" than real time.)
timing    the daemon in real time for S s (default 600) twice: rotation off, then rotation at MB and
          K files: the loop's period error p50/p99/max and the rotations done; R rounds (default 1)
          alternate the two and print the median p99 of each. On a shared machine the figures move by
          several µs between identical runs (far more under load); compare against that noise.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402

from ankle_rt.clock import SimClock  # noqa: E402
from ankle_rt.commands.bench import realtime_run  # noqa: E402
from ankle_rt.config import load_config  # noqa: E402
from ankle_rt.daemon import Daemon, run_lockstep  # noqa: E402
from ankle_rt.log.reader import read_log  # noqa: E402
from ankle_rt.paths import default_config_path  # noqa: E402
from tests.log_fuzz import fuzz_logs, scratch_dir  # noqa: E402


def bench_fuzz(cfg, inputs: int, work: Path) -> None:
    path = work / "clean.arlog"
    run_lockstep(cfg, 0.3, log_path=path)
    t0 = time.perf_counter()
    r = fuzz_logs(path.read_bytes(), inputs, seed=20261123, directory=scratch_dir(work))
    dt = time.perf_counter() - t0
    print(f"fuzz: {r.inputs} mutated logs tried in {dt:.1f} s ({r.inputs / dt:.0f}/s); refused (LogFormatError) "
          f"{r.refused}; crashes {len(r.crashes)}; damaged records read back {len(r.violations)}; "
          f"intact records kept {r.records_kept}, damaged counted {r.damaged_counted}")
    for line in (r.crashes + r.violations)[:10]:
        print(f"  {line}")


def _with_rotation(cfg, rotate_mb: float, keep: int):
    cfg = cfg.deep_copy()
    cfg["logging"].update(rotate_size_mb=rotate_mb, keep_files=keep)
    return cfg


def bench_rotation(cfg, minutes: float, rotate_mb: float, keep: int, work: Path) -> None:
    cfg = _with_rotation(cfg, rotate_mb, keep)
    directory = work / "rotation"
    d = Daemon(cfg, SimClock())
    d.open_log(directory / "run.arlog")
    t0 = time.perf_counter()
    try:
        d.run(minutes * 60.0)
    finally:
        d.close()
    dt = time.perf_counter() - t0
    w = d.recorder
    files = sorted(directory.glob("*.arlog"), key=lambda p: read_log(p, last=0).meta["part"])
    logs = [read_log(p) for p in files]
    joined = all(a.meta["first_record"] + len(a) == b.meta["first_record"] for a, b in zip(logs, logs[1:]))
    seq = np.concatenate([log.records["seq"] for log in logs])
    ends = logs[-1].meta["first_record"] + len(logs[-1]) == w.written
    sizes = [p.stat().st_size / 1e6 for p in files]
    damaged = sum(log.damaged + log.torn_bytes for log in logs)
    print(f"rotation: {minutes:g} min lockstep ({dt:.0f} s wall), {w.written} records, rotate at {rotate_mb:g} MB, "
          f"keep {keep}: {w.part + 1} parts written, {len(files)} files kept ({min(sizes):.2f}-{max(sizes):.2f} MB), "
          f"{len(w.deleted)} deleted; dropped {w.dropped}; damaged/torn {damaged}; kept parts join without a gap: "
          f"{joined and bool(np.all(np.diff(seq) >= 0))}; last record is the last cycle: {ends}; "
          f"status {w.status()['state']}")


def bench_timing(cfg, seconds: float, rotate_mb: float, keep: int, rounds: int, work: Path) -> None:
    """Rotation off and on, alternated ``rounds`` times (so a burst of load elsewhere on the machine
    hits both alike); the median p99 of each at the end."""
    p99: dict[str, list[float]] = {}
    for k in range(rounds):
        for label, c in (("rotation off", _with_rotation(cfg, 0.0, 0)),
                         (f"rotation at {rotate_mb:g} MB, keep {keep}", _with_rotation(cfg, rotate_mb, keep))):
            directory = work / f"{label.split(',')[0].replace(' ', '_')}-{k}"
            stats, notes = realtime_run(c, seconds, directory)
            pe = stats["period_error"]
            p99.setdefault(label, []).append(pe["p99_us"])
            files = list(directory.glob("*.arlog"))
            parts = max(read_log(p, last=0).meta.get("part", 0) for p in files) + 1 if files else 0
            print(f"timing, {label}: {seconds:g} s real time, {stats['cycles']} cycles, period error p50/p99/max "
                  f"{pe['p50_us']:.1f} / {pe['p99_us']:.1f} / {pe['max_us']:.0f} us, late {stats['late_cycles']}, "
                  f"overruns {stats['overruns']}; {parts} parts, {len(files)} files kept"
                  + (f" ({'; '.join(notes)})" if notes else ""), flush=True)
    if rounds > 1:
        print("timing, median p99 period error over the rounds: "
              + ", ".join(f"{label} {np.median(v):.1f} us" for label, v in p99.items()))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--fuzz-inputs", type=int, default=100_000)
    p.add_argument("--minutes", type=float, default=10.0, help="simulated minutes of the rotation run")
    p.add_argument("--rotate-mb", type=float, default=5.0)
    p.add_argument("--keep-files", type=int, default=4)
    p.add_argument("--realtime-s", type=float, default=600.0, help="s of each real-time run")
    p.add_argument("--rounds", type=int, default=1, help="real-time runs of each kind, alternated")
    p.add_argument("--priority", type=int, metavar="N",
                   help="SCHED_FIFO priority of the real-time loop (default: loop.realtime.priority of the config)")
    p.add_argument("--only", choices=("fuzz", "rotation", "timing"))
    args = p.parse_args()
    cfg = load_config(default_config_path())
    if args.priority is not None:
        cfg["loop"]["realtime"]["priority"] = args.priority
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        if args.only in (None, "fuzz"):
            bench_fuzz(cfg, args.fuzz_inputs, work)
        if args.only in (None, "rotation"):
            bench_rotation(cfg, args.minutes, args.rotate_mb, args.keep_files, work)
        if args.only in (None, "timing"):
            bench_timing(cfg, args.realtime_s, args.rotate_mb, args.keep_files, args.rounds, work)


if __name__ == "__main__":
    main()
