"""The effects of the model-discrepancy vocabulary: registered, validated, physically right, and
integrated accurately by the compliant model (against a fine-step RK4 reference)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ankle_rt.config import ConfigError
from ankle_rt.params import PlantParams
from sim_backend.effects import EFFECTS, build_effects
from sim_backend.model import CompliantModel, rk4_step
from sim_backend.plant import SimulatedPlant

VOCABULARY = {"stribeck", "asymmetric_friction", "load_dependent_friction", "backlash", "cogging",
              "delay", "stiffness_nonlinear"}
DT = 1e-3


@pytest.fixture
def params(sim_cfg) -> PlantParams:
    return PlantParams.from_config(sim_cfg)


def test_every_vocabulary_word_has_an_effect_of_that_cause():
    causes = {cls.cause for cls in EFFECTS.values()}
    assert VOCABULARY <= causes
    for word in VOCABULARY:
        assert EFFECTS[word].cause == word


def test_bad_effect_parameter_names_its_key(params):
    with pytest.raises(ConfigError, match=r"sim\.effects\.0\.stribeck_velocity"):
        build_effects([{"type": "stribeck", "static_excess": 0.1, "stribeck_velocity": -1.0}], params, DT)
    with pytest.raises(ConfigError, match=r"sim\.effects\.1\.amplitude"):
        build_effects([{"type": "delay", "delay": 0.002}, {"type": "cogging", "periods_per_rev": 5}], params, DT)


def test_delay_line_shifts_the_command_by_whole_and_fractional_ticks(params):
    whole, = build_effects([{"type": "delay", "delay": 3 * DT}], params, DT)
    frac, = build_effects([{"type": "delay", "delay": 2.25 * DT}], params, DT)
    cmds = [float(k * k) for k in range(12)]
    out_w = [whole.command(c, -c)[0] for c in cmds]
    out_f = [frac.command(c, -c)[1] for c in cmds]
    assert out_w[3:] == cmds[:-3] and out_w[:3] == [0.0, 0.0, 0.0]
    expected = [-(0.75 * cmds[k - 2] + 0.25 * cmds[k - 3]) for k in range(3, 12)]
    assert np.allclose(out_f[3:], expected)
    whole.reset()
    assert whole.command(1.0, 1.0) == (0.0, 0.0)


def _free_motor(params, effects, torque, ticks=1500):
    """Motor 1 off the cables under a constant torque (N m); returns its final rate (rad/s)."""
    model = CompliantModel(params, dt=DT, cables=False, effects=build_effects(effects, params, DT))
    model.reset()
    for _ in range(ticks):
        model.step(torque, 0.0)
    return float(model.x[6])


def test_stribeck_raises_the_breakaway_torque(params):
    torque = params.actuator.coulomb + 0.1
    moving = _free_motor(params, [], torque)
    stuck = _free_motor(params, [{"type": "stribeck", "static_excess": 0.2, "stribeck_velocity": 0.05}], torque)
    assert moving > 0.5            # above kc it slides (towards (tau - kc) / D)
    assert abs(stuck) < 0.02       # below kc + excess it barely creeps (tanh-smoothed stiction)


def test_asymmetric_friction_makes_the_two_directions_differ(params):
    eff = [{"type": "asymmetric_friction", "coulomb_asymmetry": 0.1, "viscous_asymmetry": 0.02}]
    fwd = _free_motor(params, eff, 1.0, ticks=3000)
    back = _free_motor(params, eff, -1.0, ticks=3000)
    D, kc = params.actuator.damping, params.actuator.coulomb
    assert fwd == pytest.approx((1.0 - kc - 0.1) / (D + 0.02), rel=0.02)
    assert back == pytest.approx(-(1.0 - kc + 0.1) / (D - 0.02), rel=0.02)


def test_asymmetric_friction_and_stribeck_take_their_per_motor_sizes_and_shape(params):
    """Motor 2's own asymmetry (default motor 1's); the Stribeck shape exponent (2 Gaussian, 1 exponential)."""
    asym, = build_effects([{"type": "asymmetric_friction", "coulomb_asymmetry": 0.05,
                            "coulomb_asymmetry_2": 0.12, "viscous_asymmetry": 0.01}], params, DT)
    t1, t2 = asym.motor_torque(0.0, 0.0, 2.0, -2.0, 0.0, 0.0)
    assert t1 == pytest.approx(0.05 + 0.02, rel=1e-3) and t2 == pytest.approx(0.12 + 0.02, rel=1e-3)
    w, vs = 0.1, 0.05
    for e in (2.0, 1.0):
        strib, = build_effects([{"type": "stribeck", "static_excess": 0.2, "stribeck_velocity": vs,
                                 "exponent": e}], params, DT)
        assert strib.motor_torque(0.0, 0.0, w, w, 0.0, 0.0)[0] == pytest.approx(
            0.2 * math.exp(-(w / vs) ** e) * math.tanh(w / params.actuator.friction_smoothing_velocity))


@pytest.mark.parametrize("per", ["axis", "cable"])
def test_stiffening_with_slack_acts_on_the_taut_stretch_only(params, per):
    """Beside a dead zone of the same half-width the law acts on the stretch beyond it: nothing inside, the
    plain law at the stretch less the slack per axis outside (per cable: on each cable's own stretch)."""
    slack, s_h = 2e-4, 4e-4
    law = {"type": "stiffness_nonlinear", "hardening_stretch": s_h, "exponent": 2.0, "per": per}
    taut, = build_effects([{**law, "slack": slack}], params, DT)
    whole, = build_effects([law], params, DT)
    tr = params.transmission
    lever = tr.lever_dp      # a DP rotation alone stretches both cables by lever_dp x phi (m)
    inside = 0.5 * slack / lever
    assert taut.cable_torque(inside, 0.0, 0.0, 0.0) == (0.0, 0.0)
    outside = 3.0 * slack / lever
    tdp = taut.cable_torque(outside, 0.0, 0.0, 0.0)[0]
    assert tdp == pytest.approx(whole.cable_torque(outside - slack / lever, 0.0, 0.0, 0.0)[0], rel=1e-9)
    assert tdp > 0.0


def test_backlash_per_axis_may_give_the_ie_axis_a_width_of_its_own(params):
    """``half_width_ie``: the IE axis' dead zone is half_width_ie / R_IE, DP's stays half_width / R_DP; the
    key is refused with ``per: cable`` (one length per cable) and named in its entry."""
    tr = params.transmission
    own, = build_effects([{"type": "backlash", "half_width": 2e-4, "half_width_ie": 5e-5}], params, DT)
    shared, = build_effects([{"type": "backlash", "half_width": 2e-4}], params, DT)
    phi_ie = 1.2 * 5e-5 / tr.lever_ie        # beyond IE's own dead zone, inside the shared one
    assert shared.cable_torque(0.0, phi_ie, 0.0, 0.0)[1] == pytest.approx(-shared.k_ie * phi_ie)
    assert own.cable_torque(0.0, phi_ie, 0.0, 0.0)[1] == pytest.approx(-own.k_ie * 5e-5 / tr.lever_ie)
    phi_dp = 0.5 * 2e-4 / tr.lever_dp
    assert own.cable_torque(phi_dp, 0.0, 0.0, 0.0)[0] == shared.cable_torque(phi_dp, 0.0, 0.0, 0.0)[0]
    with pytest.raises(ConfigError, match=r"sim\.effects\.1\.half_width_ie: .*per: axis"):
        build_effects([{"type": "delay", "delay": 0.002},
                       {"type": "backlash", "half_width": 2e-4, "half_width_ie": 5e-5, "per": "cable"}], params, DT)


def test_torque_offset_shifts_both_directions_the_same_way(params):
    """Unlike friction asymmetry, a load torque keeps its sign when the motion reverses."""
    eff = [{"type": "torque_offset", "torque_1": 0.1}]
    fwd = _free_motor(params, eff, 1.0, ticks=3000)
    back = _free_motor(params, eff, -1.0, ticks=3000)
    D, kc = params.actuator.damping, params.actuator.coulomb
    assert fwd == pytest.approx((1.0 - kc - 0.1) / D, rel=0.02)
    assert back == pytest.approx(-(1.0 - kc + 0.1) / D, rel=0.02)


def test_cogging_holds_the_motor_at_a_ripple_minimum(params):
    eff = [{"type": "cogging", "amplitude": 0.5, "periods_per_rev": 40, "phase": 0.3}]
    model = CompliantModel(params, dt=DT, cables=False, friction=False, effects=build_effects(eff, params, DT))
    model.reset(np.array([0, 0, 0.05, 0, 0, 0, 0, 0], dtype=float))
    for _ in range(4000):
        model.step(0.0, 0.0)
    # resisting torque a sin(n th + p) = 0 with positive slope: n th + p = 0 (mod 2 pi)
    assert math.remainder(40 * model.x[2] + 0.3, 2 * math.pi) == pytest.approx(0.0, abs=0.05)


def _compare_with_rk4(params, effects, ticks=1000, load=8.0):
    """RMS joint-torque error (N m) of the compliant model against RK4 at dt/40, and the RMS torque."""
    model = CompliantModel(params, dt=DT, effects=build_effects(effects, params, DT))
    ref = CompliantModel(params, dt=DT, effects=build_effects(effects, params, DT))
    model.set_rest_at((0.0, 0.0))
    x = model.x.copy()
    err, size = [], []
    for k in range(ticks):
        t = k * DT
        tau1 = 3 * math.sin(2 * math.pi * 3 * t) + math.sin(2 * math.pi * 17 * t)
        tau2 = 2 * math.sin(2 * math.pi * 5 * t + 1)
        td = load * math.sin(2 * math.pi * 2 * t), 0.5 * load * math.sin(2 * math.pi * 1.3 * t)
        model.step(tau1, tau2, *td)
        a1, a2 = ref.command_torque(tau1, tau2)
        for _ in range(40):
            x = rk4_step(ref, x, DT / 40, a1, a2, *td)
        ref.set_state(x)
        truth = np.array(ref.joint_torque())
        err.append(truth - np.array(model.joint_torque()))
        size.append(truth)
    return np.sqrt(np.mean(np.square(err))), np.sqrt(np.mean(np.square(size)))


@pytest.mark.parametrize("effect", [
    {"type": "backlash", "half_width": 2e-4},
    {"type": "stiffness_nonlinear", "hardening_stretch": 3e-4},
    {"type": "load_dependent_friction", "coefficient": 0.3},
])
def test_compliant_model_stays_accurate_with_transmission_effects(params, effect):
    """At the configured default substeps, raised to the effect's declared minimum."""
    err, size = _compare_with_rk4(params, [effect])
    assert err < 0.005 * size


def test_an_effect_raises_the_substeps_to_its_minimum_and_no_further(sim_cfg):
    assert sim_cfg["sim"]["substeps"] < 4
    sim_cfg["sim"]["effects"] = [{"type": "backlash", "half_width": 2e-4}]
    assert SimulatedPlant(sim_cfg).model.substeps == 4
    sim_cfg["sim"]["substeps"] = 6
    assert SimulatedPlant(sim_cfg).model.substeps == 6
    sim_cfg["sim"]["substeps"] = 2
    sim_cfg["sim"]["effects"] = [{"type": "delay", "delay": 0.004}]
    assert SimulatedPlant(sim_cfg).model.substeps == 2


def test_effects_switch_on_from_the_config(sim_cfg):
    sim_cfg["sim"]["effects"] = [{"type": "delay", "delay": 0.004}]
    plant = SimulatedPlant(sim_cfg)
    assert [type(e).__name__ for e in plant.model.effects] == ["CoulombFriction", "ActuationDelay"]
    plant.step(1.0, 1.0)
    assert plant.model.tau_applied == [0.0, 0.0]
    sim_cfg["sim"]["effects"] = [{"type": "no_such_effect"}]
    with pytest.raises(ConfigError, match=r"sim\.effects\.0\.type"):
        SimulatedPlant(sim_cfg)
