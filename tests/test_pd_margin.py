"""Every accepted gain set is stable, the motor-side PD's too (the paper's controller, the simulator's
default): gain sets within controller.gain_limits that oscillate (kd 0) are refused by the config
loader and by set_gains naming the gain, and a stable but saturating step is not taken for an
oscillation."""

from __future__ import annotations

import pytest

from ankle_rt.analysis import REQUIRED_GAIN_MARGIN_DB, gain_set_margin_db
from ankle_rt.cli import main
from ankle_rt.config import ConfigError, load_config
from ankle_rt.control.gains import GainError
from ankle_rt.daemon import run_lockstep
from ankle_rt.paths import default_config_path


def _pd_yaml(tmp_path, kp, kd, extra=""):
    path = tmp_path / "pd.yaml"
    path.write_text(f"include: {default_config_path()}\ncontroller:\n  step_gains: {{kp: {kp}, kd: {kd}}}\n{extra}")
    return path


@pytest.mark.parametrize("kp", [90.0, 200.0])
def test_an_undamped_pd_is_refused_by_config_check_naming_kd(tmp_path, capsys, kp):
    """kp 90 / 200 with kd 0 passed `config check` and oscillated at +-15 A until the detector."""
    assert main(["config", "check", str(_pd_yaml(tmp_path, kp, 0.0))]) != 0
    out = capsys.readouterr()
    assert "controller.step_gains.kd" in out.out + out.err and "unstable" in out.out + out.err


def test_the_chosen_pd_gain_set_is_the_one_checked(tmp_path):
    path = tmp_path / "pd.yaml"
    path.write_text(f"include: {default_config_path()}\ncontroller:\n  validation_gains: {{kp: 90.0, kd: 0.0}}\n")
    load_config(path)                                    # pd_gains: step (the validation set is not run)
    with pytest.raises(ConfigError, match="controller.validation_gains.kd"):
        load_config(path, {"controller": {"pd_gains": "validation"}})


def test_the_shipped_pd_gains_keep_the_margin():
    cfg = load_config(default_config_path())
    for gains in (cfg["controller"]["step_gains"], cfg["controller"]["validation_gains"]):
        margin, limiting = gain_set_margin_db(cfg, gains)
        assert margin >= REQUIRED_GAIN_MARGIN_DB and limiting is None


def test_set_gains_refuses_an_undamped_pd_and_applies_a_stable_change():
    from ankle_rt.clock import SimClock
    from ankle_rt.daemon import Daemon

    daemon = Daemon(load_config(default_config_path()), SimClock())
    try:
        with pytest.raises(GainError) as err:
            daemon.controller.set_gains(kd=0.0)
        assert err.value.gain == "kd" and "unstable" in str(err.value)
        daemon.controller.set_gains(kp=120.0)
        assert daemon.controller.gains.targets[0] == 120.0
    finally:
        daemon.close()


def test_a_stable_pds_saturated_step_is_not_an_oscillation(tmp_path):
    """kp 400, kd 3 keeps 17 dB of margin; its 10 deg step runs at the 15 A clamp and overshoots for
    ~0.2 s, which kept the detector's band above its limit 0.31 s (the 0.25 s hold faulted it)."""
    cfg = load_config(_pd_yaml(tmp_path, 400.0, 3.0))
    rec = run_lockstep(cfg, 1.5)
    assert rec.summary["fault"] == "NONE"
    assert abs(rec["current_cmd_1"]).max() == pytest.approx(cfg["amplifier"]["current_limit_peak"])
