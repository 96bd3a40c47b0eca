"""Shared fixtures: the shipped configuration, loaded and validated once per test. Hypothesis runs
derandomized (examples drawn from a fixed seed, no example database), so every run tests the same cases."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import settings

settings.register_profile("deterministic", derandomize=True, database=None)
settings.load_profile("deterministic")

from ankle_rt.config import Config, load_config

ROOT = Path(__file__).resolve().parent.parent
SIM_CONFIG = ROOT / "config" / "sim.yaml"


@pytest.fixture(scope="session")
def _sim_cfg() -> Config:
    return load_config(SIM_CONFIG)


@pytest.fixture
def sim_cfg(_sim_cfg: Config) -> Config:
    """A private deep copy of config/sim.yaml that a test may edit."""
    return _sim_cfg.deep_copy()
