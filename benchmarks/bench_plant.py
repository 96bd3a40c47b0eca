"""Simulator speed against accuracy: the plant alone stepped at 1 kHz control ticks.

For 1, 2 and 4 integration substeps per tick, prints the wall time per tick, the real-time factor
(simulated seconds per wall second; goal >= 50) and the integrator's largest state error over 1 s of
the excitation in sim_backend.reference against RK4 at 1e-5 s. Each tick does what the simulated
backend does per cycle: step the plant with held set values, read the encoders and strain gauges.
Friction, quantisation and noise are on, as in config/sim.yaml. Timing is noisy on shared cores:
the best of several repeats is the machine's capability, the median what a busy machine gives.

    python benchmarks/bench_plant.py [--config FILE] [--seconds 5] [--repeats 5]
"""

from __future__ import annotations

import argparse
import copy
import datetime
import math
import os
import statistics
import time
from pathlib import Path

from ankle_rt.config import load_config
from ankle_rt.params import PlantParams
from ankle_rt.paths import default_config_path
from sim_backend.model import CompliantModel
from sim_backend.plant import SimulatedPlant
from sim_backend.reference import max_errors, model_trajectory, reference_trajectory

SUBSTEPS = (1, 2, 4)


def wall_per_tick(cfg: dict, substeps: int, seconds: float) -> float:
    """s of wall time per control tick for ``seconds`` of simulated time."""
    cfg = copy.deepcopy(cfg)
    cfg["sim"]["substeps"] = substeps
    plant = SimulatedPlant(cfg)
    n = round(seconds / plant.dt)
    i1 = [0.5 * math.sin(2 * math.pi * 2.0 * k * plant.dt) for k in range(n)]
    i2 = [0.4 * math.cos(2 * math.pi * 3.0 * k * plant.dt) for k in range(n)]
    step, enc, sg = plant.step, plant.motor_positions, plant.strain_gauge_torques
    start = time.perf_counter()
    for k in range(n):
        step(i1[k], i2[k])
        enc()
        sg()
    return (time.perf_counter() - start) / n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=None, help="default: the shipped config/sim.yaml")
    ap.add_argument("--seconds", type=float, default=5.0, help="simulated seconds per timing run")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    cfg = load_config(args.config or default_config_path())
    params = PlantParams.from_config(cfg)
    dt = 1.0 / cfg["controller"]["rate_hz"]

    print(f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M:%S} UTC, load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}, {os.cpu_count()} CPUs")
    print(f"config {args.config or default_config_path()} (default substeps {cfg['sim']['substeps']}); "
          f"accuracy over 1 s against RK4 at 1e-5 s ...")
    ticks = round(1.0 / dt)
    ref = reference_trajectory(CompliantModel(params, dt=dt), ticks)
    print(f"\n{'substeps':>8} {'us/tick best':>13} {'median':>8} {'RTF best':>9} {'median':>7}"
          f" {'max pos err (rad)':>18} {'max rate err (rad/s)':>21}")
    for n in SUBSTEPS:
        pos, vel = max_errors(model_trajectory(CompliantModel(params, dt=dt, substeps=n), ticks), ref)
        times = [wall_per_tick(cfg, n, args.seconds) for _ in range(args.repeats)]
        best, med = min(times), statistics.median(times)
        print(f"{n:>8} {best * 1e6:>13.1f} {med * 1e6:>8.1f} {dt / best:>9.0f} {dt / med:>7.0f}"
              f" {pos:>18.1e} {vel:>21.1e}")
    print(f"\none encoder count = {2 * math.pi / params.actuator.encoder_counts_per_rev:.1e} rad; "
          "goal: RTF >= 50 at the default substeps")


if __name__ == "__main__":
    main()
