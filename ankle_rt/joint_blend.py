"""The impedance law's ankle angle where joint encoders are read: theirs below a crossover frequency, the
estimate through the cables (motor encoders minus the measured stretch) above it.

Why: the joint encoders see what the cables hide (slack, backlash, a stretch the gauges misread), which
the law needs at standstill and in slow motion. But a law on the joint angle alone closes its fast loop
from the motors through the cables to the foot: where a cable goes slack (backlash around zero load) the
motor is no longer held by the gauges' torque feedback and that loop, non-collocated through a soft
spring, limit-cycles (12-14 Hz, +-0.26 deg at zero load with 0.2 mm backlash: docs/daemon.md). Above the
crossover the law acts on the motors' own angle, collocated, and that loop stays stable down to a slack
cable. Off by default (``controller.impedance.joint_crossover_hz`` 0): on a cable softer than configured the
estimate's error passes the crossover shifted in phase and the ankle gives energy back to the foot (x0.7, K
200 / 100: -0.115 J per 2 Hz cycle at a 2 Hz crossover; docs/daemon.md). One function serves the daemon's law (ankle_rt.control.impedance) and the sampled linear model
(ankle_rt.analysis). A leaf module (element-wise: floats for one device, arrays over a batch, rows of a
matrix in the model)."""

from __future__ import annotations

import math
from typing import TypeVar

V = TypeVar("V")


def law_crossover_hz(configured_hz: float, torque_loop: bool) -> float:
    """Hz: the crossover the law runs (``controller.impedance.joint_crossover_hz``), 0 (the joint encoders
    alone) without the joint-torque loop: there nothing amplifies the law's torque when a cable goes slack,
    and on the joint encoders alone it stays stable down to x0.02 of the cable (K 200 / 100, linear model),
    while the estimate above a crossover would bring a cable stiffer than configured into the law (x1.3,
    foot held: 5.7 dB of margin at 1 Hz against 22 on the joint encoders)."""
    return configured_hz if torque_loop else 0.0


def crossover_alpha(crossover_hz: float, dt: float) -> float:
    """The per-cycle gain of the first-order low-pass at ``crossover_hz`` (period ``dt`` s); 1 for 0 Hz:
    the joint encoders alone, at every frequency."""
    return 1.0 if crossover_hz <= 0.0 else 1.0 - math.exp(-2.0 * math.pi * crossover_hz * dt)


def blended_angle(estimate: V, joint: V, lead: V, alpha: float) -> tuple[V, V]:
    """(angle, lead) rad: the law's angle from the ``estimate`` through the cables and the ``joint``
    encoders' angle, and the new ``lead`` (the low-passed joint-minus-estimate, the state kept per cycle)."""
    # lead + alpha (joint - estimate - lead), written so that alpha 1 gives the joint encoders' angle exactly
    angle = joint - (1.0 - alpha) * (joint - estimate - lead)
    return angle, angle - estimate
