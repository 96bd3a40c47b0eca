"""Shared fixtures: the shipped configuration, loaded and validated once per test."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest

from ankle_rt.config import Config, load_config

ROOT = Path(__file__).resolve().parent.parent
SIM_CONFIG = ROOT / "config" / "sim.yaml"


@pytest.fixture(scope="session")
def _sim_cfg() -> Config:
    return load_config(SIM_CONFIG)


@pytest.fixture
def sim_cfg(_sim_cfg: Config) -> Config:
    """A private deep copy of config/sim.yaml that a test may edit."""
    cfg = Config(copy.deepcopy(dict(_sim_cfg)))
    cfg.source = _sim_cfg.source
    return cfg
