"""Irregular sample times onto the uniform grid the diagnosis' filters and differences assume.

A loop without real-time scheduling logs jittered periods: the filters, finite differences and lags of
:mod:`ankle_rt.diagnosis.signals` take every period as the median one, so the acceleration and the held
torque's timing are off where the period is, and the catch-all's torque-history columns fit that error
(a spurious ``unknown``). Such records are put on the median-period grid from the logged instants: the
set values (current commands, motor torques) as held from their stamp to the next (what the amplifier
applied), the measured columns interpolated linearly. Gaps stay masked: a grid row is usable only where
both logged samples around it are (the screening's mask, found on the logged instants).
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
    tu = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
    k = np.clip(np.searchsorted(t, tu, side="right") - 1, 0, len(t) - 2)   # logged period holding each row
    cols = {"t": tu}
    for name, x in rec.columns.items():
        if name != "t":
            cols[name] = x[k] if name.startswith(HELD_PREFIXES) else np.interp(tu, t, x)
    note = (f"{rec.source}: irregular sample times (period spread {100 * spread:.1f} % of the median "
            f"{1e3 * dt:.3g} ms): re-sampled onto a uniform grid (set values held, measurements interpolated)")
    return Recording(cols, rec.source, dict(rec.extra)), good[k] & good[k + 1], note
