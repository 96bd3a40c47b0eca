"""The diagnosis on the ground a real device gives: several effects at once, rotor cogging at its true
count through the gearbox, a constant load torque, sensor artefacts, gait-like and one-directional
motion, short records, and a residual nothing in the vocabulary explains.

Every case is simulated by sim_backend with its effects (tests/diagnosis_cases.py; seeded, the seed is in
every message); the tests require the exact set of hidden effects to be named, nothing else, and the
artefacts to be flagged, not named."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ankle_rt.cli import main
from ankle_rt.config import load_config
from ankle_rt.daemon import run_lockstep
from ankle_rt.diagnosis import diagnose
from ankle_rt.interchange import Recording, write_csv
from tests.diagnosis_cases import SIM_CONFIG, make_case, primary_error

pytestmark = pytest.mark.slow   # 8-80 s per test on a busy 2-core VM: deselected by -m 'not slow'

PARAM_TOLERANCE = 0.15
PHYSICAL = {"stribeck", "asymmetric_friction", "load_dependent_friction", "cogging", "delay", "backlash",
            "stiffness_nonlinear", "torque_offset"}


def _diagnose(**kwargs):
    case = make_case(ident_s=kwargs.pop("ident_s", 10.0), valid_s=kwargs.pop("valid_s", 5.0), **kwargs)
    print(case.describe())
    diag = diagnose(case.ident, case.valid, plant=case.plant, cfg=case.nominal_cfg)
    return case, diag, f"{case.describe()} -> {diag.causes} warnings {diag.data_warnings} notes {diag.notes}"


@pytest.mark.parametrize("seed,causes,motion", [
    (11, ["backlash", "delay"], "multisine"),            # the pair: delay was dropped
    (12, ["stribeck", "cogging"], "multisine"),          # Stribeck was dropped
    (13, ["stribeck", "delay"], "multisine"),            # delay absorbed, Stribeck 34 % high
    (33, ["cogging", "delay", "stribeck"], "multisine"),
    (22, ["delay", "stribeck"], "gait"),
    (26, ["asymmetric_friction", "load_dependent_friction"], "multisine"),
])
def test_several_effects_are_all_named_each_fitted_and_earning_its_place(seed, causes, motion):
    case, diag, msg = _diagnose(seed=seed, plant="ankle", cause=causes, motion=motion)
    assert sorted(diag.causes) == sorted(causes), msg
    assert diag.cause == diag.causes[0]
    for e in diag.effects:
        assert primary_error(case, e["parameters"], e["type"]) < PARAM_TOLERANCE, msg
        assert e["gain"] > 1.0, msg            # each one's own share of the validation gain
        assert e["confidence"] > 0.5, msg
    assert [x["type"] for x in diag.sim_effects] == [e["type"] for e in diag.effects]
    sizes = [e["size"] for e in diag.effects]
    assert sizes == sorted(sizes, reverse=True), msg     # strongest first
    assert diag.gain > 1.0 / 0.7, msg


def test_rotor_cogging_at_486_periods_from_the_readme_trajectory():
    """6 periods per motor turn x the 81:1 gearbox, 1 % of the rated torque, found without a prior on the
    README's identification run (a chirp through the daemon on the simulator)."""
    run = load_config(SIM_CONFIG, overrides={
        "reference": {"profile": "chirp", "chirp": {"amplitude_dp": 0.09, "amplitude_ie": 0.05, "f0_hz": 0.2,
                                                    "f1_hz": 3.0, "duration_s": 20.0, "start_s": 0.3}}})
    rated = run["actuator"]["torque_constant"] * run["amplifier"]["current_limit_continuous"]
    effect = {"type": "cogging", "amplitude": 0.01 * rated, "periods_per_rev": 486, "phase": 2.0}
    truth = load_config(SIM_CONFIG, overrides={"reference": run["reference"], "sim": {"effects": [effect]}})
    rec = Recording(run_lockstep(truth, 20.0).interchange(), "README run")
    diag = diagnose(rec, None, plant="ankle", cfg=run)
    assert diag.causes == ["cogging"], diag.notes
    p = diag.parameters
    assert p["periods_per_rev"]["value"] == 486
    assert p["amplitude"]["value"] == pytest.approx(effect["amplitude"], rel=0.05)
    assert diag.data_warnings == []


@pytest.mark.parametrize("seed,plant", [(18, "ankle"), (31, "actuator")])
def test_rotor_cogging_through_the_gearbox_on_random_motion(seed, plant):
    case, diag, msg = _diagnose(seed=seed, plant=plant, cause=["cogging"], rotor_cogging=True)
    n = case.effect["periods_per_rev"]
    assert n >= 4 * 81 and diag.causes == ["cogging"], msg
    assert diag.parameters["periods_per_rev"]["value"] == n, msg


@pytest.mark.parametrize("seed,causes", [(14, ["torque_offset"]), (102, ["asymmetric_friction"]),
                                         (53, ["asymmetric_friction", "torque_offset"])])
def test_a_load_offset_is_torque_offset_not_asymmetric_friction(seed, causes):
    case, diag, msg = _diagnose(seed=seed, plant="ankle", cause=causes)
    assert sorted(diag.causes) == sorted(causes), msg
    if "torque_offset" in causes:
        p = next(e for e in diag.effects if e["type"] == "torque_offset")["parameters"]
        truth = next(e for e in case.effects if e["type"] == "torque_offset")
        for k in ("torque_1", "torque_2"):
            assert p[k]["value"] == pytest.approx(truth[k], rel=PARAM_TOLERANCE), msg


@pytest.mark.parametrize("seed,artefact,words", [
    (15, "sg_clip", ("strain gauge", "clipped")), (16, "sg_drift", ("drift",)), (19, "sg_hold", ("held",)),
    (17, "current_limit", ("limit",)), (20, "dropouts", ("gap",)),
])
def test_sensor_artefacts_are_flagged_and_never_named(seed, artefact, words):
    _, diag, msg = _diagnose(seed=seed, plant="ankle", cause="none", artefacts=(artefact,))
    assert not set(diag.causes) & PHYSICAL, msg
    assert diag.data_warnings, msg
    assert all(any(w in text for text in diag.data_warnings) for w in words), msg


@pytest.mark.parametrize("seed,artefact,cause", [(29, "sg_clip", "delay"), (23, "current_limit", "stribeck"),
                                                 (28, "sg_drift", "stiffness_nonlinear")])
def test_an_effect_is_still_named_through_a_sensor_artefact(seed, artefact, cause):
    case, diag, msg = _diagnose(seed=seed, plant="ankle", cause=[cause], artefacts=(artefact,))
    assert diag.causes == [cause] and diag.data_warnings, msg
    assert primary_error(case, diag.parameters) < PARAM_TOLERANCE, msg


def test_currents_held_at_the_limit_most_of_the_time_are_flagged_and_nothing_is_named():
    """The issue's case: set currents on the amplifier's rail 60 % of the time (the recording holds
    the rail while the applied current does not follow it). The config states that amplifier limit:
    a flat extreme below the configured peak is the controller's clamp, which the current follows."""
    case = make_case(47, "ankle", "none", ident_s=10.0, valid_s=5.0)
    print(case.describe())
    level = float(np.percentile(np.abs(case.ident["current_cmd_1"]), 40))
    cfg = case.nominal_cfg.deep_copy()
    cfg["amplifier"]["current_limit_peak"] = cfg["amplifier"]["current_limit_continuous"] = level

    def railed(rec: Recording) -> Recording:
        cols = dict(rec.columns)
        for c in ("current_cmd_1", "current_cmd_2"):
            cols[c] = np.clip(cols[c], -level, level)
        return Recording(cols, rec.source)

    diag = diagnose(railed(case.ident), railed(case.valid), plant="ankle", cfg=cfg)
    assert not set(diag.causes) & PHYSICAL, diag.causes
    assert any("limit" in w for w in diag.data_warnings) and any("nothing is named" in w for w in diag.data_warnings)


def test_one_directional_motion_is_flagged_and_friction_asymmetry_not_tried():
    _, diag, msg = _diagnose(seed=21, plant="ankle", cause="none", motion="one_way")
    assert diag.causes == ["none"], msg
    assert any("one direction" in w for w in diag.data_warnings), msg
    assert not any(c["cause"] in ("asymmetric_friction", "torque_offset") for c in diag.candidates), msg
    _, diag, msg = _diagnose(seed=24, plant="ankle", cause=["cogging"], motion="one_way")
    assert diag.causes == ["cogging"], msg


def test_a_short_record_is_flagged_and_a_too_short_one_names_nothing():
    _, diag, msg = _diagnose(seed=41, plant="ankle", cause=["delay"], ident_s=4.0, valid_s=2.0)
    assert diag.causes == ["delay"] and any("short" in w for w in diag.data_warnings), msg
    case = make_case(42, "ankle", ["cogging"], ident_s=1.2, valid_s=0.6)
    diag = diagnose(case.ident, case.valid, plant="ankle", cfg=case.nominal_cfg)
    assert diag.causes == ["unknown"] and diag.effects == [], diag.notes
    assert any("too short" in w for w in diag.data_warnings)


@pytest.mark.parametrize("seed,effect,correlate", [(43, "position_friction", "position"),
                                                   (44, "kt_saturation", "torque level"),
                                                   (48, "friction_drift", "time (drift)")])
def test_an_unexplained_residual_is_unknown_with_what_it_correlates_with(seed, effect, correlate):
    _, diag, msg = _diagnose(seed=seed, plant="ankle", cause=effect)
    assert diag.causes == ["unknown"] and not diag.effects, msg
    assert diag.unexplained["motor"]["correlates_with"][0]["with"] == correlate, msg


def test_stribeck_friction_in_walking_data_is_named():
    """Walking reverses the motors within about a sample: friction regressors sampled at the instant read
    every reversal as a negative Stribeck effect that hid this one (vs 0.11 rad/s, static excess 0.126 N m,
    with asymmetric friction and backlash: not named even at vs 0.18 before they were the step mean)."""
    case, diag, msg = _diagnose(seed=1061, plant="ankle", cause=["asymmetric_friction", "stribeck", "backlash"],
                                motion="gait", ident_s=12.0, valid_s=6.0)
    assert sorted(diag.causes) == ["asymmetric_friction", "backlash", "stribeck"], msg
    stribeck = next(e for e in diag.effects if e["type"] == "stribeck")
    assert stribeck["gain"] > 1.0, msg
    # each reversal crosses the Stribeck band in a few samples: the data fix its impulse, static excess x
    # Stribeck velocity, more closely than either factor
    p, true = stribeck["parameters"], next(e for e in case.effects if e["type"] == "stribeck")
    impulse = p["static_excess"]["value"] * p["stribeck_velocity"]["value"]
    assert abs(impulse / (true["static_excess"] * true["stribeck_velocity"]) - 1.0) < PARAM_TOLERANCE, msg


@pytest.mark.parametrize("seed,plant,motion", [(45, "ankle", "gait"), (46, "actuator", "multisine")])
def test_effect_free_data_are_none(seed, plant, motion):
    _, diag, msg = _diagnose(seed=seed, plant=plant, cause="none", motion=motion)
    assert diag.causes == ["none"] and diag.unexplained is None and diag.gain == 1.0, msg


def test_cli_json_lists_every_effect_and_writes_them_all(tmp_path, capsys):
    case = make_case(11, "ankle", ["backlash", "delay"], ident_s=10.0, valid_s=5.0)
    print(case.describe())
    ident, valid = tmp_path / "ident.csv", tmp_path / "valid.csv"
    write_csv(ident, case.ident.columns)
    write_csv(valid, case.valid.columns)
    (tmp_path / "models").mkdir()
    model = tmp_path / "models" / "extended.yaml"
    capsys.readouterr()
    assert main(["diagnose", str(ident), "--validation", str(valid), "--config", str(SIM_CONFIG), "--json",
                 "--write-model", str(model), "--report", str(tmp_path / "report")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert sorted(out["causes"]) == ["backlash", "delay"] and out["cause"] == out["causes"][0]
    assert out["data_warnings"] == []
    for e in out["effects"]:
        assert {"type", "channel", "parameters", "confidence", "gain", "rss_share", "effect"} <= set(e)
    kinds = [c.get("catch_all", False) or c["cause"] == "none" for c in out["candidates"]]
    assert kinds == sorted(kinds), "none / unknown must not outrank a named candidate"
    text = model.read_text()
    assert str(tmp_path) not in text                     # the include is relative to the model file
    cfg = load_config(model)
    assert sorted(e["type"] for e in cfg["sim"]["effects"]) == ["backlash", "delay"]
    from sim_backend.plant import SimulatedPlant
    names = [type(e).__name__ for e in SimulatedPlant(cfg).model.effects]
    assert "ActuationDelay" in names and "Backlash" in names       # the simulator runs them together
    report = (tmp_path / "report" / "report.md").read_text()
    assert "Effect `backlash`" in report and "Effect `delay`" in report


def test_the_configs_cogging_prior_is_scored_and_the_search_reaches_2000_periods():
    from ankle_rt.diagnosis.candidates import Cogging
    from ankle_rt.diagnosis.core import build_channels, resolve_inputs

    case = make_case(61, "ankle", "none", ident_s=6.0, valid_s=3.0)
    cfg = case.nominal_cfg.deep_copy()
    cfg["diagnosis"] = {"cogging_periods_per_motor_rev": 7}
    inputs = resolve_inputs(case.ident, "ankle", cfg)
    assert inputs.cogging_prior == 7 * 81
    ch = build_channels(case.ident, inputs)["motor"]
    noise = np.random.default_rng(0).standard_normal(len(ch.target()))
    cog = Cogging()
    assert 7 * 81 in cog.search_grid(ch, noise, lambda n: cog.design(ch, n))
    assert cog.count_range(ch)[1] >= 2000
