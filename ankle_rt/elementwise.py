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


def minimum(x, high):
    """min(x, high)."""
    if x.__class__ is _ARRAY or high.__class__ is _ARRAY:
        return np.minimum(x, high)
    return x if x < high else high


def all_true(condition) -> bool:
    """Whether ``condition`` holds (for a batch: on every device). A plain bool, to branch on."""
    if condition.__class__ is _ARRAY:
        return bool(condition.all())
    return bool(condition)


def any_true(condition) -> bool:
    """Whether ``condition`` holds (for a batch: on some device). A plain bool, to branch on."""
    if condition.__class__ is _ARRAY:
        return bool(condition.any())
    return bool(condition)


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


def outside(x, buffer):
    """How far ``x`` lies outside the range of a ring buffer's values: x - max above it, x - min
    below it, 0 within. One plant: a number and a list; a batch: one value per plant and
    (slots, plants)."""
    if buffer.__class__ is _ARRAY:
        return x - np.minimum(np.maximum(x, buffer.min(axis=0)), buffer.max(axis=0))
    low = min(buffer)
    if x < low:
        return x - low
    high = max(buffer)
    return x - high if x > high else 0.0


def fill(buffer, value: float, where=True) -> None:
    """Every slot of a ring buffer set to ``value``, in place; for a batch ((slots, plants)), only
    the plants where ``where`` (bool per plant) holds."""
    if buffer.__class__ is _ARRAY:
        buffer[:, where] = value
    elif where:
        for i in range(len(buffer)):
            buffer[i] = value


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


def stack(objects, shared: tuple[str, ...] = (), columns: tuple[str, ...] = (), tables: tuple[str, ...] = ()):
    """One object of the same class standing for ``objects`` (one per plant of a batch): every
    number becomes an array over the batch; each ``columns`` attribute (a list or tuple of numbers
    per object, e.g. a matrix's entries) a list or tuple of such arrays; each ``tables`` attribute
    (a sequence of numbers per object, read with :func:`pick`) a (slots, plants) array; an attribute
    that is itself stackable (its class has ``stack``) is stacked by it; a flag (bool) stays a plain
    bool where it is the same on every object (code may branch on it) and becomes a bool array where
    it differs; anything else must be equal on every object (else ValueError: the caller runs them
    one by one), except the ``shared`` attributes, which are taken from the first object: descriptive
    only, or moving in step for the whole batch (a ring buffer's length and head)."""
    first = objects[0]
    out = object.__new__(type(first))
    owner = type(first).__name__
    for name, value in vars(first).items():
        values = [getattr(o, name) for o in objects]
        if name in columns or name in tables:
            if any(len(v) != len(value) for v in values):
                raise ValueError(f"{owner}.{name} differs in length between plants")
            if name in tables:
                value = np.stack([np.asarray(v, dtype=float) for v in values], axis=1)
            else:
                value = type(value)(np.array(column, dtype=float) for column in zip(*values))
        elif name not in shared:
            value = _stacked(owner, name, values)
        setattr(out, name, value)
    return out


def _stacked(owner: str, name: str, values: list):
    value = values[0]
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return np.array(values, dtype=float)
    if isinstance(value, bool) and all(isinstance(v, bool) for v in values):
        return value if all(v == value for v in values) else np.array(values)
    if hasattr(type(value), "stack") and all(type(v) is type(value) for v in values):
        return type(value).stack(values)
    if not all(_equal(v, value) for v in values[1:]):
        raise ValueError(f"{owner}.{name} differs between plants and is not a number")
    return value


def _equal(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(a, b))
    try:
        return bool(a == b)
    except (TypeError, ValueError):
        return a is b
