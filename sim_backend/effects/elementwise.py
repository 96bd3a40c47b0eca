"""Element-wise maths for laws written once for one plant (plain floats) and for a batch of plants
(numpy arrays over the batch, :mod:`sim_backend.batch`).

A float goes to :mod:`math` (the single plant's hot path stays on fast scalar calls); anything else
to numpy. An effect whose hooks use only arithmetic and these functions declares
``Effect.elementwise = True`` and a batch calls each hook once for all its plants.
"""

from __future__ import annotations

import math

import numpy as np

_tanh, _exp, _sin = math.tanh, math.exp, math.sin


def tanh(x):
    return _tanh(x) if x.__class__ is float else np.tanh(x)


def exp(x):
    return _exp(x) if x.__class__ is float else np.exp(x)


def sin(x):
    return _sin(x) if x.__class__ is float else np.sin(x)


def absolute(x):
    return abs(x)   # abs() is numpy's absolute on arrays


def clip(x, low, high):
    """``x`` limited to [low, high] (bounds broadcast over the batch)."""
    if x.__class__ is float:
        return low if x < low else (high if x > high else x)
    return np.minimum(np.maximum(x, low), high)


def select(condition, if_true, if_false):
    """``if_true`` where ``condition`` holds, else ``if_false``."""
    if condition.__class__ is bool:
        return if_true if condition else if_false
    return np.where(condition, if_true, if_false)


def positive_part(x):
    """max(x, 0)."""
    if x.__class__ is float:
        return x if x > 0.0 else 0.0
    return np.maximum(x, 0.0)


def pick(buffer, index):
    """``buffer[index]`` of a ring buffer: one slot for one plant; for a batch, ``buffer`` is
    (slots, plants) and ``index`` one slot per plant."""
    if index.__class__ is int:
        return buffer[index]
    return buffer[index, np.arange(index.size)]


def stack(objects):
    """One object of the same class standing for ``objects`` (one per plant of a batch): every
    number becomes an array over the batch, anything else is taken from the first object."""
    first = objects[0]
    out = object.__new__(type(first))
    for name, value in vars(first).items():
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = np.array([getattr(o, name) for o in objects], dtype=float)
        setattr(out, name, value)
    return out
