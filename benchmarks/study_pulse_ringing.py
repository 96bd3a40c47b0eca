"""Study (issue 19, friction compensation): does the ankle ring after a static torque pulse?

The static pulses of ``ankle-rt bench impedance`` (DP +-1 to +-12 N m, IE +-1 to +-6 N m, 1.5 s each, the
bench's plant: load-dependent friction 0.12 + Stribeck) at K_dp 50 and 200 (K_ie half, damping 0.5 /
0.25), in lockstep. Per pulse: the overshoot of the true ankle angle over its pulse-end value (%), and
the zero crossings of (angle - end value) beyond 2 % of it in the pulse's first 0.5 s. The bench itself
reads the angle at the pulse's end only (stiffness), so a feed-forward that removes friction's damping
can ring there unseen. And the chatter at rest: the set currents' RMS above 20 Hz over the last 0.5 s
of each rest between pulses (a feed-forward whose direction follows a noisy signal shows there). Run: ``PYTHONPATH=$PWD nice python3 benchmarks/study_pulse_ringing.py [--config FILE]
[--friction-ff identified]`` (about 10 s).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from ankle_rt.backend import open_backend
from ankle_rt.bench.impedance import Experiment, TorqueProgramBackend, bench_config, schedule, torque_at
from ankle_rt.clock import SimClock
from ankle_rt.commands.bench import plant_effects
from ankle_rt.config import load_config
from ankle_rt.daemon import run_lockstep
from ankle_rt.paths import default_config_path

SETTLE_WINDOW_S = 0.05     # the pulse-end angle: mean over the pulse's last 50 ms (the bench's)
RING_WINDOW_S = 0.5        # zero crossings counted over the pulse's first 0.5 s
REST_WINDOW_S = 0.5        # chatter: the last 0.5 s of each rest
CHATTER_HZ = 20.0


def pulse_ringing(cfg_path: Path, friction_ff: str | None, stiffness_dp: float
                  ) -> tuple[list[tuple[str, float, int]], float]:
    """(pulse, overshoot %, zero crossings) per static pulse of the bench at ``stiffness_dp``, and the
    set currents' RMS above CHATTER_HZ at rest (A, the larger motor)."""
    c = bench_config(load_config(cfg_path), stiffness=(stiffness_dp, stiffness_dp / 2.0), damping=(0.5, 0.25),
                     torque_feedback="auto", friction_ff=friction_ff, effects=plant_effects(0.12, (0.15, 0.1)))
    exp = Experiment(sine_nm=((), ()), step_nm=(0.0, 0.0))
    segs, duration = schedule(exp)      # each pulse is followed by exp.rest_s of rest
    backend = TorqueProgramBackend(open_backend(c, SimClock()), lambda t, x: torque_at(segs, t))
    try:
        run = run_lockstep(c, duration, backend=backend)
    finally:
        backend.close()
    t, out = run["t"], []
    dt = float(t[1] - t[0])
    power = [0.0, 0.0]
    for s in segs:
        rest = (t >= s.stop + exp.rest_s - REST_WINDOW_S) & (t < s.stop + exp.rest_s)
        for m in (0, 1):
            i = run[f"current_cmd_{m + 1}"][rest]
            spectrum = np.fft.rfft(i - i.mean())
            high = np.fft.rfftfreq(len(i), dt) > CHATTER_HZ
            power[m] += 2.0 * float(np.sum(np.abs(spectrum[high]) ** 2)) / len(i) ** 2 / len(segs)
        angle = run["ankle_dp" if s.axis == 0 else "ankle_ie"]
        end = float(np.mean(angle[(t >= s.stop - SETTLE_WINDOW_S) & (t < s.stop)]))
        during = (t >= s.start) & (t < s.stop)
        overshoot = 100.0 * max(0.0, float(np.max(angle[during] * np.sign(end))) / abs(end) - 1.0)
        d = angle[during & (t < s.start + RING_WINDOW_S)] - end
        crossings = int(np.sum(np.diff(np.sign(d[np.abs(d) > 0.02 * abs(end)])) != 0))
        out.append((f"{'DP' if s.axis == 0 else 'IE'} {s.size:+g}", overshoot, crossings))
    return out, float(np.sqrt(max(power)))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--config", type=Path, default=default_config_path())
    p.add_argument("--friction-ff", choices=("off", "coulomb_viscous", "identified"), default="off")
    args = p.parse_args()
    ff = None if args.friction_ff == "off" else args.friction_ff
    for k in (50.0, 200.0):
        rows, chatter = pulse_ringing(args.config, ff, k)
        print(f"K_dp {k:g} (overshoot % / crossings): " + "; ".join(f"{name}: {over:.0f} % / {n}" for name, over, n in rows)
              + f"; at rest {chatter:.3f} A RMS above {CHATTER_HZ:g} Hz")


if __name__ == "__main__":
    main()
