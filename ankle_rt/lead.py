"""The impedance law's damping under the joint-torque loop: what the law must command on the motor rate so
the ankle renders the commanded damping. One function serves the daemon's law (ankle_rt.control.impedance)
and the sampled linear model (ankle_rt.analysis), so the margin check counts exactly what the law does. A
leaf module (element-wise: floats for one device, arrays over a batch).

The loop follows a desired torque as ``tau_des / (1 + s lag)`` (:func:`loop_lag`: its rate term acts on the
measured torque): on a spring K that is ``K lag`` of negative damping. And the law damps the motor
rate, which moves the cable's stretch as well as the ankle: with the ankle on the law's spring K in series
with the cable's ``k_c`` (at the ankle), only ``1 - K / k_c`` of the motor's motion is the ankle's. To first
order in frequency the foot-free loop renders ``Im Z / w = B_law (1 - K / k_c) - K lag``, so the law takes

    B_law = (B + K lag) / (1 - K / k_c)

(on IE at K 100, k_c 221 N m/rad, the old ``B + K lag`` rendered -0.25 N m s/rad for 0.25 with kd 0.35:
active). ``k_c`` is the configured cable's; the torque loop's stable set keeps K far below it
(ImpedanceLimits: 0.3 DP, 0.5 IE)."""

from __future__ import annotations

from ankle_rt.elementwise import Value


def loop_lag(kp: Value, kd: Value, filter_alpha: Value, dt: float) -> Value:
    """s: the loop's lag on a desired torque at low frequency. Its rate term ``kd`` (s) on the measured torque
    gives ``kd / (1 + kp)``; the loop tracks the *filtered* torque, so the torque itself leads by the
    filter's delay, ``dt (1 - a) / a`` for the sampled first-order low-pass of gain ``filter_alpha`` = a
    (0.3 ms at 230 Hz): the difference."""
    return kd / (1.0 + kp) - dt * (1.0 - filter_alpha) / filter_alpha


def law_damping(stiffness: Value, damping: Value, lag: Value, cable: float) -> Value:
    """N m s/rad on the ankle-side motor rate rendering ``damping`` (N m s/rad) with ``stiffness`` (N m/rad)
    under a loop of ``lag`` (s, :func:`loop_lag`) on a cable of ``cable`` N m/rad at the ankle."""
    return (damping + stiffness * lag) / (1.0 - stiffness / cable)
