"""Linear analysis (paper eq. 6, Figs 8-11) and the `ankle-rt analyze` command."""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest
import yaml

from ankle_rt.analysis import (AXES, KNOWN_MISMATCH, PAPER, TOLERANCE, analyze, decoupled_input, frequency_response,
                               poles, position_outputs, soft_cables, unit_ratio, with_transmission)
from ankle_rt.cli import main
from ankle_rt.linear_model import LinearModel
from ankle_rt.params import PlantParams
from tests.conftest import ROOT


@pytest.fixture(scope="module")
def params() -> PlantParams:
    from ankle_rt.config import load_config
    return PlantParams.from_config(load_config(ROOT / "config" / "sim.yaml"))


@pytest.fixture(scope="module")
def result(params):
    return analyze(params)


# -- the figures the model must reproduce (issue 2 tolerances) -----------------------------------
def test_unit_ratio_resonances_match_fig8(result):
    assert result.values["resonance_unit_ratio_hz"]["dp"] == pytest.approx(23.0, rel=0.05)
    assert result.values["resonance_unit_ratio_hz"]["ie"] == pytest.approx(31.0, rel=0.05)


def test_low_frequency_offsets_match_fig9(result):
    assert result.values["offset_db"]["dp"] == pytest.approx(13.0, abs=0.5)
    assert result.values["offset_db"]["ie"] == pytest.approx(8.0, abs=0.5)


def test_offsets_are_the_lever_ratio(params, result):
    t = params.transmission
    assert result.values["offset_db"]["dp"] == pytest.approx(20 * math.log10(t.lever_dp / t.pulley_radius), abs=0.02)
    assert result.values["offset_db"]["ie"] == pytest.approx(20 * math.log10(t.lever_ie / t.pulley_radius), abs=0.02)


def test_dp_torque_resonance_matches_fig11(result):
    assert result.values["torque_resonance_hz"]["dp"] == pytest.approx(98.0, rel=0.05)


def test_known_mismatches_are_reported_with_the_models_values(result):
    """Fig. 10 and the IE torque resonance: the model's own values (docs/design.md), flagged, not failed."""
    assert result.values["fig10_resonance_hz"]["dp"] == pytest.approx(31.0, rel=0.02)
    assert result.values["fig10_resonance_hz"]["ie"] == pytest.approx(24.5, rel=0.02)
    assert result.values["torque_resonance_hz"]["ie"] == pytest.approx(77.0, rel=0.02)
    flagged = {(c.key, c.axis) for c in result.checks if c.status == "MISMATCH"}
    assert flagged == KNOWN_MISMATCH
    assert all(c.note for c in result.checks if c.status == "MISMATCH")
    assert result.ok


def test_every_check_is_judged_against_its_tolerance(result):
    assert len(result.checks) == len(PAPER) * len(AXES)
    for c in result.checks:
        kind, size = TOLERANCE[c.key]
        bound = size * c.paper if kind == "rel" else size
        assert (c.status == "PASS") == (abs(c.model - c.paper) <= bound), c


def test_a_wrong_geometry_fails_the_check(params):
    bad = analyze(with_transmission(params, lever_dp=0.07))
    failed = {(c.key, c.axis) for c in bad.checks if c.status == "FAIL"}
    assert ("offset_db", "dp") in failed and not bad.ok


# -- internal consistency of the linear analysis -------------------------------------------------
def test_resonance_peaks_sit_at_lightly_damped_poles(params, result):
    """The peak search and the eigenvalues are independent routes to the same modes."""
    for p, key in ((unit_ratio(params), "resonance_unit_ratio_hz"), (soft_cables(params), "fig10_resonance_hz")):
        ev, _ = poles(LinearModel.from_params(p))
        mode_hz = np.abs(ev[np.abs(ev.imag) > 1.0]) / (2 * math.pi)
        for axis in AXES:
            assert np.min(np.abs(mode_hz - result.values[key][axis])) < 0.01 * result.values[key][axis]


def test_cable_resonances_scale_with_root_stiffness(params, result):
    """Fig. 10 is the actual geometry at k/10: every cable mode divides by sqrt(10)."""
    ev, axes = poles(LinearModel.from_params(params))
    ev_soft, axes_soft = poles(LinearModel.from_params(soft_cables(params)))
    hz = {a: abs(s) / (2 * math.pi) for s, a in zip(ev, axes) if s.imag > 1.0}
    hz_soft = {a: abs(s) / (2 * math.pi) for s, a in zip(ev_soft, axes_soft) if s.imag > 1.0}
    for axis in AXES:
        assert hz[axis] / hz_soft[axis] == pytest.approx(math.sqrt(10.0), rel=0.01)


def test_decoupled_input_moves_one_ankle_axis_only(params):
    lm = LinearModel.from_params(params)
    freqs = np.array([1.0, 50.0, 200.0])
    for i in range(2):
        H = frequency_response(lm.A, decoupled_input(lm, i), position_outputs(), freqs)
        assert np.all(np.abs(H[:, 1 - i]) < 1e-9 * np.abs(H[:, i]))
        # both motors move with equal magnitude (same sign in DP, opposite in IE)
        np.testing.assert_allclose(H[:, 3], (1 if i == 0 else -1) * H[:, 2], rtol=1e-9)


def test_frequency_response_solves_the_state_equation(params):
    lm = LinearModel.from_params(params)
    b = decoupled_input(lm, 0)
    f = 37.0
    x = frequency_response(lm.A, b, np.eye(8), [f])[0]
    np.testing.assert_allclose(2j * math.pi * f * x, lm.A @ x + b, rtol=1e-9, atol=1e-15)


def test_paper_form_also_reproduces_the_figures(params):
    assert analyze(with_transmission(params, form="paper")).ok


# -- the command ---------------------------------------------------------------------------------
def test_analyze_json_has_the_documented_keys_within_tolerance(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the default config is found from anywhere
    assert main(["analyze", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["resonance_unit_ratio_hz"]["dp"] == pytest.approx(23.0, rel=0.05)
    assert out["resonance_unit_ratio_hz"]["ie"] == pytest.approx(31.0, rel=0.05)
    assert out["offset_db"]["dp"] == pytest.approx(13.0, abs=0.5)
    assert out["offset_db"]["ie"] == pytest.approx(8.0, abs=0.5)
    assert out["torque_resonance_hz"]["dp"] == pytest.approx(98.0, rel=0.05)
    assert out["paper"]["torque_resonance_hz"] == {"dp": 98.0, "ie": 70.0}
    assert len(out["poles"]) == 8 and out["ok"] is True
    assert out["plots"] is None  # --json writes no plots unless asked


def test_analyze_table_shows_model_beside_paper_and_writes_plots(tmp_path, capsys):
    assert main(["analyze", "--plots", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "22.26 Hz" in text and "23.0 Hz" in text and "PASS" in text and "MISMATCH" in text
    assert "known mismatch" in text
    pngs = sorted(p.name for p in tmp_path.glob("*.png"))
    assert pngs == ["fig10_soft_cables.png", "fig11_joint_torque.png", "fig8_unit_ratio.png",
                    "fig9_actual_geometry.png"]
    assert all((tmp_path / n).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for n in pngs)


def test_analyze_without_matplotlib_says_so_and_still_prints(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)  # import fails as if not installed
    assert main(["analyze", "--plots", str(tmp_path / "plots")]) == 0
    text = capsys.readouterr().out
    assert "matplotlib is not installed" in text and "98.33 Hz" in text
    assert not (tmp_path / "plots").exists()


def test_analyze_exits_1_when_a_figure_is_out_of_tolerance(tmp_path, capsys):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(yaml.safe_dump({"include": [str(ROOT / "config" / "sim.yaml")],
                                   "transmission": {"lever_dp": 0.07}}))
    assert main(["analyze", "--json", "--config", str(cfg)]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["ok"] is False
    assert any(c["status"] == "FAIL" and c["key"] == "offset_db" for c in out["checks"])


def test_analyze_names_a_missing_config_file(tmp_path, capsys):
    assert main(["analyze", "--config", str(tmp_path / "nope.yaml")]) == 2
    assert "nope.yaml" in capsys.readouterr().err


def test_analyze_says_when_the_plot_directory_cannot_be_made(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["analyze", "--plots", str(blocker / "plots")]) == 0
    text = capsys.readouterr().out
    assert "cannot create the plot directory" in text and "98.33 Hz" in text


def test_gain_set_margin_db_names_the_limiting_gain():
    """The shipped gains keep >= 6 dB over the robustness cases (no gain named); a torque-loop gain set
    that oscillates (kp 100, issue 19) is refused naming that kp (unstable on the gauges' loop); an unknown key
    is refused by name."""
    from ankle_rt.analysis import REQUIRED_GAIN_MARGIN_DB, gain_set_margin_db
    from ankle_rt.config import load_config
    from ankle_rt.paths import default_config_path
    from tests.loop_configs import gauge_loop_config

    for cfg in (load_config(default_config_path()), gauge_loop_config()):    # the encoders' rate, the gauges'
        cfg["controller"]["type"] = "impedance"
        margin, name = gain_set_margin_db(cfg, {})
        assert margin >= REQUIRED_GAIN_MARGIN_DB and name is None
        bad, why = gain_set_margin_db(cfg, {"kp_ie": 100.0})
        assert bad < REQUIRED_GAIN_MARGIN_DB and why == "kp_ie"
    assert bad == -math.inf                 # on the gauges' loop (the issue's): unstable
    with pytest.raises(ValueError, match="nonsense"):
        gain_set_margin_db(cfg, {"nonsense": 1.0})
    cfg["controller"]["type"] = "pd"
    with pytest.raises(ValueError, match="kp_ie"):
        gain_set_margin_db(cfg, {"kp_ie": 1.0})
