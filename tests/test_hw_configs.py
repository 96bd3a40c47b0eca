"""The shipped hardware configs are safe to start on the prosthesis: they load, wait for an explicit
`ankle-rt ctl activate` and then hold the ankle (no section 7 step), and state every ESCON calibration
value. No hardware is opened: the simulator stands in for it where the daemon runs. The bench configs
(emulators) still run the section 7 experiment."""

from __future__ import annotations

import math

import pytest
import yaml

from ankle_rt.clock import SimClock
from ankle_rt.config import load_config
from ankle_rt.config_schema import ESCON_AMPLIFIER
from ankle_rt.safety import State
from sim_backend.backend import SimBackend
from tests.conftest import ROOT
from tests.daemon_helpers import lockstep_daemon, run_cycles
from tests.hw_helpers import sim_copy

HW = {"hw-serial.yaml": "serial", "hw-canopen.yaml": "canopen"}


@pytest.mark.parametrize("name", sorted(HW))
def test_hardware_config_loads_and_does_not_auto_activate(name):
    cfg = load_config(ROOT / "config" / name)
    assert cfg["backend"] == HW[name]
    assert cfg["safety"]["auto_activate"] is False
    assert cfg["reference"]["profile"] == "hold"
    assert (cfg["reference"]["hold"]["dp"], cfg["reference"]["hold"]["ie"]) == (0.0, 0.0)
    assert cfg["loop"]["duration_s"] == 0                       # runs until stopped, waiting for activate


@pytest.mark.parametrize("name", sorted(HW))
def test_the_daemon_on_a_hardware_config_waits_then_holds(name):
    """1 s past start-up (the tare, and the section 7 step's 0.5 s): still CONFIGURED, no current.
    After `activate`, 1.5 s later: ACTIVE with the reference still at the hold (0, 0), no step."""
    cfg = load_config(ROOT / "config" / name)
    daemon = lockstep_daemon(cfg, backend=SimBackend(sim_copy(cfg), SimClock()))
    plant = daemon.backend.plant
    peak = 0.0
    for _ in range(1000):
        run_cycles(daemon, 1)
        peak = max(peak, abs(plant.current[0]), abs(plant.current[1]))
    assert daemon.safety.state == State.CONFIGURED and peak == 0.0
    daemon.activate()
    run_cycles(daemon, 1500)
    assert daemon.safety.state == State.ACTIVE
    assert max(abs(daemon.reference.ref[0]), abs(daemon.reference.ref[1])) < math.radians(0.01)
    daemon.close()


@pytest.mark.parametrize("name", sorted(HW))
def test_hardware_config_states_every_escon_calibration_value(name):
    """Calibration values on hardware are explicit, not schema defaults (read from the file itself)."""
    raw = yaml.safe_load((ROOT / "config" / name).read_text())
    for k, amp in enumerate(raw["escon"]["amplifiers"]):
        missing = set(ESCON_AMPLIFIER.fields) - set(amp)
        assert not missing, f"{name}: escon.amplifiers.{k} leaves {sorted(missing)} to defaults"


@pytest.mark.parametrize("name", ["bench-serial.yaml", "bench-canopen.yaml"])
def test_bench_configs_still_run_the_section7_experiment(name):
    cfg = load_config(ROOT / "config" / name)
    assert cfg["safety"]["auto_activate"] is True and cfg["reference"]["profile"] == "step"
    assert cfg["reference"]["step"]["dp"] == pytest.approx(math.radians(10), rel=1e-3)
    assert cfg["loop"]["duration_s"] == 5.0
