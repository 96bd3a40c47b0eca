"""Helpers for the identification tests: the sim config as `ankle-rt identify` prepares it."""

from __future__ import annotations

from ankle_rt.config import Config
from ankle_rt.identification.runner import actuator_config, with_overrides


def actuator_cfg(sim_cfg: Config, **sim: object) -> Config:
    """The shipped sim config as the identify command prepares it (motors off the cables, no ankle
    disturbances), with quantisation and strain-gauge noise on and ``sim`` overrides."""
    return actuator_config(with_overrides(sim_cfg, sim={"quantization": True, "sensor_noise": True, **sim}))[0]
