"""Sensor conversion: counter wrap-around, encoder signs, stuck encoders, strain-gauge matrix and rails."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

from ankle_rt.config import ConfigError
from ankle_rt.kinematics import Kinematics
from ankle_rt.params import TransmissionParams
from hardware.sensors import CounterUnwrap, MotorEncoders, StrainGauges, StuckEncoderDetector

CPR = 116640


@given(bits=st.sampled_from([16, 32]), start=st.integers(-10**6, 10**6),
       steps=st.lists(st.integers(-30000, 30000), max_size=60))
def test_unwrap_follows_the_true_count_through_any_number_of_wraps(bits, start, steps):
    u = CounterUnwrap(bits)
    u.reset(start % (1 << bits))
    true = ((start + (1 << (bits - 1))) % (1 << bits)) - (1 << (bits - 1))  # start as the counter shows it
    for s in steps:
        true += s
        u.update(true % (1 << bits))
        assert u.count == true


def test_16_bit_counter_over_more_than_a_revolution():
    enc = MotorEncoders(CPR, 16, (1, -1))
    out = np.zeros(2)
    enc.reset(*enc.raw_from_counts(0, 0), out)
    counts = lambda a: math.floor(a * CPR / (2 * math.pi))   # noqa: E731
    for k in range(1, 800):          # 8 rad in 10 mrad steps: the 16-bit counter wraps ~10 times
        angle = 0.01 * k
        enc.update(*enc.raw_from_counts(counts(angle), counts(-angle)), out)
    assert out[0] == pytest.approx(angle, abs=2 * math.pi / CPR)
    assert out[1] == pytest.approx(-angle, abs=2 * math.pi / CPR)


def test_reset_reads_a_counter_below_zero_as_negative():
    enc = MotorEncoders(CPR, 32, (1, 1))
    out = np.zeros(2)
    enc.reset(2**32 - 5, 7, out)
    assert out[0] == pytest.approx(-5 * 2 * math.pi / CPR) and out[1] == pytest.approx(7 * 2 * math.pi / CPR)


def sg(matrix=((2e-5, 1e-7), (-2e-7, 1.5e-5)), tare=(0.3, -0.1)):
    return StrainGauges([list(r) for r in matrix], list(tare), -8_380_000, 8_380_000)


@given(dp=st.floats(-100, 100), ie=st.floats(-100, 100))
def test_strain_gauge_round_trip(dp, ie):
    s = sg()
    out = np.zeros(2)
    assert not s.convert(*s.raw(dp, ie, -2**23, 2**23 - 1), out)
    assert out[0] == pytest.approx(dp, abs=2e-5) and out[1] == pytest.approx(ie, abs=2e-5)


def test_strain_gauge_rails_and_broken_wire():
    s = sg()
    out = np.zeros(2)
    assert s.convert(2**23 - 1, 0, out) and s.at_rail == [True, False]     # overload / open bridge
    assert s.convert(0, -2**23, out) and s.at_rail == [False, True]        # wire to the negative rail
    assert not s.convert(8_379_999, -8_379_999, out)
    hi = s.raw(1e6, 0.0, -2**23, 2**23 - 1)                                # an emulated overload saturates
    assert s.convert(*hi, out)


def test_strain_gauge_config_is_required_on_hardware(sim_cfg):
    sim_cfg["backend"] = "serial"
    with pytest.raises(ConfigError, match=r"strain_gauges\.matrix: missing"):
        StrainGauges.from_config(sim_cfg)
    sim_cfg["strain_gauges"].update(matrix=[[1.0, 2.0], [2.0, 4.0]])
    with pytest.raises(ConfigError, match=r"strain_gauges\.matrix: singular"):
        StrainGauges.from_config(sim_cfg)


def detector(sim_cfg):
    kin = Kinematics.from_params(TransmissionParams(**sim_cfg["transmission"]))
    return StuckEncoderDetector(1.66, kin, stuck_torque=2.0, stuck_cycles=10), kin


def test_stuck_encoder_is_flagged_after_the_stated_cycles(sim_cfg):
    det, _ = detector(sim_cfg)
    flags = [det.update([False, True], 5.0, 0.0, 0.0, 0.0) for _ in range(12)]
    assert flags.index(True) == 9                         # the 10th unbalanced cycle without a count


def test_a_still_motor_holding_a_load_is_not_stuck(sim_cfg):
    det, kin = detector(sim_cfg)
    tau = np.array([40.0, -10.0])                         # N m at the ankle, held by the motors
    i = kin.R_inv_T @ tau / 1.66
    assert not any(det.update([False, False], i[0], i[1], tau[0], tau[1]) for _ in range(100))
    assert not any(det.update([True, True], 8.0, -8.0, 0.0, 0.0) for _ in range(100))  # moving
