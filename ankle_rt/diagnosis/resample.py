"""Irregular sample times onto the uniform grid the diagnosis' filters and differences assume.

A loop without real-time scheduling logs jittered periods: the filters, finite differences and lags of
:mod:`ankle_rt.diagnosis.signals` take every period as the median one, so the acceleration and the held
torque's timing are off where the period is, and the catch-all's torque-history columns fit that error
(a spurious ``unknown``). Such records are put on the median-period grid from the logged instants: the
set values (current commands, motor torques), held from their stamp to the next (what the amplifier
applied), averaged over each grid period; the measured columns interpolated linearly. Gaps stay masked: a
grid row is usable only where both logged samples around it are (the screening's mask, found on the logged
instants).
"""

from __future__ import annotations

import numpy as np

from ankle_rt.interchange import Recording
from ankle_rt.diagnosis.screening import GAP_FACTOR

#: sample periods spread (robust sd, gaps left out) above this share of the median: the stamps are
#: irregular and the record is re-sampled; a real-time loop's timer jitter stays far below it
JITTER_SHARE = 0.01
#: columns the controller sets and holds over the period (zero-order hold)
HELD_PREFIXES = ("current_cmd", "motor_torque")
#: s, a time gap longer than this is left out of the uniform grid (its rows would all be masked)
GRID_GAP_S = 1.0


def period_spread(t: np.ndarray) -> float:
    """Robust sd of the sample periods (gaps left out) / their median."""
    d = np.diff(t)
    dt = float(np.median(d))
    regular = d[d <= GAP_FACTOR * dt]
    return float(1.4826 * np.median(np.abs(regular - dt)) / dt) if regular.size else 0.0


def to_uniform_grid(rec: Recording, good: np.ndarray) -> tuple[Recording, np.ndarray, str | None]:
    """(``rec`` on its median-period grid, its usable rows, a note) when the stamps are irregular, else
    ``rec`` and ``good`` unchanged with no note. ``good`` is the screening's mask on the logged rows."""
    t = np.asarray(rec["t"], dtype=float)
    spread = period_spread(t)
    if spread <= JITTER_SHARE:
        return rec, good, None
    dt = rec.dt
    # the grid skips a time gap longer than GRID_GAP_S (masked anyway, its rows stand for nothing): a
    # record with a day's gap would otherwise get 86 M grid rows at 1 kHz, a MemoryError
    cuts = np.flatnonzero(np.diff(t) > max(GRID_GAP_S, GAP_FACTOR * dt)) + 1
    first = np.floor((t[np.r_[0, cuts]] - t[0]) / dt + 1e-9).astype(np.int64)
    last = np.floor((t[np.r_[cuts - 1, len(t) - 1]] - t[0]) / dt + 1e-9).astype(np.int64)
    tu = t[0] + dt * np.concatenate([np.arange(a, b + 1) for a, b in zip(first, last)]).astype(float)
    k = np.clip(np.searchsorted(t, tu, side="right") - 1, 0, len(t) - 2)   # logged period holding each row
    cols = {"t": tu}
    for name, x in rec.columns.items():
        if name != "t":
            cols[name] = held_mean(t, x, tu, dt) if name.startswith(HELD_PREFIXES) else np.interp(tu, t, x)
    note = (f"{rec.source}: irregular sample times (period spread {100 * spread:.1f} % of the median "
            f"{1e3 * dt:.3g} ms): re-sampled onto a uniform grid (set values averaged as held over each period, "
            "measurements interpolated)")
    return Recording(cols, rec.source, dict(rec.extra)), good[k] & good[k + 1], note


def held_mean(t: np.ndarray, x: np.ndarray, tu: np.ndarray, dt: float) -> np.ndarray:
    """The mean over each grid period [tu, tu + dt) of ``x`` held from each stamp ``t`` to the next: what
    the amplifier applied over the period the grid row stands for. Taking the value held at tu instead
    gives a row the period before's set value wherever the loop woke late (the set value changed just
    after tu): a latency of up to a period on a random part of the rows, which the catch-all's
    torque-history columns fitted as `unknown` (generator D's late ticks, 0-0.4 ms at 1 kHz)."""
    x = np.asarray(x, dtype=float)
    area = np.concatenate([[0.0], np.cumsum(x[:-1] * np.diff(t))])     # integral of the held x up to each stamp

    def integral(at: np.ndarray) -> np.ndarray:
        i = np.clip(np.searchsorted(t, at, side="right") - 1, 0, len(t) - 1)
        return area[i] + x[i] * (at - t[i])

    return (integral(tu + dt) - integral(tu)) / dt


#: measured columns a stale row repeats (a sensor bridge that re-sent its previous sample)
MEASURED = ("motor_pos_1", "motor_pos_2", "sg_torque_dp", "sg_torque_ie", "ankle_dp", "ankle_ie")


def repair_stale_rows(rec: Recording) -> tuple[Recording, str | None]:
    """(``rec`` with its stale rows re-interpolated, a note). A row is stale when every measured column
    repeats the row before while a motor's count changes on both sides of it: a moving motor and noisy
    gauges never repeat all at once, a bridge re-sending its last sample does. Left in, each one is a step
    and back in the second difference of the angle, a torque spike the fits read as an effect (generator
    D: a Stribeck term lost); masked, each would take the filter's reach with it. Its true values lie
    between its neighbours: interpolated linearly in time. Unchanged (no note) when there is none, or
    without strain gauges: a slow motor's count alone repeats between two changes by nature (generator A's
    actuator records)."""
    cols = [c for c in MEASURED if c in rec]
    motors = [c for c in ("motor_pos_1", "motor_pos_2") if c in rec]
    if len(rec) < 4 or not motors or not any(c.startswith("sg_") for c in cols):
        return rec, None
    X = np.column_stack([rec[c] for c in cols])
    same = np.all(X[1:-1] == X[:-2], axis=1)
    P = np.column_stack([rec[c] for c in motors])
    moving = np.any((P[:-2] != np.r_[P[:1], P[:-3]]) & (P[2:] != P[1:-1]), axis=1)
    stale = np.flatnonzero(same & moving) + 1
    stale = stale[(stale > 1) & (stale < len(rec) - 1)]
    if not stale.size:
        return rec, None
    keep = np.ones(len(rec), dtype=bool)
    keep[stale] = False
    t = np.asarray(rec["t"], dtype=float)
    out = dict(rec.columns)
    for c in cols:
        x = np.array(rec[c], dtype=float)
        x[stale] = np.interp(t[stale], t[keep], x[keep])
        out[c] = x
    note = (f"{rec.source}: {stale.size} stale row(s) ({100 * stale.size / len(rec):.2f} %: every measurement "
            "repeats the row before while a motor moves): re-interpolated from their neighbours")
    return Recording(out, rec.source, dict(rec.extra)), note
