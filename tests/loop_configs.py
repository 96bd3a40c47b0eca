"""The joint-torque loops the tests pin: the walking loop (config/torque-loop-walk.yaml, the notched DP loop
shipped before the noise-bounded one), whose notch, lag and cutoff tests were written around it."""

from __future__ import annotations

import yaml

from ankle_rt.config import Config, load_config
from ankle_rt.paths import CONFIG_DIR, default_config_path

WALK_LOOP: dict = yaml.safe_load((CONFIG_DIR / "torque-loop-walk.yaml").read_text())["controller"]["torque_loop"]


def merged(base: dict, changes: dict) -> dict:
    """``base`` with ``changes`` merged in, section by section (a nested mapping of overrides)."""
    out = dict(base)
    for key, value in changes.items():
        out[key] = merged(out.get(key, {}), value) if isinstance(value, dict) else value
    return out


def walk_loop_config(changes: dict | None = None) -> Config:
    """config/sim.yaml on the walking loop, then ``changes`` (load_config's overrides: validated, the margin
    checks included)."""
    return load_config(default_config_path(), merged({"controller": {"torque_loop": WALK_LOOP}}, changes or {}))
