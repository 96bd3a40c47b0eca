"""Strict JSON for the commands' output and the daemon's replies, so any parser reads it
(``json.dumps`` would write NaN and Infinity, which are not JSON); a value that does not exist is
``null``."""

from __future__ import annotations

import json
import math
from typing import Any


def finite_or_none(value: Any) -> Any:
    """``value`` in plain JSON types, recursively: every NaN or infinite float becomes None, numpy
    scalars and arrays plain numbers and lists."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(v) for v in value]
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return finite_or_none(value.tolist())
    return value


def dumps(value: Any, **kwargs: Any) -> str:
    """Strict JSON text of ``value`` (see the module docstring)."""
    return json.dumps(finite_or_none(value), allow_nan=False, default=float, **kwargs)
