"""The current limits of a maxon ESCON 50/5 in current mode, as the simulator applies them."""

from __future__ import annotations

from ankle_rt.params import AmplifierParams
from ankle_rt.elementwise import clip, positive_part, select

PEAK_DURATION_S = 20.0  # the ESCON 50/5 allows its peak current for < 20 s


class EsconCurrentLimit:
    """Clamps the set value to the peak current and, once the I^2 t budget of a 20 s peak is spent,
    to the continuous current until the budget recovers (the amplifier's thermal limiting)."""

    def __init__(self, p: AmplifierParams, dt: float):
        self.i_cont = p.current_limit_continuous
        self.i_peak = p.current_limit_peak
        self.dt = dt
        self.budget = (self.i_peak ** 2 - self.i_cont ** 2) * PEAK_DURATION_S  # A^2 s
        self.i_cont2 = self.i_cont * self.i_cont   # A^2
        self.used = 0.0

    def reset(self) -> None:
        self.used = 0.0

    def apply(self, current: float) -> float:
        """A: the current the amplifier actually drives for the set value ``current`` (element-wise:
        a batch stacks one limiter per plant, :mod:`sim_backend.batch`)."""
        used = self.used
        limit = select(used >= self.budget, self.i_cont, self.i_peak)
        i = clip(current, -limit, limit)
        self.used = positive_part(used + (i * i - self.i_cont2) * self.dt)
        return i
