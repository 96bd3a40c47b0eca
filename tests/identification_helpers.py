"""Helpers for the identification tests: configs for the motors-off-the-cables simulator and a
lockstep run of a CycleController that returns an interchange Recording."""

from __future__ import annotations

import copy
import math

import numpy as np

from ankle_rt.backend import SensorFrame, open_backend
from ankle_rt.clock import SimClock
from ankle_rt.config import Config
from ankle_rt.interchange import Recording


def actuator_cfg(sim_cfg: Config, **sim: object) -> Config:
    """The shipped sim config with the motors off the cables, quantisation and noise on."""
    cfg = Config(copy.deepcopy(dict(sim_cfg)))
    cfg.source = sim_cfg.source
    cfg["sim"].update({"cables": False, "quantization": True, "sensor_noise": True}, **sim)
    return cfg


class _Est:
    """The fields of ankle_rt.estimation.Estimate the experiments use (velocity: backward difference,
    first-order low-pass at 50 Hz)."""

    def __init__(self) -> None:
        self.t = 0.0
        self.motor_pos = np.zeros(2)
        self.motor_vel = np.zeros(2)


def drive(cfg: Config, controller, duration_s: float) -> Recording:
    """Minimal lockstep loop: read, estimate, controller, torque -> current, write; ZOH rows."""
    clock = SimClock()
    backend = open_backend(cfg, clock)
    kt = cfg["actuator"]["torque_constant"]
    period = round(1e9 / cfg["controller"]["rate_hz"])
    n = int(round(duration_s * 1e9 / period))
    frame, est, out = SensorFrame(), _Est(), np.zeros(2)
    cols = {k: np.zeros(n) for k in ("t", "motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2")}
    a = 1.0 - math.exp(-2 * math.pi * 50.0 * period * 1e-9)
    backend.activate()
    for k in range(n):
        clock.sleep_until(k * period)
        backend.read(frame)
        if k:
            h = frame.t - est.t
            est.motor_vel += a * ((frame.motor_pos - est.motor_pos) / h - est.motor_vel)
        est.t = frame.t
        est.motor_pos[:] = frame.motor_pos
        if k == 0:
            controller.reset(est)
        controller.update(est, out)
        backend.write(out[0] / kt, out[1] / kt)
        cols["t"][k] = frame.t
        cols["motor_pos_1"][k], cols["motor_pos_2"][k] = frame.motor_pos
        cols["current_cmd_1"][k], cols["current_cmd_2"][k] = out[0] / kt, out[1] / kt
    backend.close()
    return Recording(cols, "lockstep")
