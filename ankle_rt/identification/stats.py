"""A value measured over repeats: mean, standard deviation and the individual results."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable


@dataclass(frozen=True)
class Measured:
    """``mean`` and sample standard deviation ``sd`` (ddof = 1; NaN from a single repeat) of ``values``.
    ``sd`` may instead be a regression standard error when ``note`` says so."""

    mean: float
    sd: float
    values: tuple[float, ...]
    note: str = ""

    @property
    def n(self) -> int:
        return len(self.values)

    def fmt(self, digits: int = 4) -> str:
        sd = "n/a" if math.isnan(self.sd) else f"{self.sd:.{digits}f}"
        return f"{self.mean:.{digits}f} ± {sd}"


def measured(values: Iterable[float], note: str = "") -> Measured:
    """Mean and sample SD of the repeats (NaN SD for a single value)."""
    vals = tuple(float(v) for v in values)
    if not vals:
        raise ValueError("no repeats to average")
    mean = sum(vals) / len(vals)
    sd = math.sqrt(sum((v - mean) ** 2 for v in vals) / (len(vals) - 1)) if len(vals) > 1 else math.nan
    return Measured(mean, sd, vals, note)
