"""An experiment script on ankle_rt.client: activate, step the DP reference under two gain sets,
record the response, save it.

    ankle-rt run --config config/sim.yaml --socket /tmp/demo.sock    # another terminal (or the service)
    python3 examples/step_experiment.py --socket /tmp/demo.sock --out step.npz

The saved .npz holds one array per sample field (t in s, angles in rad, currents in A, ...) plus
``trial`` (which gain set each sample belongs to). Leaving the ``with`` block deactivates the ankle,
also when the script fails half-way.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from ankle_rt.client import AnkleClient

TRIALS = ({"kp": 60.0, "kd": 3.0}, {"kp": 120.0, "kd": 3.0})
"""The PD gain sets compared (N m/rad, N m s/rad, motor side); within config/sim.yaml's gain limits and
keeping the daemon's 6 dB gain margin at 250 Hz too (kp 120 with kd 5 keeps only 4.4 dB there)."""


def run_experiment(ankle: AnkleClient, step_deg: float, hold_s: float, interval_s: float) -> dict[str, np.ndarray]:
    """For each gain set: back to 0, tune, step DP by ``step_deg`` and record ``hold_s`` s."""
    ankle.activate(tare_timeout_s=10.0)
    trials = []
    for number, gains in enumerate(TRIALS):
        ankle.set_reference(0.0, 0.0, ramp_s=0.2)
        ankle.set_gains(**gains)
        ankle.record(0.4, interval_s)                            # settle at 0 with the new gains
        ankle.set_reference(math.radians(step_deg), 0.0, ramp_s=0.0)   # a step (rate-limited by the daemon)
        data = ankle.record(hold_s, interval_s)
        data["trial"] = np.full(len(data["t"]), number)
        trials.append(data)
    ankle.deactivate()
    return {name: np.concatenate([trial[name] for trial in trials]) for name in trials[0]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", type=Path, help="the daemon's config (its service.socket_path)")
    parser.add_argument("--socket", type=Path, help="the daemon's socket (instead of --config)")
    parser.add_argument("--out", type=Path, default=Path("step.npz"), help="where the samples go (.npz)")
    parser.add_argument("--step-deg", type=float, default=10.0, help="DP step, degrees (default 10)")
    parser.add_argument("--hold-s", type=float, default=1.0, help="s recorded after each step (default 1)")
    parser.add_argument("--interval-s", type=float, default=0.02, help="s between samples (default 0.02)")
    args = parser.parse_args(argv)
    with AnkleClient.connect(args.config, socket_path=args.socket) as ankle:
        data = run_experiment(ankle, args.step_deg, args.hold_s, args.interval_s)
    np.savez(args.out, **data)
    for number, gains in enumerate(TRIALS):
        last = data["est_ankle_dp"][data["trial"] == number][-1]
        print(f"trial {number} {gains}: DP after {args.hold_s:g} s = {math.degrees(last):.2f} deg "
              f"(reference {args.step_deg:g} deg)")
    print(f"{len(data['t'])} samples saved to {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
