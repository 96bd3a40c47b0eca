"""The maxon ESCON 50/5 as the daemon drives it: current set value <-> analog voltage or PWM duty.

In current mode the ESCON reads its set value from an analog input (+/-10 V) or a PWM input (duty
10-90 %) and maps it linearly to a motor current. ESCON Studio stores that map as two points
("current at -10 V / +10 V", or "at 10 % / 90 %"); ``escon.amplifiers[i]`` in the config states the
same two points, so the daemon computes exactly the voltage or duty ESCON Studio expects
(docs/escon-setup.md says how to set it up). Per amplifier the config also holds:

- ``sign`` (+1/-1): whether a positive amplifier current turns the motor in the model's positive
  direction (motor wiring, mounting). ``ankle-rt calibrate`` checks it.
- ``offset`` (A): the current the amplifier drives at the nominal zero set value (DAC and input
  offset, measured); it is compensated.
- ``scale``: the measured current over the current the map promises (DAC reference and amplifier gain
  error, measured); it is compensated. The motor current is ``sign * (scale * map(value) + offset)``.
- enable and ready polarity (ESCON Studio: "Enable, high active", "Ready, high active").

The set value leaves the bridge or I/O module as an integer code: :class:`SetValueCode` is that
quantisation (a 12-bit bipolar DAC over +/-10 V: 10 V / 2048 = 4.88 mV per code, i.e. 7.32 mA per
code for the +/-15 A map; a PWM timer with ``pwm_counts`` per 100 %). Motor current in this module is
in the model's convention (positive = positive motor torque), in A.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ankle_rt.config import ConfigError
from hardware.config_values import required

ANALOG_RANGE_V = (-10.0, 10.0)      # the ESCON 50/5 analog set-value input
PWM_RANGE = (0.10, 0.90)            # the ESCON PWM set-value input: valid duty range (fraction)


@dataclass(frozen=True)
class SetValueCode:
    """Integer set-value codes: ``code = round(value / lsb)`` clamped to [code_min, code_max].

    ``value`` is in V (analog) or a duty fraction (PWM). A signed code keeps zero volts exactly
    representable; the bridge adds its DAC's mid-scale itself.
    """

    lsb: float          # V or duty fraction per code
    code_min: int
    code_max: int

    @classmethod
    def analog(cls, bits: int, full_scale_v: float = ANALOG_RANGE_V[1]) -> "SetValueCode":
        """A bipolar ``bits``-bit DAC over +/-``full_scale_v`` (two's complement codes)."""
        half = 1 << (bits - 1)
        return cls(full_scale_v / half, -half, half - 1)

    @classmethod
    def pwm(cls, counts_per_period: int) -> "SetValueCode":
        """A PWM timer with ``counts_per_period`` counts per 100 % duty, limited to 10-90 %."""
        return cls(1.0 / counts_per_period, math.ceil(PWM_RANGE[0] * counts_per_period),
                   math.floor(PWM_RANGE[1] * counts_per_period))

    def code(self, value: float) -> int:
        c = round(value / self.lsb)
        return self.code_min if c < self.code_min else (self.code_max if c > self.code_max else c)

    def value(self, code: int) -> float:
        return code * self.lsb


class EsconAmplifier:
    """One ESCON 50/5: the host's current <-> set value map and the emulator's amplifier model.

    ``code(i)`` is what the host sends for a motor current ``i``; ``current(code)`` is the motor
    current an amplifier configured like this one drives for ``code`` (the emulator's amplifier, and
    the host's record of what it actually commanded after quantisation). The two are inverse up to
    the quantisation of ``codec`` and the clamping to +/-``limit``.
    """

    def __init__(self, *, mode: str, current_at_min: float, current_at_max: float, sign: int,
                 offset: float, limit: float, codec: SetValueCode, scale: float = 1.0, enable_active_high: bool = True,
                 ready_active_high: bool = True, key: str = "escon.amplifiers", source: str | None = None):
        if mode not in ("analog", "pwm"):
            raise ConfigError(f"expected 'analog' or 'pwm', got {mode!r}", source, f"{key}.mode")
        if sign not in (-1, 1):
            raise ConfigError(f"expected 1 or -1, got {sign!r}", source, f"{key}.sign")
        self.mode = mode
        self.value_min, self.value_max = ANALOG_RANGE_V if mode == "analog" else PWM_RANGE
        if current_at_max == current_at_min:
            raise ConfigError("current_at_min and current_at_max must differ", source, f"{key}.current_at_max")
        self.current_at_min = current_at_min
        self.current_at_max = current_at_max
        self.slope = (current_at_max - current_at_min) / (self.value_max - self.value_min)  # A per V / per duty
        reach = min(abs(self._amp_current(self.value_min)), abs(self._amp_current(self.value_max)))
        if reach + 1e-9 < limit:
            raise ConfigError(f"the set-value map reaches only +/-{reach:g} A but amplifier.current_limit_peak "
                              f"is {limit:g} A: widen the map in ESCON Studio and here, or lower the limit",
                              source, f"{key}.current_at_max")
        if not scale > 0.0:
            raise ConfigError(f"must be > 0, got {scale!r}", source, f"{key}.scale")
        self.sign = sign
        self.offset = offset
        self.scale = scale
        self.limit = limit
        self.codec = codec
        self.enable_active_high = enable_active_high
        self.ready_active_high = ready_active_high
        self.current_lsb = abs(self.slope) * scale * codec.lsb     # A per code
        self.zero_code = self.code(0.0)

    # -- the linear map ESCON Studio is set to ---------------------------------------------------
    def _amp_current(self, value: float) -> float:
        """A, in the amplifier's own direction, for a set value (V or duty), before offset."""
        return self.current_at_min + (value - self.value_min) * self.slope

    def set_value(self, current: float) -> float:
        """V or duty fraction for the motor current ``current`` (A), clamped to +/-limit and the input range."""
        lim = self.limit
        i = lim if current > lim else (-lim if current < -lim else current)
        value = self.value_min + ((self.sign * i - self.offset) / self.scale - self.current_at_min) / self.slope
        return self.value_min if value < self.value_min else (self.value_max if value > self.value_max else value)

    def code(self, current: float) -> int:
        """The quantised set-value code for the motor current ``current`` (A)."""
        return self.codec.code(self.set_value(current))

    def current(self, code: int) -> float:
        """A: the motor current (model convention) this amplifier drives for ``code``."""
        c = self.codec
        code = c.code_min if code < c.code_min else (c.code_max if code > c.code_max else code)
        value = c.value(code)
        value = self.value_min if value < self.value_min else (self.value_max if value > self.value_max else value)
        return self.sign * (self.scale * self._amp_current(value) + self.offset)

    # -- digital lines ---------------------------------------------------------------------------
    def enable_level(self, enabled: bool) -> bool:
        """The electrical level of the enable line for ``enabled``."""
        return enabled == self.enable_active_high

    def is_enabled(self, level: bool) -> bool:
        """Whether the enable line's electrical ``level`` enables the amplifier (emulators)."""
        return level == self.enable_active_high

    def is_ready(self, level: bool) -> bool:
        """Whether the ready line's electrical ``level`` means ready (no fault)."""
        return level == self.ready_active_high

    def ready_level(self, ready: bool) -> bool:
        """The electrical level of the ready line for ``ready`` (emulators)."""
        return ready == self.ready_active_high


def enable_outputs(amps: tuple[EsconAmplifier, EsconAmplifier], bits: tuple[int, int], enabled: bool) -> int:
    """The digital-output word (``bits[k]``: amplifier k's enable line) that sets both enable lines
    to the electrical level for ``enabled``. Backends compute both words once, at configure."""
    return ((bits[0] if amps[0].enable_level(enabled) else 0)
            | (bits[1] if amps[1].enable_level(enabled) else 0))


def escon_amplifiers(cfg: dict, codec: SetValueCode | None = None) -> tuple[EsconAmplifier, EsconAmplifier]:
    """Both amplifiers from ``escon:`` and ``amplifier:`` of a validated config.

    ``codec`` overrides the bridge's quantisation (a CANopen I/O module has its own analog codes);
    by default it follows ``escon.dac_bits`` / ``escon.pwm_counts`` and each amplifier's mode.
    """
    amps = required(cfg, "escon.amplifiers", "the ESCON Studio set-value map and wiring of both amplifiers")
    esc = cfg["escon"]
    limit = cfg["amplifier"]["current_limit_peak"]
    out = []
    for i, a in enumerate(amps):
        c = codec or (SetValueCode.analog(esc["dac_bits"]) if a["mode"] == "analog"
                      else SetValueCode.pwm(esc["pwm_counts"]))
        out.append(EsconAmplifier(mode=a["mode"], current_at_min=a["current_at_min"],
                                  current_at_max=a["current_at_max"], sign=a["sign"], offset=a["offset"],
                                  scale=a["scale"], limit=limit, codec=c, enable_active_high=a["enable_active_high"],
                                  ready_active_high=a["ready_active_high"], key=f"escon.amplifiers.{i}",
                                  source=getattr(cfg, "source", None)))
    return out[0], out[1]
