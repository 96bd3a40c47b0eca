"""Valid files a lab's logs bring that the generators do not: stamps from any clock, a long pause in
irregular stamps, a dead encoder, gauges of the wrong sign, a baseline re-fit the config would refuse.
Each gets a verdict, and nothing the config refuses is simulated or written."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from ankle_rt.config import load_config
from ankle_rt.diagnosis import diagnose
from ankle_rt.diagnosis.closed_loop import closed_loop_gain
from ankle_rt.diagnosis.core import _gauges_against_stretch, _refit_problem, build_channels, resolve_inputs
from ankle_rt.diagnosis.model_fragment import fragment
from ankle_rt.diagnosis.resample import to_uniform_grid
from ankle_rt.diagnosis.screening import screen
from ankle_rt.interchange import Recording
from benchmarks.diagnosis_cases_d import draw_case_d, make_case_d
from tests.diagnosis_cases import SIM_CONFIG


@pytest.mark.parametrize("t0,period", [(-40.0, 1e-3), (1.0e6, 1e-3), (-40.0, 2e-3)])
def test_the_closed_loop_replays_a_record_from_its_first_stamp(t0, period):
    """Stamps counted from a later trigger (negative) or a clock's uptime: the re-run lasts the record's
    2 s (it simulated t[-1] s: a negative count, or a 1e6 s log buffer), taken at the record's own
    instants (a 500 Hz log beside the 1 kHz loop was compared sample by sample)."""
    t = t0 + period * np.arange(round(2.0 / period))
    wave = 0.01 * np.sin(2 * np.pi * t)
    cols = {"t": t, "ref_dp": wave, "ref_ie": wave,
            **{c: wave for c in ("motor_pos_1", "motor_pos_2", "ankle_dp", "ankle_ie")}}
    gain = closed_loop_gain(Recording(cols, "offset stamps"), SIM_CONFIG,
                            SimpleNamespace(actuator_refit=None, sim_effects=[]))
    assert gain.duration_s == pytest.approx(2.0, abs=period)
    assert gain.traces["t"][0] == 0.0 and len(gain.traces["baseline"]["ankle_dp"]) == t.size
    assert np.isfinite(gain.nrmse_baseline) and gain.nrmse_baseline == gain.nrmse_extended


def test_a_long_pause_in_irregular_stamps_is_left_out_of_the_grid():
    """A jittered 1 kHz log with a day's pause in the middle: a grid over the pause would hold 86 M rows (a
    MemoryError); it holds the logged stretches only, the rows beside the pause masked."""
    rng = np.random.default_rng(5)
    n = 4000
    t = 1e-3 * (np.arange(n) + rng.uniform(-0.3, 0.3, n))
    t[n // 2:] += 86400.0
    cols = {"t": t, "motor_pos_1": np.sin(t), "current_cmd_1": np.cos(t)}
    good = np.ones(n, dtype=bool)
    good[n // 2 - 1:n // 2 + 1] = False                  # screening masks the samples around a time gap
    rec, ok, note = to_uniform_grid(Recording(cols, "paused"), good)
    assert note and abs(len(rec) - n) <= 4
    assert np.allclose(rec["motor_pos_1"][ok], np.sin(rec["t"][ok]), atol=1e-5)
    pause = np.flatnonzero(np.diff(rec["t"]) > 1.0)
    assert len(pause) == 1 and not ok[pause[0]] and not ok[pause[0] + 1]


def test_a_baseline_re_fit_the_config_refuses_is_named():
    cfg = load_config(SIM_CONFIG)
    assert _refit_problem(cfg, {"coulomb": float(cfg["actuator"]["coulomb"])}) is None
    assert "actuator.coulomb" in _refit_problem(cfg, {"coulomb": -0.04})
    assert "unstable" in _refit_problem(cfg, {"inertia": 0.1 * float(cfg["actuator"]["inertia"])})


@pytest.fixture(scope="module")
def walking_case():
    """Generator D's seed 112: a multisine under the impedance law on a rig (a linear load), joint
    encoders logged, a gauge gain condition and no effect."""
    return make_case_d(**draw_case_d(112))


def _variant(rec: Recording, **cols: np.ndarray) -> Recording:
    return Recording({**rec.columns, **cols}, rec.source)


def test_gauges_of_the_wrong_sign_are_a_warning_and_nothing_named(walking_case):
    c = walking_case
    flip = {g: -c.ident[g] for g in ("sg_torque_dp", "sg_torque_ie")}
    vflip = {g: -c.valid[g] for g in ("sg_torque_dp", "sg_torque_ie")}
    diag = diagnose(_variant(c.ident, **flip), _variant(c.valid, **vflip), plant="ankle", cfg=c.nominal_cfg)
    assert diag.causes == ["unknown"] and diag.confidence == 0.0
    assert diag.unexplained is None                  # no remainder of an unusable record either
    assert any("read against the stretch" in w for w in diag.data_warnings), diag.data_warnings


@pytest.mark.parametrize("seed,change,against", [
    (112, "clean", False), (112, "flip", True), (112, "scale", False),
    (115, "clean", False), (115, "flip", True), (115, "scale", False)])
def test_gauges_against_the_stretch_are_told_from_an_encoder_scale_and_from_walking(seed, change, against):
    """Generator D's 112 (a rig) and 115 (walking, effect-free): both gauges flipped read against the
    stretch; motor angles read 0.9 x tilt it (the cable baseline alone fitted -2152 N m/rad on 112's DP),
    and in walking the spring law of the motor angles fits IE at -638 N m/rad (115): neither is flagged."""
    c = make_case_d(**draw_case_d(seed))
    cols = {"flip": {g: -c.ident[g] for g in ("sg_torque_dp", "sg_torque_ie")},
            "scale": {m: 0.9 * c.ident[m] for m in ("motor_pos_1", "motor_pos_2")}, "clean": {}}[change]
    rec = _variant(c.ident, **cols)
    chans = build_channels(rec, resolve_inputs(rec, "ankle", c.nominal_cfg))
    assert (_gauges_against_stretch([chans]) is not None) == against


@pytest.mark.parametrize("share,dead", [(0.1, False), (0.5, True)])
def test_a_still_motor_is_a_dead_encoder_only_while_driven_like_the_moving_one(share, dead):
    """A parked motor holds against a varying load with a small current: no finding. One whose current
    spans half the moving motor's while its count never changes has a dead encoder."""
    t = 1e-3 * np.arange(6000)
    cols = {"t": t, "motor_pos_1": 0.3 * np.sin(2 * np.pi * t), "motor_pos_2": np.full(t.size, 0.2),
            "current_cmd_1": 2.0 * np.cos(2 * np.pi * t), "current_cmd_2": share * 2.0 * np.sin(3 * t)}
    scr = screen(Recording(cols, "parked"), v_eps=0.01, current_limit=15.0)
    found = [w for w in scr.warnings if "motor_pos_2 never changes" in w]
    assert bool(found) == dead and scr.unusable == dead, scr.warnings


def test_a_dead_encoder_while_its_motor_is_driven_is_a_warning_and_nothing_named(walking_case):
    c = walking_case
    still = np.full(len(c.ident), float(c.ident["motor_pos_2"][0]))
    diag = diagnose(_variant(c.ident, motor_pos_2=still), c.valid, plant="ankle", cfg=c.nominal_cfg)
    assert diag.causes == ["unknown"]
    assert any("motor_pos_2 never changes while current_cmd_2 spans" in w for w in diag.data_warnings)


def test_a_one_way_record_writes_no_re_fit_the_config_refuses(walking_case, tmp_path):
    """Each motor's path folded to one direction (the logged currents kept): the baseline explains nothing
    and its Coulomb term fits below zero. It is named in a note and left out of the written config,
    which loads."""
    c = walking_case
    fold = {m: c.ident[m][0] + np.r_[0.0, np.cumsum(np.abs(np.diff(c.ident[m])))]
            for m in ("motor_pos_1", "motor_pos_2")}
    diag = diagnose(_variant(c.ident, **fold), None, plant="ankle", cfg=c.nominal_cfg)
    refused = [n for n in diag.notes if "re-fitted actuator baseline is not used" in n]
    assert refused and diag.actuator_refit is None, diag.notes
    out = tmp_path / "extended.yaml"
    frag = fragment(diag, SIM_CONFIG, out)
    assert "actuator" not in frag
    out.write_text(yaml.safe_dump(frag))
    load_config(out)
