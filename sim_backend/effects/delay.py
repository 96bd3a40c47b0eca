"""Actuation delay: the motor torque lags the command (amplifier, bus and filter latency)."""

from __future__ import annotations

import math

from ankle_rt.config import Section, non_negative
from sim_backend.effects.base import Effect, register_effect


@register_effect("delay")
class ActuationDelay(Effect):
    """The torque applied during a tick is the command of ``delay`` seconds earlier, linearly
    interpolated between ticks for a fractional delay. Uses a preallocated ring buffer."""

    PARAMS = Section({
        "delay": non_negative("s, actuation latency"),
    })
    cause = "delay"

    def __init__(self, params, plant, dt):
        super().__init__(params, plant, dt)
        ticks = params["delay"] / dt
        self.whole = int(math.floor(ticks))
        self.frac = ticks - self.whole
        self.size = self.whole + 2
        self.buf1 = [0.0] * self.size
        self.buf2 = [0.0] * self.size
        self.head = 0

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
        return ((1.0 - f) * self.buf1[a] + f * self.buf1[b],
                (1.0 - f) * self.buf2[a] + f * self.buf2[b])
