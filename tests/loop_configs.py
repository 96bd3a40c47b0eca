"""The joint-torque loops the tests pin: the walking loop (config/torque-loop-walk.yaml, the notched DP loop
shipped before the noise-bounded one), whose notch, lag and cutoff tests were written around it; and the gauges'
loop (config/torque-loop-gauges.yaml, the schema's defaults: the worn prosthesis's, without joint encoders), which
config/sim.yaml replaces with the encoder-rate loop."""

from __future__ import annotations

import yaml

from ankle_rt.config import Config, load_config
from ankle_rt.paths import CONFIG_DIR, default_config_path


def loop_file(name: str) -> dict:
    """controller.torque_loop of config/``name``."""
    return yaml.safe_load((CONFIG_DIR / name).read_text())["controller"]["torque_loop"]


WALK_LOOP: dict = loop_file("torque-loop-walk.yaml")
GAUGE_LOOP: dict = loop_file("torque-loop-gauges.yaml")


def merged(base: dict, changes: dict) -> dict:
    """``base`` with ``changes`` merged in, section by section (a nested mapping of overrides)."""
    out = dict(base)
    for key, value in changes.items():
        out[key] = merged(out.get(key, {}), value) if isinstance(value, dict) else value
    return out


def on_loop(loop: dict, changes: dict | None = None) -> Config:
    """config/sim.yaml on the joint-torque loop ``loop``, then ``changes`` (load_config's overrides: validated,
    the margin checks included)."""
    return load_config(default_config_path(), merged({"controller": {"torque_loop": loop}}, changes or {}))


def walk_loop_config(changes: dict | None = None) -> Config:
    """config/sim.yaml on the walking loop, then ``changes``."""
    return on_loop(WALK_LOOP, changes)


def gauge_loop_config(changes: dict | None = None) -> Config:
    """config/sim.yaml on the gauges' loop (the device's without joint encoders), then ``changes``."""
    return on_loop(GAUGE_LOOP, changes)
