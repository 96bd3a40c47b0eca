"""Issue 10: a seeded, deterministic fuzz suite over every parser (>= 10^4 inputs each) and the
property that no sequence of commands and configs drives a current beyond the configured limit.
benchmarks/bench_fuzz.py runs the same generators with >= 10^5 inputs each."""

from __future__ import annotations

import itertools
import os
import tempfile
from pathlib import Path

import pytest

from tests import fuzz_inputs as fuzz

N = 10_000
SEED = 20261123
_channels = itertools.count()


def check(result: fuzz.FuzzResult) -> None:
    print(result.line())
    assert result.tried >= N
    assert result.crashes == []


def test_config_fuzz():
    result = fuzz.fuzz_config(N, SEED)
    check(result)
    assert N // 2 < result.refused < result.tried        # the mutations hit both ways


@pytest.fixture
def scratch(tmp_path):
    """A directory in memory when the machine has one (10^4 file rewrites on a disk take ~20 s)."""
    shm = Path("/dev/shm")
    if not (shm.is_dir() and os.access(shm, os.W_OK)):
        yield tmp_path
        return
    with tempfile.TemporaryDirectory(dir=shm) as name:
        yield Path(name)


def test_csv_fuzz(scratch, _sim_cfg):
    result = fuzz.fuzz_csv(N, SEED, scratch, _sim_cfg)
    check(result)
    assert result.refused > N // 2


def test_serial_frame_fuzz():
    check(fuzz.fuzz_serial(N, SEED))


def test_can_frame_fuzz():
    check(fuzz.fuzz_can(N, SEED, f"test-fuzz-can-{next(_channels)}"))


def test_command_line_fuzz():
    result = fuzz.fuzz_commands(N, SEED)
    check(result)
    assert result.refused > N // 2


def test_fuzz_is_deterministic():
    first, second = fuzz.fuzz_commands(500, 7), fuzz.fuzz_commands(500, 7)
    assert (first.tried, first.refused) == (second.tried, second.refused)


@pytest.mark.parametrize("seed", [1, 2])
def test_no_command_sequence_drives_a_current_beyond_the_configured_limit(seed):
    ratio, current, result = fuzz.current_property(sequences=8, cycles=1500, seed=seed)
    print(f"largest current commanded: {current:.3f} A = {ratio:.4f} x its configured peak")
    assert result.crashes == []
    assert 0.0 < ratio <= 1.0
