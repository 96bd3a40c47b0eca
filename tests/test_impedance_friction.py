"""Friction feed-forward from the identified model (Stribeck, asymmetric, load-dependent) and its
standstill band; the model file a diagnosis writes."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from ankle_rt.config import ConfigError, load_config
from ankle_rt.control import build_controller
from ankle_rt.control.friction import FrictionFeedForward
from ankle_rt.kinematics import Kinematics
from ankle_rt.params import PlantParams, TransmissionParams
from ankle_rt.paths import default_config_path
from sim_backend.effects import build_effects
from sim_backend.model import baseline_friction

MODEL = [{"type": "stribeck", "static_excess": 0.15, "stribeck_velocity": 0.1},
         {"type": "asymmetric_friction", "coulomb_asymmetry": 0.03, "viscous_asymmetry": 0.01},
         {"type": "load_dependent_friction", "coefficient": 0.12}]


@pytest.fixture(scope="module")
def cfg():
    c = load_config(default_config_path()).deep_copy()
    c["sim"]["effects"] = [dict(e) for e in MODEL]
    ff = c["controller"]["friction_ff"]
    ff.update(enabled=True, model="identified", model_file="")
    return c


def simulated_friction(cfg, v, tc):
    """The simulator's resisting torque on motor 1 at speed v and cable torque tc (baseline + effects)."""
    p = PlantParams.from_config(cfg)
    total = 0.0
    for e in [baseline_friction(p, 1e-3)] + build_effects(cfg["sim"]["effects"], p, 1e-3):
        total += e.motor_torque(0.0, 0.0, v, 0.0, tc, 0.0)[0]
    return total + p.actuator.damping * v


@pytest.mark.parametrize("v", [-2.0, -0.3, -0.08, 0.08, 0.3, 2.0])
@pytest.mark.parametrize("tc", [0.0, 0.7, -1.5])
def test_identified_feed_forward_equals_the_plant_friction_while_sliding(cfg, v, tc):
    """Outside the standstill band the feed-forward is the identified model itself: Stribeck, the
    direction asymmetry and the load-dependent term on the measured cable torque included."""
    ff = FrictionFeedForward.from_config(cfg)
    assert ff.torque(v, tc) == pytest.approx(simulated_friction(cfg, v, tc), rel=1e-3, abs=1e-4)
    baseline = FrictionFeedForward(cfg["actuator"]["coulomb"], cfg["actuator"]["damping"], 0.05)
    if tc != 0.0 and abs(v) < 0.2:   # the baseline misses the Stribeck and load terms
        assert abs(baseline.torque(v) - simulated_friction(cfg, v, tc)) > 0.1


def test_standstill_band_is_continuous_and_bounded(cfg):
    """Inside |v| < velocity_band the direction-dependent terms fade linearly: velocity noise of one
    encoder count per cycle moves the command by at most the band's slope, never by 2 kc."""
    ff = FrictionFeedForward.from_config(cfg)
    band = cfg["controller"]["friction_ff"]["velocity_band"]
    v = np.linspace(-2 * band, 2 * band, 4001)
    out = np.array([ff.torque(x, 1.0) for x in v])
    slope = np.max(np.abs(np.diff(out) / np.diff(v)))
    kc = cfg["actuator"]["coulomb"] + 0.15 + 0.12 * 1.0 + 0.03
    assert slope <= kc / band * 1.01 + cfg["actuator"]["damping"] + 0.02
    assert ff.torque(0.0, 1.0) == 0.0
    small = 0.054 * 0.1                                   # a tenth of one count per cycle
    assert abs(ff.torque(small, 1.0)) <= small / band * kc + (cfg["actuator"]["damping"] + 0.01) * small + 1e-12


def test_model_file_as_diagnose_writes_it(tmp_path):
    """``model_file``: a complete config (include + actuator + sim.effects, what `diagnose
    --write-model` writes); a relative path is relative to the config file. The running config states
    the same plant (it includes the model): a model with more friction than the config states is
    refused (test_friction_ff_safety.py)."""
    base = default_config_path()
    (tmp_path / "model.yaml").write_text(yaml.safe_dump({
        "include": [str(base)], "actuator": {"coulomb": 0.31, "damping": 0.09},
        "sim": {"effects": [MODEL[0], MODEL[2]]}}))
    (tmp_path / "run.yaml").write_text(yaml.safe_dump({
        "include": ["model.yaml"], "controller": {"friction_ff": {"enabled": True, "model": "identified",
                                                                  "model_file": "model.yaml"}}}))
    c = load_config(tmp_path / "run.yaml")
    ff = FrictionFeedForward.from_config(c)
    assert (ff.kc, ff.d, ff.a, ff.mu, ff.dc) == (0.31, 0.09, 0.15, 0.12, 0.0)
    assert ff.torque(1.0, 2.0) == pytest.approx(0.31 + 0.15 * math.exp(-100.0) + 0.24 + 0.09)


def test_bad_model_file_names_the_key(tmp_path):
    base = default_config_path()
    (tmp_path / "run.yaml").write_text(yaml.safe_dump({
        "include": [str(base)], "controller": {"friction_ff": {"enabled": True, "model": "identified",
                                                               "model_file": "missing.yaml"}}}))
    with pytest.raises(ConfigError, match=r"controller\.friction_ff\.model_file"):
        FrictionFeedForward.from_config(load_config(tmp_path / "run.yaml"))
    (tmp_path / "run2.yaml").write_text(yaml.safe_dump({
        "include": [str(base)], "controller": {"friction_ff": {"model": "stribeck_only"}}}))
    with pytest.raises(ConfigError, match=r"controller\.friction_ff\.model"):
        load_config(tmp_path / "run2.yaml")
    (tmp_path / "model.yaml").write_text(yaml.safe_dump({
        "include": [str(base)], "sim": {"effects": [{"type": "stribeck", "static_excess": 0.1,
                                                     "stribeck_velocity": 0.0}]}}))
    (tmp_path / "run3.yaml").write_text(yaml.safe_dump({
        "include": [str(base)], "controller": {"friction_ff": {"enabled": True, "model": "identified",
                                                               "model_file": "model.yaml"}}}))
    with pytest.raises(ConfigError, match=r"model\.yaml: sim\.effects\.0\.stribeck_velocity: expected a finite number > 0"):
        FrictionFeedForward.from_config(load_config(tmp_path / "run3.yaml"))


def test_torque_loop_leaves_the_viscous_compensation_out(cfg):
    """Under the joint-torque loop the feed-forward drops D and dv (the loop's integral needs the
    motors' viscous damping); open loop keeps them."""
    kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
    c = cfg.deep_copy()
    c["controller"]["type"] = "impedance"
    closed = build_controller(c, kin, np.zeros(2)).friction
    # open loop the viscous terms are a negative damping on the motors: the law's must outweigh them
    # (the gain margin counts them; test_friction_ff_safety.py)
    c["controller"]["impedance"].update(torque_feedback="off", damping_dp=5.0, damping_ie=2.0)
    opened = build_controller(c, kin, np.zeros(2)).friction
    assert (closed.d, closed.dv) == (0.0, 0.0)
    assert (opened.d, opened.dv) == (cfg["actuator"]["damping"], 0.01)
    assert closed.torque(1.0, 0.5) == pytest.approx(opened.torque(1.0, 0.5) - 0.112 - 0.01)
