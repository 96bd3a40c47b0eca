"""The batch simulator against sim_backend, plant by plant: same model, effects, limits and sensors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_backend.batch import BatchPlant, PlantByPlant
from sim_backend.plant import SimulatedPlant

SECONDS = 5.0

# every registered effect at a magnitude that shows (two values per effect: the plants differ)
EFFECT_CASES = {
    "none": [[], []],
    "stribeck": [[{"type": "stribeck", "static_excess": 0.2, "stribeck_velocity": 0.05}],
                 [{"type": "stribeck", "static_excess": 0.4, "stribeck_velocity": 0.1}]],
    "asymmetric_friction": [[{"type": "asymmetric_friction", "coulomb_asymmetry": 0.05, "viscous_asymmetry": 0.02}],
                            [{"type": "asymmetric_friction", "coulomb_asymmetry": -0.08}]],
    "load_dependent_friction": [[{"type": "load_dependent_friction", "coefficient": 0.2}],
                                [{"type": "load_dependent_friction", "coefficient": 0.4}]],
    "backlash": [[{"type": "backlash", "half_width": 1e-4}], [{"type": "backlash", "half_width": 3e-4}]],
    "cogging": [[{"type": "cogging", "amplitude": 0.05, "periods_per_rev": 12}],
                [{"type": "cogging", "amplitude": 0.1, "periods_per_rev": 7, "phase": 0.5}]],
    "delay": [[{"type": "delay", "delay": 0.0025}], [{"type": "delay", "delay": 0.004}]],
    "stiffness_nonlinear": [[{"type": "stiffness_nonlinear", "hardening_stretch": 3e-4}],
                            [{"type": "stiffness_nonlinear", "hardening_stretch": 6e-4}]],
    "torque_offset": [[{"type": "torque_offset", "torque_1": 0.3, "torque_2": -0.1}],
                      [{"type": "torque_offset", "torque_1": -0.2}]],
}


def currents(t: float) -> tuple[float, float]:
    """A: set values moving both motors through friction reversals, now and then into the current limit."""
    i1 = 2.0 * math.sin(2 * math.pi * 1.1 * t) + 0.8 * math.sin(2 * math.pi * 13 * t) + (12.0 if 1.0 <= t < 1.05 else 0.0)
    i2 = 1.5 * math.sin(2 * math.pi * 0.7 * t + 1.0) - (20.0 if 3.0 <= t < 3.03 else 0.0)
    return i1, i2


def _configs(sim_cfg, effects_per_plant):
    cfgs = []
    for j, effects in enumerate(effects_per_plant):
        c = sim_cfg.deep_copy()
        c["sim"]["effects"] = effects
        c["sim"]["seed"] = 10 + j
        c["transmission"]["cable_stiffness"] *= (0.7, 1.3)[j % 2]
        c["actuator"]["coulomb"] *= (1.3, 0.7)[j % 2]
        c["sim"]["disturbances"] = [{"start": 2.0 + 0.5 * j, "stop": 2.6 + 0.5 * j, "torque_dp": 0.5, "torque_ie": -0.4}]
        cfgs.append(c)
    return cfgs


def _run_alone(cfg, ticks):
    plant = SimulatedPlant(cfg)
    out = np.empty((ticks, 8))
    sensors = np.empty((ticks, 4))
    for k in range(ticks):
        plant.step(*currents(k * plant.dt))
        out[k] = plant.model.x
        sensors[k] = plant.motor_positions() + plant.strain_gauge_torques()
    return out, sensors


def _run_batch(cfgs, ticks):
    batch = BatchPlant(cfgs)
    out = np.empty((ticks, 8, len(cfgs)))
    sensors = np.empty((ticks, 4, len(cfgs)))
    for k in range(ticks):
        i1, i2 = currents(k * batch.dt)
        batch.step(np.full(batch.n, i1), np.full(batch.n, i2))
        out[k] = batch.model.x
        sensors[k] = batch.motor_positions() + batch.strain_gauge_torques()
    return batch, out, sensors


@pytest.mark.parametrize("name", sorted(EFFECT_CASES))
def test_batch_matches_the_single_plant_for_every_effect(sim_cfg, name):
    cfgs = _configs(sim_cfg, EFFECT_CASES[name])
    ticks = round(SECONDS * 1000)
    batch, got, got_sensors = _run_batch(cfgs, ticks)
    for j, cfg in enumerate(cfgs):
        want, want_sensors = _run_alone(cfg, ticks)
        span = want.max(axis=0) - want.min(axis=0)
        assert np.all(span[:4] > 0.05)                     # the motion is not trivial
        rms = np.sqrt(np.mean((got[:, :, j] - want) ** 2, axis=0))
        assert np.all(rms < 1e-3 * span), (name, j, rms / span)
        s_span = want_sensors.max(axis=0) - want_sensors.min(axis=0)
        s_rms = np.sqrt(np.mean((got_sensors[:, :, j] - want_sensors) ** 2, axis=0))
        assert np.all(s_rms < 1e-3 * s_span), (name, j, s_rms / s_span)
    # the element-wise effects run stacked, others plant by plant
    for e in batch.model.effects:
        kind = e.kind if isinstance(e, PlantByPlant) else type(e)
        assert isinstance(e, PlantByPlant) == (not kind.elementwise)


def test_a_batch_refuses_plants_of_different_structure(sim_cfg):
    other = sim_cfg.deep_copy()
    other["sim"]["effects"] = [{"type": "delay", "delay": 0.002}]
    with pytest.raises(ValueError, match="same"):
        BatchPlant([sim_cfg, other])


def test_an_elementwise_effect_with_per_plant_tables_falls_back_to_plant_by_plant(sim_cfg):
    """Stacking turns numbers into arrays; other per-plant data (here a list) cannot be stacked, so
    the batch calls those plants one by one; equal data is shared."""
    from ankle_rt.params import PlantParams
    from sim_backend.batch import stack_effects
    from sim_backend.effects import build_effects

    params = PlantParams.from_config(sim_cfg)
    effects = [build_effects(case, params, 1e-3)[0] for case in EFFECT_CASES["stribeck"]]
    assert not isinstance(stack_effects(effects), PlantByPlant)
    for e in effects:
        e.table = [1.0, 2.0]
    assert stack_effects(effects).table == [1.0, 2.0]
    effects[1].table = [1.0, 3.0]
    assert isinstance(stack_effects(effects), PlantByPlant)


def test_bench_batch_prints_one_json_object_and_refuses_absurd_sizes(capsys):
    """`ankle-rt bench batch --json`: the issue's key with one factor per size; a size that would only
    exhaust memory (or is not a positive integer) is refused before anything runs."""
    import json

    from ankle_rt.cli import main

    assert main(["bench", "batch", "--seconds", "0.05", "--sizes", "1,3", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert set(result["realtime_factor_by_batch"]) == {"1", "3"}
    assert all(f > 0 for f in result["realtime_factor_by_batch"].values())
    assert set(result["plant_cycle_ref_steps_by_batch"]) == {"1", "3"} and result["reference_step_us"] > 0
    for bad in ("100000000", "0", "2.5", "1,,2"):
        assert main(["bench", "batch", "--sizes", bad, "--json"]) == 2
        assert "--sizes must be integers from 1 to" in capsys.readouterr().err
