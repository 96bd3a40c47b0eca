"""ESCON 50/5 set-value map: round trips, quantisation, clamping, sign/offset calibration, config errors."""

from __future__ import annotations

import pytest
from hypothesis import given, strategies as st

from ankle_rt.config import ConfigError
from hardware.escon import EsconAmplifier, SetValueCode, escon_amplifiers


def amp(mode="analog", sign=1, offset=0.0, lo=-15.0, hi=15.0, limit=15.0, **kw):
    codec = SetValueCode.analog(12) if mode == "analog" else SetValueCode.pwm(10000)
    return EsconAmplifier(mode=mode, current_at_min=lo, current_at_max=hi, sign=sign, offset=offset,
                          limit=limit, codec=codec, **kw)


def test_quantisation_of_the_12_bit_analog_map():
    a = amp()
    assert a.codec.lsb == pytest.approx(10.0 / 2048)          # 4.88 mV per code
    assert a.current_lsb == pytest.approx(30.0 / 4096)        # 7.32 mA per code over +/-15 A
    assert a.zero_code == 0 and a.current(0) == 0.0           # zero current is exactly representable
    assert a.set_value(7.5) == pytest.approx(5.0)             # +15 A at +10 V


def test_pwm_map_is_10_to_90_percent():
    a = amp("pwm")
    assert a.set_value(-15.0) == pytest.approx(0.10)
    assert a.set_value(15.0) == pytest.approx(0.90)
    assert a.zero_code == 5000
    assert a.current_lsb == pytest.approx(30.0 / 8000)


@given(i=st.floats(-15.0, 15.0), mode=st.sampled_from(["analog", "pwm"]), sign=st.sampled_from([-1, 1]),
       offset=st.floats(-0.3, 0.3), scale=st.floats(0.97, 1.03))
def test_round_trip_within_half_a_code(i, mode, sign, offset, scale):
    a = amp(mode, sign=sign, offset=offset, scale=scale, lo=-16.5, hi=16.5)
    assert abs(a.current(a.code(i)) - i) <= a.current_lsb / 2 + 1e-12


@given(i=st.floats(15.0, 1e6))
def test_set_values_beyond_the_peak_limit_are_clamped(i):
    a = amp(lo=-20.0, hi=20.0)
    assert a.code(i) == a.code(15.0)
    assert a.code(-i) == a.code(-15.0)
    assert abs(a.current(a.code(i)) - 15.0) <= a.current_lsb


def test_codes_beyond_the_dac_range_are_clamped_by_the_amplifier_model():
    a = amp()
    assert a.current(10**6) == a.current(a.codec.code_max)
    assert a.current(-10**6) == pytest.approx(-15.0)


def test_sign_and_offset_calibration():
    assert amp(sign=-1).code(3.0) == amp().code(-3.0)
    a = amp(offset=0.2)                                        # the amplifier drives +0.2 A at 0 V
    assert a.current(a.code(0.0)) == pytest.approx(0.0, abs=a.current_lsb / 2)
    assert a.code(0.0) == amp().code(-0.2)


def test_scale_calibration():
    a = amp(scale=0.95)                                        # the amplifier drives 5 % less than mapped
    assert a.set_value(7.125) == pytest.approx(5.0)            # so 7.125 A needs the 7.5 A voltage
    assert a.current(a.code(7.125)) == pytest.approx(7.125, abs=a.current_lsb / 2)
    assert a.current_lsb == pytest.approx(0.95 * 30.0 / 4096)


def test_enable_and_ready_polarity():
    assert amp().enable_level(True) is True
    low = amp(enable_active_high=False, ready_active_high=False)
    assert low.enable_level(True) is False and low.enable_level(False) is True
    assert low.is_ready(False) is True and low.is_ready(True) is False


def test_a_map_narrower_than_the_peak_limit_is_refused():
    with pytest.raises(ConfigError, match=r"escon.amplifiers.*current_at_max.*15"):
        amp(lo=-10.0, hi=10.0)


def test_missing_map_names_the_key(sim_cfg):
    sim_cfg["backend"] = "serial"
    with pytest.raises(ConfigError, match=r"escon\.amplifiers: missing"):
        escon_amplifiers(sim_cfg)
