"""Sensor conversion shared by the hardware transports and their emulators.

- Motor encoders: quadrature counters at the gearbox output (``actuator.encoder_counts_per_rev``,
  116640 for 1440 counts at the motor x 81). The bridge or I/O module reports the raw value of a 16-
  or 32-bit up/down counter; it wraps, so the position is accumulated from the *signed* difference of
  successive readings modulo 2^bits. That is exact as long as an encoder moves less than half the
  counter range between two samples (32768 counts = 1.77 rad per ms for 16 bits: far beyond the
  motors). ``encoders.sign`` flips a channel whose counts run against the model's direction.
- Stuck encoder: a motor whose counter does not move although the torque on it is out of balance by
  more than ``encoders.stuck_torque`` (motor torque kt i minus the cable torque R^-T tau_sg that the
  strain gauges see) for ``encoders.stuck_time`` must be accelerating, so its encoder is not
  counting. Under a steady load (balanced torques) a still motor is not a fault.
- Strain gauges: ankle torques [DP, IE] (N m) = ``matrix`` @ raw ADC counts - ``tare``. A linear map
  makes a per-channel raw offset and a torque tare the same thing, so only the tare is kept; it is
  what ``ankle-rt calibrate`` records. A channel at or beyond ``rail_low`` / ``rail_high`` (ADC
  saturated: overload or a broken bridge wire pulling the input to a supply rail) is reported.
"""

from __future__ import annotations

import math

import numpy as np

from ankle_rt.kinematics import Kinematics
from ankle_rt.params import TransmissionParams
from hardware.config_values import config_error, required


class CounterUnwrap:
    """Accumulates an n-bit wrapping up/down counter into an unbounded count."""

    __slots__ = ("modulus", "half", "count", "last")

    def __init__(self, bits: int):
        self.modulus = 1 << bits
        self.half = 1 << (bits - 1)
        self.count = 0
        self.last = 0

    def reset(self, raw: int) -> None:
        """Start from ``raw``, read as a two's complement value (a counter that went below zero)."""
        raw %= self.modulus
        self.last = raw
        self.count = raw - self.modulus if raw >= self.half else raw

    def update(self, raw: int) -> int:
        """Take the next reading; return the signed step in counts."""
        raw %= self.modulus
        step = (raw - self.last + self.half) % self.modulus - self.half
        self.last = raw
        self.count += step
        return step


class MotorEncoders:
    """Both motor encoders: raw counter values -> rad at the gearbox output."""

    def __init__(self, counts_per_rev: int, counter_bits: int, signs: tuple[int, int]):
        self.rad_per_count = 2.0 * math.pi / counts_per_rev
        self.counter_bits = counter_bits
        self.signs = (int(signs[0]), int(signs[1]))
        self.counters = (CounterUnwrap(counter_bits), CounterUnwrap(counter_bits))
        self.moved = [False, False]    # whether each counter changed at the last update
        self.started = False           # counting since a first reading (reset)

    @classmethod
    def from_config(cls, cfg: dict, counter_bits: int | None = None) -> "MotorEncoders":
        """``counter_bits``: the counter width when the device states it (a CANopen node's EDS);
        default ``encoders.counter_bits`` (the serial bridge)."""
        if counter_bits is None:
            counter_bits = required(cfg, "encoders.counter_bits", "the bridge's counter width, 16 or 32")
        return cls(cfg["actuator"]["encoder_counts_per_rev"], counter_bits,
                   tuple(required(cfg, "encoders.sign", "+1/-1 per motor encoder")))

    def reset(self, raw_1: int, raw_2: int, out: np.ndarray) -> None:
        """Start counting from these raw values; write the angles (rad) into ``out[0:2]``."""
        c1, c2 = self.counters
        c1.reset(raw_1)
        c2.reset(raw_2)
        self.started = True
        self.moved[0] = self.moved[1] = False
        out[0] = self.signs[0] * c1.count * self.rad_per_count
        out[1] = self.signs[1] * c2.count * self.rad_per_count

    def update(self, raw_1: int, raw_2: int, out: np.ndarray) -> None:
        """Unwrap the next raw values; write the angles (rad) into ``out[0:2]``."""
        c1, c2 = self.counters
        self.moved[0] = c1.update(raw_1) != 0
        self.moved[1] = c2.update(raw_2) != 0
        out[0] = self.signs[0] * c1.count * self.rad_per_count
        out[1] = self.signs[1] * c2.count * self.rad_per_count

    def convert(self, raw_1: int, raw_2: int, out: np.ndarray) -> None:
        """A sample's raw values into angles (rad) in ``out[0:2]``: the first one starts the count
        (:meth:`reset`), later ones :meth:`update` it."""
        if self.started:
            self.update(raw_1, raw_2, out)
        else:
            self.reset(raw_1, raw_2, out)

    def raw_from_counts(self, count_1: int, count_2: int) -> tuple[int, int]:
        """The counter values (wrapped to the counter width) an encoder pair shows at these positions
        in counts, model direction (``SimulatedPlant.encoder_counts``). Used by the emulators."""
        m = (1 << self.counter_bits) - 1
        return (self.signs[0] * count_1) & m, (self.signs[1] * count_2) & m


class StuckEncoderDetector:
    """Flags an encoder that does not count while its motor's torques are out of balance."""

    def __init__(self, torque_constant: float, kin: Kinematics, stuck_torque: float, stuck_cycles: int):
        self.kt = torque_constant
        self.RiT = kin.R_inv_T.ravel().tolist()   # motor torque balancing an ankle torque
        self.stuck_torque = stuck_torque
        self.stuck_cycles = stuck_cycles
        self.still = [0, 0]                        # consecutive unbalanced cycles without a count

    @classmethod
    def from_config(cls, cfg: dict, dt: float) -> "StuckEncoderDetector":
        enc = cfg["encoders"]
        kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
        return cls(cfg["actuator"]["torque_constant"], kin, enc["stuck_torque"],
                   max(1, round(enc["stuck_time"] / dt)))

    def reset(self) -> None:
        self.still[0] = self.still[1] = 0

    def update(self, moved: list[bool], current_1: float, current_2: float,
               sg_dp: float, sg_ie: float) -> bool:
        """One sample: ``moved`` per encoder, the set currents (A) that acted since the previous
        sample, the strain-gauge torques (N m). True when an encoder counts as stuck."""
        r = self.RiT
        unbalanced_1 = abs(self.kt * current_1 - (r[0] * sg_dp + r[1] * sg_ie)) > self.stuck_torque
        unbalanced_2 = abs(self.kt * current_2 - (r[2] * sg_dp + r[3] * sg_ie)) > self.stuck_torque
        s = self.still
        s[0] = s[0] + 1 if (unbalanced_1 and not moved[0]) else 0
        s[1] = s[1] + 1 if (unbalanced_2 and not moved[1]) else 0
        return s[0] >= self.stuck_cycles or s[1] >= self.stuck_cycles


class StrainGauges:
    """Two strain-gauge bridges: raw ADC counts -> ankle torques [DP, IE] in N m."""

    def __init__(self, matrix: list[list[float]], tare: list[float], rail_low: int, rail_high: int):
        self.m = [float(matrix[0][0]), float(matrix[0][1]), float(matrix[1][0]), float(matrix[1][1])]
        self.tare = [float(tare[0]), float(tare[1])]
        self.rail_low = rail_low
        self.rail_high = rail_high
        det = self.m[0] * self.m[3] - self.m[1] * self.m[2]
        self._inv = [self.m[3] / det, -self.m[1] / det, -self.m[2] / det, self.m[0] / det]
        self.at_rail = [False, False]

    @classmethod
    def from_config(cls, cfg: dict) -> "StrainGauges":
        matrix = required(cfg, "strain_gauges.matrix", "N m per ADC count, 2 x 2 [[DP from ch 1, DP from ch 2], "
                                                         "[IE from ch 1, IE from ch 2]]")
        for i, row in enumerate(matrix):
            if len(row) != 2:
                raise config_error(cfg, f"strain_gauges.matrix.{i}", f"expected 2 numbers, got {len(row)}")
        if abs(np.linalg.det(np.asarray(matrix, dtype=float))) < 1e-300:
            raise config_error(cfg, "strain_gauges.matrix", "singular: the two channels cannot tell DP from IE")
        tare = required(cfg, "strain_gauges.tare", "N m [DP, IE], recorded by ankle-rt calibrate")
        low = required(cfg, "strain_gauges.rail_low", "raw ADC count at or below which a channel is at its rail")
        high = required(cfg, "strain_gauges.rail_high", "raw ADC count at or above which a channel is at its rail")
        if low >= high:
            raise config_error(cfg, "strain_gauges.rail_high", f"must be above rail_low ({low}), got {high}")
        return cls(matrix, tare, low, high)

    def convert(self, raw_1: int, raw_2: int, out: np.ndarray) -> bool:
        """Write the tared torques (N m) into ``out[0:2]``; return True if a channel is at its rail."""
        m = self.m
        out[0] = m[0] * raw_1 + m[1] * raw_2 - self.tare[0]
        out[1] = m[2] * raw_1 + m[3] * raw_2 - self.tare[1]
        lo, hi = self.rail_low, self.rail_high
        self.at_rail[0] = raw_1 <= lo or raw_1 >= hi
        self.at_rail[1] = raw_2 <= lo or raw_2 >= hi
        return self.at_rail[0] or self.at_rail[1]

    def raw(self, torque_dp: float, torque_ie: float, adc_min: int, adc_max: int) -> tuple[int, int]:
        """The raw counts (rounded, saturated at the ADC's range) these torques produce. Emulators."""
        dp = torque_dp + self.tare[0]
        ie = torque_ie + self.tare[1]
        v = self._inv
        r1 = round(v[0] * dp + v[1] * ie)
        r2 = round(v[2] * dp + v[3] * ie)
        return min(max(r1, adc_min), adc_max), min(max(r2, adc_min), adc_max)


class JointEncoders:
    """Absolute joint encoders of a bench (optional): raw counts -> ankle angles [DP, IE] in rad."""

    def __init__(self, counts_per_rev: int, signs: tuple[int, int]):
        self.rad_per_count = 2.0 * math.pi / counts_per_rev
        self.signs = (int(signs[0]), int(signs[1]))

    @classmethod
    def from_config(cls, cfg: dict) -> "JointEncoders | None":
        """None when the config has no ``joint_encoders.counts_per_rev`` (no joint encoders)."""
        je = cfg["joint_encoders"]
        if je["counts_per_rev"] is None:
            return None
        return cls(je["counts_per_rev"], tuple(je["sign"]))

    def convert(self, raw_dp: int, raw_ie: int, out: np.ndarray) -> None:
        out[0] = self.signs[0] * raw_dp * self.rad_per_count
        out[1] = self.signs[1] * raw_ie * self.rad_per_count

    def raw(self, angle_dp: float, angle_ie: float) -> tuple[int, int]:
        k = 1.0 / self.rad_per_count
        return self.signs[0] * math.floor(angle_dp * k), self.signs[1] * math.floor(angle_ie * k)
