"""A minimal motor-side PD around the simulated plant, for the paper's section 7 scenario in tests.

Not the daemon's controller (that is ankle_rt.control): just the paper's eq. 11 per motor,
u = kp (theta_ref_m - theta_m) - kd dtheta_m with theta_ref_m = R theta_ref, the motor rate taken
from the encoder positions by backward difference (as the paper's simulation does), and the torque
sent as current set values (u / kt) to the plant's amplifiers. Lockstep: one plant tick per cycle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ankle_rt.config import Config
from sim_backend.plant import SimulatedPlant


@dataclass
class PdRun:
    """Per-tick records of a run (rows sampled before each tick's command)."""

    t: np.ndarray          # s
    ankle: np.ndarray      # (n, 2) rad [DP, IE], true joint angles
    motor: np.ndarray      # (n, 2) rad, encoder readings
    torque: np.ndarray     # (n, 2) N m, PD output (before the amplifiers' limits)
    ref: np.ndarray        # (2,) rad, the ankle reference [DP, IE]

    def error_at(self, t: float) -> np.ndarray:
        """rad [DP, IE]: ankle position minus reference at time ``t``."""
        return self.ankle[int(round(t / (self.t[1] - self.t[0])))] - self.ref

    def max_error(self, t0: float, t1: float) -> np.ndarray:
        """rad [DP, IE]: the largest |ankle - reference| in [t0, t1)."""
        sel = (self.t >= t0) & (self.t < t1)
        return np.max(np.abs(self.ankle[sel] - self.ref), axis=0)


def run_pd_step(cfg: Config, ref_deg: tuple[float, float], duration_s: float) -> PdRun:
    """Step the ankle reference to ``ref_deg`` (DP, IE in degrees) at t = 0 under the config's
    ``controller.step_gains`` and run for ``duration_s``; disturbances come from ``sim.disturbances``."""
    plant = SimulatedPlant(cfg)
    gains = cfg["controller"]["step_gains"]
    kp, kd, kt, dt = gains["kp"], gains["kd"], plant.kt, plant.dt
    ref = np.radians(ref_deg)
    ref_m = plant.model.linear.kin.R @ ref
    n = int(round(duration_s / dt))
    t, ankle, motor, torque = np.arange(n) * dt, np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 2))
    prev = plant.motor_positions()
    for k in range(n):
        pos = plant.motor_positions()
        u1 = kp * (ref_m[0] - pos[0]) - kd * (pos[0] - prev[0]) / dt
        u2 = kp * (ref_m[1] - pos[1]) - kd * (pos[1] - prev[1]) / dt
        prev = pos
        ankle[k] = plant.ankle_positions()
        motor[k] = pos
        torque[k] = u1, u2
        plant.step(u1 / kt, u2 / kt)
    return PdRun(t, ankle, motor, torque, ref)
