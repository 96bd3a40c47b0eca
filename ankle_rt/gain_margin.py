"""Accepting a gain set of the impedance controller with the joint-torque loop: the closed loop must
keep :data:`ankle_rt.analysis.REQUIRED_GAIN_MARGIN_DB` over cable stiffness +-30 %, the friction
range and foot free and held (:func:`ankle_rt.analysis.gain_set_margin_db`), render a passive impedance
(:mod:`ankle_rt.passivity`) and not ring on the sensors' noise, at load (the config loader) and at run
time (``set_gains``: the target and every checked point of the ramp to it).
Outside :mod:`ankle_rt.control` so the config loader can use it without an import circle.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

from ankle_rt.loop_setup import rate_from_encoders

RAMP_CHECK_POINTS = 8    # a gain ramp is checked at this many evenly spaced points, its end included
# The most of safety.oscillation_rms_a the strain gauges' noise may make of a set value at rest: the detector
# must not trip on the loop's own noise (the step-tuned loop of docs/daemon.md's sixth pass, 1.1 A in the
# model, tripped it at 1 A), nor the noise hide half of what it watches for.
MAX_NOISE_SHARE = 0.5


def gain_set_refusal(cfg: Mapping[str, Any], gains: Mapping[str, float], ff_viscous: float = 0.0, *,
                     noise: bool = True) -> tuple[str, str] | None:
    """(gain name, reason) when the closed loop with ``gains`` in place of the config's (and the friction
    feed-forward's viscous slope ``ff_viscous``, N m s/rad) keeps less than the required gain margin
    over the plant range (:func:`ankle_rt.analysis.gain_set_margin_db`), renders an impedance that is not
    passive (:func:`passivity_refusal`) or, with ``noise``, makes too much current of the gauges' noise
    (:func:`noise_refusal`); None when it keeps all three."""
    import numpy as np

    from ankle_rt.analysis import REQUIRED_GAIN_MARGIN_DB, gain_set_margin_db

    try:
        with np.errstate(all="ignore"):
            margin, name = gain_set_margin_db(cfg, gains, ff_viscous=ff_viscous)
            passivity = passivity_refusal(cfg, gains, ff_viscous) if name is None else None
    except (np.linalg.LinAlgError, ValueError, ZeroDivisionError, OverflowError) as exc:
        # degenerate physical parameters (a cable stiffness or lever of 1e-300): not provably stable
        name = next(iter(gains), "kp_dp")
        return name, (f"{name}: the gain set cannot be shown stable: the closed-loop model of this plant "
                      f"fails ({type(exc).__name__}: {exc}); check the physical parameters")
    if name is None:
        return passivity or (noise_refusal(cfg, gains) if noise else None)
    c = cfg["controller"]
    value = gains.get(name, c["torque_loop"].get(name, c["impedance"].get(name)))
    how = ("is unstable in some case (at its gains, or with its correction clamped by max_correction)"
           if margin == -math.inf else f"keeps only {margin:.1f} dB of gain margin")
    ff = f" with the friction feed-forward's viscous {ff_viscous:g} N m s/rad" if ff_viscous > 0.0 else ""
    return name, (f"{name} {value:g}: the closed loop{ff} {how} over cable stiffness +/-30 %, the friction range "
                  f"and foot free and held (at least {REQUIRED_GAIN_MARGIN_DB:g} dB required; docs/daemon.md)")


def passivity_refusal(cfg: Mapping[str, Any], gains: Mapping[str, float],
                      ff_viscous: float = 0.0) -> tuple[str, str] | None:
    """(gain name, reason) when the impedance the loop with ``gains`` renders gives energy back to the foot
    on an axis (:func:`ankle_rt.passivity.least_rendered_damping`); None when it is passive. Named: a
    torque-loop gain ``gains`` moves whose configured value makes it passive, else the axis's damping
    (``kd`` for the motor-side PD) with the least that makes it passive up to its ``controller.gain_limits``."""
    from ankle_rt.analysis import AXES, gain_set_loop
    from ankle_rt.params import PlantParams
    from ankle_rt.passivity import least_rendered_damping

    p = PlantParams.from_config(cfg)

    def least(g: Mapping[str, float]):
        return least_rendered_damping(p, gain_set_loop(cfg, g, ff_viscous=ff_viscous))

    rendered = least(gains)
    axis = next((a for a, d in enumerate(rendered) if not d.passive), None)
    if axis is None:
        return None
    ctl = cfg["controller"]
    found = rendered[axis].where()
    pd = ctl["type"] == "pd"
    tl = {} if pd else ctl["torque_loop"]
    moved = next((k for k, v in gains.items() if k in tl and tl[k] != v and least({**gains, k: tl[k]})[axis].passive),
                 None)
    if moved is not None:
        return moved, (f"{moved} {gains[moved]:g}: the impedance the loop renders with it is not passive on "
                       f"{AXES[axis].upper()} ({found}: it gives energy back to the foot); with the configured "
                       f"{tl[moved]:g} it is (docs/daemon.md \"Passivity\")")
    name = "kd" if pd else f"damping_{AXES[axis]}"
    section = ctl[ctl["pd_gains"] + "_gains"] if pd else ctl["impedance"]
    value, ceiling = float(gains.get(name, section[name])), float(ctl["gain_limits"]["kd" if pd else "damping"])
    what = "the motor-side PD" if pd else f"the impedance (stiffness_{AXES[axis]} " \
        f"{float(gains.get('stiffness_' + AXES[axis], section['stiffness_' + AXES[axis]])):g})"
    head = (f"{name} {value:g}: {what} as the loop renders it is not passive on {AXES[axis].upper()} ({found}: "
            f"it gives energy back to the foot)")
    if value >= ceiling or not least({**gains, name: ceiling})[axis].passive:
        return name, (f"{head}, and no {name} up to controller.gain_limits ({ceiling:g}) makes it so: lower the "
                      f"stiffness or change the torque loop (docs/daemon.md \"Passivity\")")
    lo, hi = value, ceiling
    while hi - lo > max(1e-3, 0.01 * hi):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if least({**gains, name: mid})[axis].passive else (mid, hi)
    return name, f"{head}; passive from {name} {hi:.3g} (docs/daemon.md \"Passivity\")"


def noise_refusal(cfg: Mapping[str, Any], gains: Mapping[str, float]) -> tuple[str, str] | None:
    """(gain name, reason) when the joint-torque loop with ``gains`` turns the sensors' noise into more
    set-value RMS than MAX_NOISE_SHARE x ``safety.oscillation_rms_a`` (:func:`ankle_rt.analysis.gain_set_noise_a`,
    the larger motor, foot free); None when it does not."""
    import numpy as np

    from ankle_rt.analysis import gain_set_noise_a

    with np.errstate(all="ignore"):      # an unstable loop's sum overflows to nan: handled below, as the margin's
        noise, name = gain_set_noise_a(cfg, gains)
    most = MAX_NOISE_SHARE * cfg["safety"]["oscillation_rms_a"]
    if noise <= most or not math.isfinite(noise):   # an unstable loop has no noise figure: the margin checks name it
        return None
    value = gains.get(name, cfg["controller"]["torque_loop"][name])
    advice = (", or with joint encoders take the rate from them (torque_rate_source: encoders)"
              if not rate_from_encoders(cfg["controller"]["torque_loop"]) else "")
    return name, (f"{name} {value:g}: the joint-torque loop turns the strain gauges' noise (sensors.strain_gauge_noise_rms "
                  f"{cfg['sensors']['strain_gauge_noise_rms']:g} N m) and the encoders' counts into {noise:.2f} A RMS of "
                  f"set value at rest, above {most:.2f} A ({MAX_NOISE_SHARE:g} x safety.oscillation_rms_a: the "
                  f"oscillation detector would trip on it); lower kp, torque_rate or the torque filter's cutoff{advice} "
                  f"(docs/daemon.md)")


def ramp_refusal(cfg: Mapping[str, Any], start: Mapping[str, float], end: Mapping[str, float],
                 ff_viscous: float = 0.0) -> tuple[str, str] | None:
    """:func:`gain_set_refusal` at RAMP_CHECK_POINTS evenly spaced points of the linear ramp from the
    gains ``start`` to ``end`` (the end first), naming the point of the ramp that fails."""
    for k in range(RAMP_CHECK_POINTS, 0, -1):
        f = k / RAMP_CHECK_POINTS
        point = {n: start[n] + f * (end[n] - start[n]) for n in end}
        bad = gain_set_refusal(cfg, point, ff_viscous)
        if bad is not None:
            return bad if k == RAMP_CHECK_POINTS else (bad[0], f"at {f:.0%} of the ramp: {bad[1]}")
    return None
