"""Element-wise maths for laws written once for one device (plain floats) and for a batch of devices
(numpy arrays over the batch: :mod:`sim_backend.batch`, :mod:`ankle_rt.sweep.cycle`).

A scalar (float, or a numpy scalar such as the daemon's float64 set values) goes to :mod:`math` and
plain comparisons, so the single device's hot path stays on fast scalar calls; an array to numpy.
Users: the simulator's effects (``Effect.elementwise = True``: a batch calls each hook once for all
its plants), the joint-torque loop and the friction feed-forward (the batched daemon cycle runs the
daemon's own code on arrays).
"""

from __future__ import annotations

import math
from typing import Union

import numpy as np

_tanh, _exp, _sin = math.tanh, math.exp, math.sin
_ARRAY = np.ndarray

Value = Union[float, np.ndarray]     # a float for one device, an array over a batch


def tanh(x):
    return np.tanh(x) if x.__class__ is _ARRAY else _tanh(x)


def exp(x):
    return np.exp(x) if x.__class__ is _ARRAY else _exp(x)


def sin(x):
    return np.sin(x) if x.__class__ is _ARRAY else _sin(x)


def clip(x, low, high):
    """``x`` limited to [low, high] (bounds broadcast over the batch)."""
    if x.__class__ is _ARRAY or low.__class__ is _ARRAY:
        return np.minimum(np.maximum(x, low), high)
    return low if x < low else (high if x > high else x)


def select(condition, if_true, if_false):
    """``if_true`` where ``condition`` holds, else ``if_false``."""
    if condition.__class__ is _ARRAY:
        return np.where(condition, if_true, if_false)
    return if_true if condition else if_false


def positive_part(x):
    """max(x, 0)."""
    if x.__class__ is _ARRAY:
        return np.maximum(x, 0.0)
    return x if x > 0.0 else 0.0


def pick(buffer, index):
    """``buffer[index]`` of a ring buffer: one slot for one plant; for a batch, ``buffer`` is
    (slots, plants) and ``index`` one slot per plant."""
    if index.__class__ is _ARRAY:
        return buffer[index, np.arange(index.size)]
    return buffer[index]


def lookup(table, position):
    """Linear interpolation in ``table`` (a 1-D numpy array of samples at 0, 1, 2, ...) at
    ``position`` (0 <= position < len(table) - 1; an array of positions over a batch)."""
    if position.__class__ is _ARRAY:
        i = position.astype(np.intp)
        lo = table[i]
        return lo + (position - i) * (table[i + 1] - lo)
    i = int(position)
    lo = table.item(i)
    return lo + (position - i) * (table.item(i + 1) - lo)


def stack(objects, shared: tuple[str, ...] = (), tables: tuple[str, ...] = ()):
    """One object of the same class standing for ``objects`` (one per plant of a batch): every
    number becomes an array over the batch; anything else must be equal on every object (else
    ValueError: the caller runs them one by one), except the ``shared`` attributes, which are
    descriptive only and taken from the first object, and the ``tables`` (a sequence of numbers per
    object, read with :func:`pick`), which become (slots, plants) arrays."""
    first = objects[0]
    out = object.__new__(type(first))
    for name, value in vars(first).items():
        if name in tables:
            value = np.stack([np.asarray(getattr(o, name), dtype=float) for o in objects], axis=1)
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            value = np.array([getattr(o, name) for o in objects], dtype=float)
        elif name not in shared and not all(_equal(getattr(o, name), value) for o in objects[1:]):
            raise ValueError(f"{type(first).__name__}.{name} differs between plants and is not a number")
        setattr(out, name, value)
    return out


def _equal(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(a, b))
    try:
        return bool(a == b)
    except (TypeError, ValueError):
        return a is b
