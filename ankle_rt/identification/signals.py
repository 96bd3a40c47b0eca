"""Signal helpers shared by the estimators: velocities from quantised encoder angles, and runs of a
boolean mask. Numpy only."""

from __future__ import annotations

import numpy as np

from ankle_rt.interchange import InterchangeError, Recording


class IdentificationError(ValueError):
    """The data does not contain what the requested experiment needs (names the column and what is missing)."""


def motor_channel(rec: Recording, motor: int, kt: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t s, motor angle rad, motor torque N m) of motor 1 or 2; the torque is the set value held
    from each row's time to the next (docs/design.md timing)."""
    name = f"motor_pos_{motor}"
    if name not in rec:
        raise InterchangeError(f"motor {motor} requested but the file has no such column", rec.source, name, 0)
    torque = rec.motor_input(kt)
    return rec["t"], rec[name], torque[:, motor - 1]


def input_column(rec: Recording, motor: int) -> str:
    """Name of motor 1's or 2's input column in ``rec`` (current set value or torque), for messages."""
    return ("current_cmd_" if rec.input_kind == "current" else "motor_torque_") + str(motor)


def centred_velocity(t: np.ndarray, pos: np.ndarray, half_window_s: float) -> np.ndarray:
    """rad/s: (pos[k+w] - pos[k-w]) / (t[k+w] - t[k-w]), w samples = half_window_s; one-sided at the ends.
    Averaging over the window turns encoder quantisation into a small, unbiased error."""
    n = len(t)
    dt = float(np.median(np.diff(t)))
    w = max(1, int(round(half_window_s / dt)))
    hi = np.minimum(np.arange(n) + w, n - 1)
    lo = np.maximum(np.arange(n) - w, 0)
    return (pos[hi] - pos[lo]) / (t[hi] - t[lo])


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index pairs of the runs of True in ``mask``."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]
