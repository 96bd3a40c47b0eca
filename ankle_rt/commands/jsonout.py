"""JSON output of the commands: strict JSON, so any parser reads it (``json.dumps`` would write
NaN and Infinity, which are not JSON); a value that does not exist is ``null``."""

from __future__ import annotations

import json
import math
from typing import Any


def finite_or_none(value: Any) -> Any:
    """``value`` with every NaN or infinite float (also numpy's) replaced by None, recursively."""
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(v) for v in value]
    if hasattr(value, "item") and type(value).__module__ == "numpy":   # a numpy scalar
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def dumps(value: Any, **kwargs: Any) -> str:
    """Strict JSON text of ``value`` (see the module docstring)."""
    return json.dumps(finite_or_none(value), allow_nan=False, default=float, **kwargs)
