"""Objects named "module:attribute" and imported on first use: how a driver reaches its device's
emulator (when a config asks for the in-process bench) without importing it, so that the drivers
run where the emulators and the simulator they need are not installed (like ankle_rt.backend's
backend registry and ``ankle-rt emulate``'s)."""

from __future__ import annotations

import importlib
from typing import Any


def load_by_name(spec: str) -> Any:
    """The attribute ``spec`` ("package.module:name") names."""
    module_name, _, attr = spec.partition(":")
    return getattr(importlib.import_module(module_name), attr)
