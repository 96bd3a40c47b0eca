"""Config values the hardware backends need but the simulator does not.

The schema (ankle_rt/config_schema.py) gives calibration values such as the ESCON map, encoder
signs and the strain-gauge matrix no default (``None`` when absent), so that a simulation config
need not state them. A hardware backend asks for them here and gets a :class:`ConfigError` naming
the file and the key when one is missing: calibration values are never silently defaulted.
"""

from __future__ import annotations

from typing import Any

from ankle_rt.config import ConfigError


def config_error(cfg: Any, key: str, message: str) -> ConfigError:
    """A ConfigError naming the config's file and ``key``."""
    return ConfigError(message, getattr(cfg, "source", None), key)


def required(cfg: Any, key: str, what: str) -> Any:
    """The value at the dotted ``key``; a ConfigError if it is absent (None)."""
    value = cfg
    for part in key.split("."):
        value = value.get(part) if isinstance(value, dict) else None
        if value is None:
            break
    if value is None:
        raise config_error(cfg, key, f"missing: {what} (required for backend {cfg.get('backend')!r}; "
                                     f"see config/hw-serial.yaml)")
    return value
