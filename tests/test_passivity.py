"""Passivity is part of accepting a gain set (ankle_rt.passivity, ankle_rt.gain_margin.passivity_refusal):
a stable loop that renders negative damping somewhere is refused at load, by set_gains and per gait
phase, and what the model refuses does give energy back on the simulator."""

from __future__ import annotations

import re

import numpy as np
import pytest

from ankle_rt import gain_margin
from ankle_rt.bench.impedance import Experiment, bench_config, run_impedance, with_plant_friction
from ankle_rt.config import ConfigError, load_config
from ankle_rt.control import build_controller
from ankle_rt.control.gains import GainError
from ankle_rt.kinematics import Kinematics
from ankle_rt.params import PlantParams, TransmissionParams
from ankle_rt.passivity import least_rendered_damping
from ankle_rt.analysis import gain_set_loop
from ankle_rt.paths import CONFIG_DIR, default_config_path
from tests.loop_configs import gauge_loop_config

BENCH_K200 = "stiffness_dp: 200, stiffness_ie: 100, damping_dp: 0.5"


def _config(tmp_path, impedance: str, *, include: str = "torque-loop-gauges.yaml", torque_loop: str = ""):
    path = tmp_path / "c.yaml"
    files = ", ".join(str(f) for f in (default_config_path(), CONFIG_DIR / include))
    path.write_text(f"include: [{files}]\ncontroller: {{type: impedance, impedance: {{{impedance}}}"
                    f"{', torque_loop: {' + torque_loop + '}' if torque_loop else ''}}}\n")
    return path


def _needed(err: str, name: str) -> float:
    return float(re.search(rf"passive from {name} ([0-9.]+)", err).group(1))


def test_config_check_refuses_a_spring_without_damping_that_gives_energy_back(tmp_path):
    """K_ie 100 with no damping: stable (margin kept), but on a cable 30 % softer than configured the
    law's lead over-compensates and the ankle renders negative damping: refused naming damping_ie, with
    the least damping that makes it passive; that much is accepted."""
    with pytest.raises(ConfigError) as err:
        load_config(_config(tmp_path, f"{BENCH_K200}, damping_ie: 0.0"))
    assert err.value.key == "controller.impedance.damping_ie"
    assert "not passive on IE" in str(err.value) and "cable x0.7" in str(err.value)
    need = _needed(str(err.value), "damping_ie")
    assert 0.0 < need < 0.5
    cfg = load_config(_config(tmp_path, f"{BENCH_K200}, damping_ie: {need}"))
    least = least_rendered_damping(PlantParams.from_config(cfg), gain_set_loop(cfg, {}))
    assert least[1].passive and least[1].damping < 0.01     # at the boundary, not far inside it


def test_what_the_check_refuses_gives_energy_back_on_the_simulator(tmp_path, monkeypatch):
    """The refused setting, run anyway (the check bypassed) in lockstep on a device with the cable x0.7,
    half the viscous friction and no Coulomb friction (the model's worst case): the IE ankle returns
    energy to the foot in 3 N m sines. At the damping the refusal names it does not once the device has
    a quarter of its stated Coulomb friction (frictionless it still returns 0.8 % of a cycle's work:
    the model is linear; docs/daemon.md "Passivity")."""
    base = gauge_loop_config()

    def run(damping_ie: float, coulomb_scale: float):
        c = bench_config(base, stiffness=(200.0, 100.0), damping=(0.5, damping_ie), torque_feedback="auto",
                         friction_ff=None, effects=[])
        plant = with_plant_friction(c, coulomb_scale)
        plant["actuator"]["damping"] *= 0.5
        plant["transmission"]["cable_stiffness"] *= 0.7
        exp = Experiment(pulses_nm=((), ()), sine_hz=(1.0, 4.0), sine_nm=((), (3.0,)), sine_cycles=6,
                         analysed_cycles=3, axes=("ie",), step_nm=(0.0, 0.0))
        res = run_impedance(c, exp, plant_cfg=plant)
        assert res.fault == "NONE"
        return res

    monkeypatch.setattr(gain_margin, "passivity_refusal", lambda *a, **k: None)
    assert not run(0.0, 0.0).passive()
    monkeypatch.undo()
    with pytest.raises(ConfigError) as err:
        load_config(_config(tmp_path, f"{BENCH_K200}, damping_ie: 0.0"))
    assert run(_needed(str(err.value), "damping_ie"), 0.25).passive()


def test_set_gains_refuses_a_gain_that_loses_passivity_naming_it(tmp_path):
    """At run time: a damping taken away names the damping; a torque-loop gain that keeps the margin
    but loses passivity (kp_ie halved at K_ie 100) names that gain; the accepted set is applied."""
    cfg = load_config(_config(tmp_path, f"{BENCH_K200}, damping_ie: 0.15"))
    ctl = build_controller(cfg, Kinematics.from_params(TransmissionParams(**cfg["transmission"])), np.zeros(2))
    with pytest.raises(GainError) as err:
        ctl.set_gains(damping_ie=0.0)
    assert err.value.gain == "damping_ie" and "not passive" in str(err.value)
    kp_ie = cfg["controller"]["torque_loop"]["kp_ie"]
    with pytest.raises(GainError) as err:
        ctl.set_gains(kp_ie=kp_ie / 2.0)
    assert err.value.gain == "kp_ie" and "not passive" in str(err.value)
    ctl.set_gains(damping_ie=0.3)
    assert ctl.gains.as_dict()["damping_ie"] == 0.15      # ramping towards the accepted target
    assert dict(zip(ctl.gains.names, ctl.gains.targets))["damping_ie"] == 0.3


@pytest.mark.parametrize("crossover, passive", [("2, torque_rate_crossover_hz_ie: 2", False),
                                                ("5, torque_rate_crossover_hz_ie: 15", True)])
def test_the_encoder_rate_crossover_is_checked_for_passivity(tmp_path, crossover, passive):
    """With the rate on the encoders, a 2 Hz crossover at K_dp 200 keeps the margin and renders negative
    damping on DP (the linear model, docs/daemon.md "Seventh pass"): refused; the shipped 5 / 15 Hz is not."""
    path = _config(tmp_path, f"{BENCH_K200}, damping_ie: 0.25", include="torque-loop-encoders.yaml",
                   torque_loop=f"torque_rate_crossover_hz_dp: {crossover}")
    if passive:
        load_config(path)
        return
    with pytest.raises(ConfigError, match="not passive on DP") as err:
        load_config(path)
    assert err.value.key == "controller.impedance.damping_dp"


def test_config_check_prints_the_least_damping_the_impedance_renders(tmp_path, capsys):
    """`config check` shows how far from giving energy back the configured impedance is: the model's least
    rendered damping per axis, the same figures the check judges."""
    from ankle_rt.cli import main

    path = _config(tmp_path, f"{BENCH_K200}, damping_ie: 0.15")
    assert main(["config", "check", str(path)]) == 0
    line = next(s for s in capsys.readouterr().out.splitlines() if "least damping rendered" in s)
    cfg = load_config(path)
    least = least_rendered_damping(PlantParams.from_config(cfg), gain_set_loop(cfg, {}))
    dp, ie = (float(v) for v in re.findall(r"[+-][0-9.e-]+", line)[:2])
    assert (dp, ie) == pytest.approx((least[0].damping, least[1].damping), rel=1e-2)
    assert 0.0 <= ie < 0.05          # just passive: damping_ie 0.15 is near its boundary, 0.111


def test_the_motor_side_pd_is_held_to_passivity_naming_kd():
    """The PD (the simulator's default controller) on the same check: kp 20 with kd 0.09 against the friction
    feed-forward's viscous 0.112 N m s/rad renders negative damping on a stiffer cable; refused naming kd with
    the least kd that is passive, which passes. (Through the loader the margin, 0.7 dB there, refuses it first.)"""
    cfg = load_config(default_config_path())
    name, reason = gain_margin.passivity_refusal(cfg, {"kp": 20.0, "kd": 0.09}, 0.112)
    assert name == "kd" and "motor-side PD" in reason and "cable x1.3" in reason
    need = _needed(reason, "kd")
    assert gain_margin.passivity_refusal(cfg, {"kp": 20.0, "kd": need}, 0.112) is None
