"""Config loading: every kind of bad input stops with a message naming file, key and expectation."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from ankle_rt.config import ConfigError, load_config
from tests.conftest import ROOT, SIM_CONFIG


def write(tmp_path: Path, body: dict, name: str = "c.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump({"include": [str(ROOT / "config" / "nominal-params.yaml")], **body}))
    return path


def test_shipped_config_loads_with_nominal_values():
    cfg = load_config(SIM_CONFIG)
    assert cfg["backend"] == "sim"
    assert cfg["actuator"]["inertia"] == pytest.approx(0.048)
    assert cfg["controller"]["rate_hz"] == 1000
    assert cfg["transmission"]["form"] == "reciprocal"
    assert cfg["sim"]["effects"] == []


@pytest.mark.parametrize("body, key, expect", [
    ({"backend": "sim", "actuator": {"inertai": 0.05}}, "actuator.inertai", "unknown key"),
    ({"backend": "sim", "actuator": {"inertia": -0.05}}, "actuator.inertia", "must be >"),
    ({"backend": "sim", "actuator": {"inertia": "heavy"}}, "actuator.inertia", "expected a number"),
    ({"backend": "sim", "controller": {"rate_hz": 0}}, "controller.rate_hz", "must be >= 250"),
    ({"backend": "sim", "transmission": {"form": "magic"}}, "transmission.form", "expected one of"),
    ({"backend": "sim", "transmission": {"pulley_radius": 1e-300}}, "transmission.pulley_radius", "must be >= 0.001"),
    ({"backend": "sim", "transmission": {"lever_ie": 1e-9}}, "transmission.lever_ie", "must be >= 0.005"),
    ({"backend": "sim", "sim": {"strain_gauge_offset": [0.1]}}, "sim.strain_gauge_offset", "2 items"),
    ({}, "backend", "missing key"),
])
def test_bad_values_name_file_key_and_expectation(tmp_path, body, key, expect):
    path = write(tmp_path, body)
    with pytest.raises(ConfigError) as err:
        load_config(path)
    msg = str(err.value)
    assert key in msg and expect in msg
    assert err.value.key == key


def test_missing_physical_parameter_is_an_error_not_a_default(tmp_path):
    data = yaml.safe_load((ROOT / "config" / "nominal-params.yaml").read_text())
    del data["foot"]["inertia_ie"]
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump({"backend": "sim", **data}))
    with pytest.raises(ConfigError, match=r"foot\.inertia_ie: missing key"):
        load_config(path)


def test_error_names_the_file_the_key_came_from(tmp_path):
    data = yaml.safe_load((ROOT / "config" / "nominal-params.yaml").read_text())
    data["foot"]["mass"] = -1.0
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(data))
    (tmp_path / "main.yaml").write_text(yaml.safe_dump({"include": ["params.yaml"], "backend": "sim"}))
    with pytest.raises(ConfigError) as err:
        load_config(tmp_path / "main.yaml")
    assert err.value.source.endswith("params.yaml")


def test_include_cycle_and_missing_include_are_errors(tmp_path):
    (tmp_path / "a.yaml").write_text("include: [b.yaml]\n")
    (tmp_path / "b.yaml").write_text("include: [a.yaml]\n")
    with pytest.raises(ConfigError, match="include cycle"):
        load_config(tmp_path / "a.yaml")
    (tmp_path / "c.yaml").write_text("include: [nowhere.yaml]\n")
    with pytest.raises(ConfigError, match="nowhere.yaml"):
        load_config(tmp_path / "c.yaml")


def test_invalid_yaml_and_unknown_backend(tmp_path):
    (tmp_path / "bad.yaml").write_text("backend: [sim\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(tmp_path / "bad.yaml")
    from ankle_rt.backend import open_backend
    from ankle_rt.clock import SimClock
    cfg = load_config(write(tmp_path, {"backend": "simulatr"}))
    with pytest.raises(ConfigError, match="unknown backend 'simulatr'"):
        open_backend(cfg, SimClock())


def test_unknown_effect_and_bad_effect_parameter(tmp_path):
    from sim_backend.plant import SimulatedPlant
    cfg = load_config(write(tmp_path, {"backend": "sim", "sim": {"effects": [{"type": "warp_drive"}]}}))
    with pytest.raises(ConfigError, match=r"sim\.effects\.0\.type.*unknown effect 'warp_drive'"):
        SimulatedPlant(cfg)
    cfg = load_config(write(tmp_path, {"backend": "sim",
                                       "sim": {"effects": [{"type": "coulomb", "coulomb": -1.0,
                                                            "smoothing_velocity": 0.01}]}}))
    with pytest.raises(ConfigError, match=r"sim\.effects\.0\.coulomb: must be >= 0"):
        SimulatedPlant(cfg)


def test_config_data_validates_again_to_the_same_config():
    """What set_controller re-checks: a loaded config, as data, passes the same validation unchanged."""
    from ankle_rt.config import config_data, config_from_data

    for name in ("sim.yaml", "hw-serial.yaml", "hw-canopen.yaml"):
        cfg = load_config(ROOT / "config" / name)
        data = config_data(cfg)
        assert None not in _leaves(data)
        assert config_from_data(data, lambda key: name, name) == cfg


def _leaves(data: dict) -> list:
    return [v for value in data.values() for v in (_leaves(value) if isinstance(value, dict) else [value])]


def _config_text(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "c.yaml"
    path.write_text(f"include: [{SIM_CONFIG}]\n" + body)
    return path


def test_duplicate_keys_are_refused_naming_the_key_and_line(tmp_path):
    path = _config_text(tmp_path, "amplifier:\n  current_limit_peak: 5\n  current_limit_peak: 15\n")
    with pytest.raises(ConfigError) as err:
        load_config(path)
    msg = str(err.value)
    assert "duplicate key 'current_limit_peak'" in msg and "line 4" in msg and "line 3" in msg


def test_a_yaml_alias_bomb_is_refused_before_it_expands(tmp_path):
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, 9)]   # 10^9 strings
    path = _config_text(tmp_path, "controller:\n  params:\n" + "".join(f"    {line}\n" for line in lines))
    with pytest.raises(ConfigError, match="alias"):
        load_config(path)


def test_a_plain_alias_is_refused_too(tmp_path):
    path = _config_text(tmp_path, "limits: &l {ankle_range_deg: 20}\ncontroller: {params: {copy: *l}}\n")
    with pytest.raises(ConfigError, match="line 2.*alias"):
        load_config(path)


def test_a_config_of_too_many_nodes_is_refused(tmp_path, monkeypatch):
    import ankle_rt.config as config

    monkeypatch.setattr(config, "MAX_CONFIG_NODES", 50)
    path = _config_text(tmp_path, "controller:\n  params: {xs: [" + ", ".join(["1"] * 60) + "]}\n")
    with pytest.raises(ConfigError, match="more than 50 YAML nodes"):
        load_config(path)


def test_every_torque_loop_file_is_a_whole_loop_so_including_one_replaces_the_one_before(tmp_path):
    """sim.yaml includes the encoder-rate loop and hw-*.yaml replace it with the gauges' loop: a loop file that
    left a key out would keep the earlier file's value for it, a hybrid loop nobody tuned or checked."""
    from ankle_rt.config_schema import TORQUE_LOOP
    loop_keys = {k for k in TORQUE_LOOP.fields if not k.startswith("max_correction")}
    files = sorted((ROOT / "config").glob("torque-loop-*.yaml"))
    assert len(files) >= 6
    for path in files:
        keys = set(yaml.safe_load(path.read_text())["controller"]["torque_loop"])
        assert keys == loop_keys, (path.name, sorted(loop_keys - keys))
    gauges = yaml.safe_load((ROOT / "config" / "torque-loop-gauges.yaml").read_text())["controller"]["torque_loop"]
    base = tmp_path / "after_encoders.yaml"
    base.write_text(f"include: [{ROOT / 'config' / 'sim.yaml'}, {ROOT / 'config' / 'torque-loop-gauges.yaml'}]\n")
    loop = load_config(base)["controller"]["torque_loop"]
    assert {k: loop[k] for k in gauges} == gauges
    assert load_config(SIM_CONFIG)["controller"]["torque_loop"]["torque_rate_source"] == "encoders"
    for name in ("hw-serial.yaml", "hw-canopen.yaml", "bench-canopen.yaml"):
        loop = load_config(ROOT / "config" / name)["controller"]["torque_loop"]
        assert {k: loop[k] for k in gauges} == gauges, name
