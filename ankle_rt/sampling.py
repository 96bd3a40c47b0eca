"""Does a recording's sampling and units fit the device? Checked before any fitting.

A file can follow the interchange format to the letter and still be wrong for the tools: time in ms
rather than s, angles in degrees rather than rad, a gap of 400 ms where the logger stalled, a time
base that wanders. Fitting such data gives a confident wrong answer (a "Stribeck effect" that is
really a unit error), so :func:`check_sampling` refuses it with an :class:`InterchangeError` naming
the column and what looks wrong, and returns warnings (strings) for what is odd but usable.

Without a configuration only what holds for any recording of this device is checked (a gap, an
irregular time base, a sample period slower than 10 Hz). With one, the values are also compared with
its limits: the sample period with ``controller.rate_hz``, motor speeds with
``safety.max_motor_speed_rad_s``, angles with ``limits.ankle_range_deg``, strain-gauge torques with
``safety.sg_rail_nm``, currents with ``amplifier.current_limit_peak``.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ankle_rt.interchange import InterchangeError, Recording

GAP_FACTOR = 5.0
"""A time step this many times the median period is a gap (lost samples): refused."""
BUNCHED = 0.1
"""More than this share of the steps over GAP_FACTOR x the median is no gap but a time base in bunches: refused."""
JITTER_WARN = 0.1
"""Warn when more than 1 % of the time steps deviate from the median period by more than this fraction."""
SLOWEST_PERIOD_S = 0.1
"""No recording of a 250-2000 Hz loop samples slower than 10 Hz: time in ms (or worse)."""
PERIOD_REFUSE, PERIOD_WARN = 10.0, 2.0
"""Refuse a median period off the configured one by more than this factor (either way); warn beyond the second."""
MARGIN = 1.5
"""How far beyond a configured limit a recorded value may go before the unit is called wrong."""


def check_sampling(rec: Recording, cfg: Mapping[str, Any] | None = None, *, gaps_masked: bool = False) -> list[str]:
    """Refuse (InterchangeError naming the column) or warn (returned strings) about ``rec``'s time
    base and units; see the module docstring. ``gaps_masked``: the caller masks the samples around each
    gap (the diagnosis' screening does, and warns), so a gap is not refused: a loop that overran on a busy
    computer logs a few cycles' gaps, and its record is still evidence. A time base in bunches still is."""
    src = rec.source
    t = np.asarray(rec["t"], dtype=float)
    warnings: list[str] = []
    if len(t) < 2:
        return warnings
    dt = np.diff(t)
    period = float(np.median(dt))
    if period > SLOWEST_PERIOD_S:
        raise InterchangeError(f"median sample period {period:g} s is slower than 10 Hz: is time in ms "
                               "rather than s?", src, "t")
    bunched = float(np.mean(dt > GAP_FACTOR * period))
    if bunched > BUNCHED:
        raise InterchangeError(f"time stamps come in bunches: {100 * bunched:.0f} % of the steps are over "
                               f"{GAP_FACTOR:g} x the median step {period:.4g} s (rows logged twice, or stamps in "
                               f"pairs?)", src, "t")
    worst = int(np.argmax(dt))
    if dt[worst] > GAP_FACTOR * period and not gaps_masked:
        raise InterchangeError(f"time gap of {dt[worst]:.4g} s ({dt[worst] / period:.0f} sample periods of "
                               f"{period:.4g} s): samples are missing", src, "t", worst + 2)
    irregular = np.mean(np.abs(dt - period) > JITTER_WARN * period)
    if irregular > 0.01:
        warnings.append(f"{src}: column 't': irregular time base ({100 * irregular:.1f} % of the steps differ "
                        f"from the median period {period:.4g} s by more than {100 * JITTER_WARN:g} %)")
    if cfg is not None:
        warnings += _check_against_config(rec, cfg, dt, period)
    return warnings


def _check_against_config(rec: Recording, cfg: Mapping[str, Any], dt: np.ndarray, period: float) -> list[str]:
    src = rec.source
    warnings = []
    configured = 1.0 / cfg["controller"]["rate_hz"]
    ratio = period / configured
    hint = "time in ms rather than s?" if ratio > 1 else "time not in s?"
    if not 1.0 / PERIOD_REFUSE <= ratio <= PERIOD_REFUSE:
        raise InterchangeError(f"median sample period {period:.4g} s is {ratio:.3g} x the configured "
                               f"{configured:g} s (controller.rate_hz): {hint}", src, "t")
    if not 1.0 / PERIOD_WARN <= ratio <= PERIOD_WARN:
        warnings.append(f"{src}: column 't': median sample period {period:.4g} s differs from the configured "
                        f"{configured:g} s (controller.rate_hz) by {ratio:.3g} x")
    speed_limit = MARGIN * cfg["safety"]["max_motor_speed_rad_s"]
    for name in ("motor_pos_1", "motor_pos_2"):
        if name in rec:
            # over each step's own time where a gap makes it longer (not shorter: a stamp's jitter is no faster motion)
            speed = np.abs(np.diff(rec[name])) / np.maximum(dt, period)
            k = int(np.argmax(speed))
            if speed[k] > speed_limit:
                raise InterchangeError(f"motor speed {speed[k]:.4g} rad/s between samples is beyond "
                                       f"{speed_limit:.4g} rad/s ({MARGIN:g} x safety.max_motor_speed_rad_s): "
                                       "angles in degrees or counts rather than rad?", src, name, k + 2)
    limits = (
        (("ankle_dp", "ankle_ie", "ref_dp", "ref_ie"), MARGIN * np.radians(cfg["limits"]["ankle_range_deg"]),
         "limits.ankle_range_deg", "rad", "degrees rather than rad?"),
        (("sg_torque_dp", "sg_torque_ie"), MARGIN * cfg["safety"]["sg_rail_nm"], "safety.sg_rail_nm", "N m",
         "N mm or a wrong calibration?"),
        (("current_cmd_1", "current_cmd_2"), MARGIN * cfg["amplifier"]["current_limit_peak"],
         "amplifier.current_limit_peak", "A", "mA rather than A?"),
    )
    for names, bound, key, unit, question in limits:
        for name in names:
            if name in rec:
                values = np.abs(rec[name])
                k = int(np.argmax(values))
                if values[k] > bound:
                    raise InterchangeError(f"|value| {values[k]:.4g} {unit} is beyond {bound:.4g} {unit} "
                                           f"({MARGIN:g} x {key}): {question}", src, name, k + 1)
    return warnings
