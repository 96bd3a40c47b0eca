"""Actuation delay: the motor torque lags the command (amplifier, bus and filter latency)."""

from __future__ import annotations

import math

import numpy as np

from ankle_rt.config import Section, non_negative
from sim_backend.effects.base import Effect, register_effect
from ankle_rt.elementwise import pick


@register_effect("delay")
class ActuationDelay(Effect):
    """The torque applied during a tick is the command of ``delay`` seconds earlier, linearly
    interpolated between ticks for a fractional delay. Uses a preallocated ring buffer."""

    PARAMS = Section({
        "delay": non_negative("s, actuation latency"),
    })
    cause = "delay"
    elementwise = True

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        ticks = params["delay"] / dt
        self.whole = int(math.floor(ticks))
        self.frac = ticks - self.whole
        self.size = self.whole + 2
        self.buf1 = [0.0] * self.size
        self.buf2 = [0.0] * self.size
        self.head = 0

    @classmethod
    def stack(cls, effects):
        """Per-plant delays on one ring of the longest length: slots (ring, plants), ``whole`` an
        index array (any ring of at least whole + 2 slots gives the same output)."""
        out = object.__new__(cls)
        out.params, out.plant, out.dt = effects[0].params, effects[0].plant, effects[0].dt
        out.whole = np.array([e.whole for e in effects], dtype=int)
        out.frac = np.array([e.frac for e in effects])
        out.size = max(e.size for e in effects)
        out.buf1 = np.zeros((out.size, len(effects)))
        out.buf2 = np.zeros((out.size, len(effects)))
        out.head = 0
        return out

    def reset(self) -> None:
        for i in range(self.size):
            self.buf1[i] = self.buf2[i] = 0.0
        self.head = 0

    def command(self, tau1, tau2):
        size, head = self.size, self.head
        self.buf1[head] = tau1
        self.buf2[head] = tau2
        a = (head - self.whole) % size      # command of `whole` ticks ago
        b = (a - 1) % size                  # one tick older
        f = self.frac
        self.head = (head + 1) % size
        return ((1.0 - f) * pick(self.buf1, a) + f * pick(self.buf1, b),
                (1.0 - f) * pick(self.buf2, a) + f * pick(self.buf2, b))
