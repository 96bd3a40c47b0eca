"""ankle-rt calibrate: the tare it records and the sign checks, on the simulator and through the serial
bridge emulator, including configs whose amplifier or encoder sign is flipped."""

from __future__ import annotations

import pytest
import yaml

from ankle_rt.backend import open_backend
from ankle_rt.calibration import CalibrationAborted, calibrate
from ankle_rt.clock import SimClock
from ankle_rt.config import Config, load_config
from hardware.serial_backend import SerialBackend
from hardware.emulators.serial_emulator import BridgeEmulator, LockstepLink
from tests.conftest import ROOT
from tests.hw_helpers import bench_config, config_copy

BENCH = ROOT / "config" / "bench-serial.yaml"


@pytest.fixture
def bench_cfg() -> Config:
    """A private copy of config/bench-serial.yaml."""
    return bench_config(BENCH)


def calibrate_against(device: Config, host: Config):
    """Calibrate the host config through the serial link against an emulator built like ``device``."""
    clock = SimClock()
    backend = SerialBackend(host, clock, port=LockstepLink(BridgeEmulator(device)))
    try:
        return calibrate(host, backend, clock), backend
    finally:
        backend.close()


def test_tare_finds_the_simulated_offset_and_signs_pass(sim_cfg):
    sim_cfg["sim"]["strain_gauge_offset"] = [0.3, -0.2]
    clock = SimClock()
    backend = open_backend(sim_cfg, clock)
    report = calibrate(sim_cfg, backend, clock)
    backend.close()
    sigma = 0.02 / report.tare_samples ** 0.5                      # noise of the mean
    assert report.tare[0] == pytest.approx(0.3, abs=5 * sigma) and report.tare[1] == pytest.approx(-0.2, abs=5 * sigma)
    assert report.tare_noise[0] == pytest.approx(0.02, rel=0.2)
    assert report.ok, report.problems
    assert not backend.active and backend.set_values == [0.0, 0.0]
    for c in report.motors:                                        # each pulse turned its own motor forward
        assert c.motor_motion[c.motor - 1] > 0.01 and abs(c.motor_motion[2 - c.motor]) < 0.002


def test_through_the_serial_emulator_the_tare_adds_to_the_configured_one(bench_cfg):
    device = config_copy(bench_cfg)
    device["sim"]["strain_gauge_offset"] = [0.25, 0.1]
    host = config_copy(bench_cfg)
    host["strain_gauges"]["tare"] = [0.05, 0.0]                    # an older tare
    report, backend = calibrate_against(device, host)
    assert report.ok, report.problems
    assert report.tare[0] == pytest.approx(0.25, abs=0.005) and report.tare[1] == pytest.approx(0.1, abs=0.005)
    assert report.tare_mean[0] == pytest.approx(0.20, abs=0.005)
    assert yaml.safe_load(report.yaml())["strain_gauges"]["tare"] == pytest.approx(list(report.tare), abs=1e-5)
    emu = backend.emulator
    assert emu.amplifier_currents() == (0.0, 0.0) and emu.enable_levels == [False, False]


def test_a_flipped_amplifier_sign_is_caught_and_named(bench_cfg):
    host = config_copy(bench_cfg)
    host["escon"]["amplifiers"][1]["sign"] = -1                    # the config disagrees with the wiring
    report, _ = calibrate_against(bench_cfg, host)
    assert not report.ok and len(report.problems) == 1
    assert "motor 2 turned -" in report.problems[0] and "flip escon.amplifiers.1.sign (list item 1 = motor 2)" in report.problems[0]


def test_a_flipped_encoder_sign_is_caught_and_named(bench_cfg):
    host = config_copy(bench_cfg)
    host["encoders"]["sign"] = [-1, 1]
    report, _ = calibrate_against(bench_cfg, host)
    assert [p.split(":")[1].strip() for p in report.problems] == [
        "the motor turned forward but encoder 1 counts backwards"]
    assert "flip encoders.sign.0" in report.problems[0]


def test_without_joint_encoders_both_candidate_keys_are_named(bench_cfg):
    device = config_copy(bench_cfg)
    device["joint_encoders"]["counts_per_rev"] = None
    host = config_copy(device)
    host["escon"]["amplifiers"][0]["sign"] = -1
    report, _ = calibrate_against(device, host)
    assert len(report.problems) == 1
    assert ("escon.amplifiers.0.sign (list item 0 = motor 1) and encoders.sign.0 (list item 0 = motor 1)"
            in report.problems[0])


def test_crossed_set_value_cables_are_caught(bench_cfg):
    emu = BridgeEmulator(bench_cfg)
    straight = emu.amplifier_currents
    emu.amplifier_currents = lambda: straight()[::-1]            # amplifier 1 drives motor 2, and back
    clock = SimClock()
    backend = SerialBackend(bench_cfg, clock, port=LockstepLink(emu))
    report = calibrate(bench_cfg, backend, clock)
    backend.close()
    assert len(report.problems) == 2
    assert report.problems[0].startswith("a pulse on amplifier 1 turned motor 2 by +2.")
    assert report.problems[1].startswith("a pulse on amplifier 2 turned motor 1 by +2.")
    assert all(p.endswith("set-value outputs or encoder channels are swapped") for p in report.problems)


def test_a_device_fault_stops_the_calibration_with_the_amplifiers_off(bench_cfg):
    clock = SimClock()
    backend = open_backend(bench_cfg, clock)
    backend.emulator.schedule.append(("not_ready_2", 0.2, 10.0))
    with pytest.raises(CalibrationAborted, match="AMP_NOT_READY"):
        calibrate(bench_cfg, backend, clock)
    assert backend.emulator.amplifier_currents() == (0.0, 0.0)
    backend.close()


def test_calibrate_command(tmp_path, capsys):
    from ankle_rt.cli import main

    out = tmp_path / "cal.yaml"
    assert main(["calibrate", "--config", str(BENCH), "--fast", "--output", str(out)]) == 0
    text = capsys.readouterr().out
    assert "motor 1: +0.5 A pulse" in text and "all checks passed" in text
    assert len(yaml.safe_load(out.read_text())["strain_gauges"]["tare"]) == 2


def test_a_wrong_enable_polarity_leaves_the_motors_still_and_is_named(bench_cfg):
    host = config_copy(bench_cfg)
    for amp in host["escon"]["amplifiers"]:
        amp["enable_active_high"] = False                          # ESCON Studio says high active
    report, _ = calibrate_against(bench_cfg, host)
    assert [p.split(" (")[0] for p in report.problems] == ["motor 1 did not move", "motor 2 did not move"]
    assert "escon.amplifiers.1.enable_active_high" in report.problems[1]


def test_calibrate_runs_on_the_canopen_emulator_too():
    cfg = load_config(ROOT / "config" / "bench-canopen.yaml")
    cfg["canopen"]["channel"] = "test-calibrate-canopen"
    clock = SimClock()
    backend = open_backend(cfg, clock)
    try:
        report = calibrate(cfg, backend, clock)
    finally:
        backend.close()
    assert report.ok, report.problems
    assert all(c.motor_motion[c.motor - 1] > 0.01 for c in report.motors)
