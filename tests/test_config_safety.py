"""Issue 10 items 1, 5: no NaN, inf or huge number passes the config, and the safety layer refuses
one on its own; config files are read as bounded, regular, UTF-8 files."""

from __future__ import annotations

import math
import os
import threading

import numpy as np
import pytest
import yaml

from ankle_rt.backend import open_backend
from ankle_rt.clock import SimClock
from ankle_rt.config import MAX_CONFIG_BYTES, ConfigError, load_config, numeric_fields
from ankle_rt.config_schema import SCHEMA
from ankle_rt.references import PROFILE_PARAMS
from ankle_rt.safety import Safety
from ankle_rt.schema import Section
from tests.conftest import ROOT

NOMINAL = str(ROOT / "config" / "nominal-params.yaml")


def write(tmp_path, body: dict, name: str = "c.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump({"include": [NOMINAL], "backend": "sim", **body}))
    return path


BAD_NUMBERS = [math.nan, math.inf, -math.inf, 1.0e9]
KEYS = [("amplifier", "current_limit_peak"), ("amplifier", "current_limit_continuous"),
        ("limits", "ankle_range_deg"), ("safety", "max_motor_speed_rad_s"), ("safety", "sg_rail_nm"),
        ("safety", "max_sg_step_nm"), ("safety", "i2t_peak_duration_s"), ("loop", "duration_s"),
        ("foot", "mass"), ("actuator", "inertia"), ("controller", "gain_ramp_s")]


@pytest.mark.parametrize("section, key", KEYS, ids=[".".join(k) for k in KEYS])
@pytest.mark.parametrize("value", BAD_NUMBERS, ids=["nan", "inf", "-inf", "1e9"])
def test_nan_inf_and_huge_numbers_are_refused_naming_the_key(tmp_path, section, key, value):
    path = write(tmp_path, {section: {key: value}})
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert err.value.key == f"{section}.{key}"
    assert "finite" in err.value.message or "must be" in err.value.message


def test_nan_in_a_nested_list_and_an_effect_parameter_is_refused(tmp_path):
    with pytest.raises(ConfigError, match=r"sim\.strain_gauge_offset\.1: expected a finite number"):
        load_config(write(tmp_path, {"sim": {"strain_gauge_offset": [0.0, math.nan]}}))
    cfg = load_config(write(tmp_path, {"sim": {"effects": [{"type": "stribeck", "static_excess": math.inf,
                                                            "stribeck_velocity": 0.01}]}}))
    with pytest.raises(ConfigError, match=r"sim\.effects\.0\.static_excess: expected a finite number"):
        open_backend(cfg, SimClock())     # effect parameters are checked by the simulator that owns them


def test_currents_beyond_the_escon_ratings_are_refused(tmp_path):
    with pytest.raises(ConfigError, match=r"amplifier\.current_limit_peak: must be <= 15"):
        load_config(write(tmp_path, {"amplifier": {"current_limit_peak": 15.5}}))
    with pytest.raises(ConfigError, match=r"amplifier\.current_limit_continuous: must be <= 5"):
        load_config(write(tmp_path, {"amplifier": {"current_limit_continuous": 6.0}}))
    with pytest.raises(ConfigError, match=r"amplifier\.current_limit_peak: must be >= amplifier\.current_limit_cont"):
        load_config(write(tmp_path, {"amplifier": {"current_limit_peak": 4.0}}))


def test_configured_gains_must_lie_within_the_gain_limits(tmp_path):
    with pytest.raises(ConfigError, match=r"controller\.step_gains\.kp: must be <= controller\.gain_limits\.kp"):
        load_config(write(tmp_path, {"controller": {"rate_hz": 1000, "validation_gains": {"kp": 80, "kd": 0.3},
                                                    "step_gains": {"kp": 90, "kd": 5},
                                                    "gain_limits": {"kp": 85}}}))


def test_huge_integers_are_refused_not_overflowed(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(f"include: [{NOMINAL}]\nbackend: sim\nfoot: {{mass: {10**400}}}\n")
    with pytest.raises(ConfigError, match=r"foot\.mass: number out of range"):
        load_config(path)


def test_every_numeric_key_of_the_schema_has_both_bounds():
    unbounded = [key for key, f in (*numeric_fields(SCHEMA), *numeric_fields(Section(PROFILE_PARAMS)))
                 if f.choices is None and (f.low is None or f.high is None)]
    assert unbounded == ["service.socket_mode"]      # octal bits, bounded by its own check (0..0o777)


# -- the files themselves -----------------------------------------------------------------------------

def test_a_config_that_is_not_utf8_is_a_config_error(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_bytes(b"backend: sim\nfoot: {mass: 0.4}  # \xff\xfe latin-1 \xe9\n")
    with pytest.raises(ConfigError, match="not UTF-8 text"):
        load_config(path)


def test_include_of_dev_zero_fails_at_once(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("include: [/dev/zero]\nbackend: sim\n")
    with pytest.raises(ConfigError, match=r"/dev/zero.*not a regular file \(a character device\)"):
        load_config(path)


def test_include_of_a_fifo_does_not_block(tmp_path):
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    path = tmp_path / "c.yaml"
    path.write_text("include: [pipe.yaml]\nbackend: sim\n")
    result = []
    worker = threading.Thread(target=lambda: result.append(pytest.raises(ConfigError, load_config, path)))
    worker.start()
    worker.join(30.0)                        # a guard: it returns at once, or the open blocked
    assert not worker.is_alive(), "load_config blocked on a FIFO"
    assert "not a regular file (a FIFO)" in str(result[0].value)


def test_a_config_larger_than_the_limit_is_refused(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("backend: sim\n" + "#" * MAX_CONFIG_BYTES)
    with pytest.raises(ConfigError, match="too large"):
        load_config(path)


def test_deeply_nested_yaml_is_a_config_error(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("backend: " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(ConfigError):
        load_config(path)


# -- the safety layer checks its own limits ---------------------------------------------------------

@pytest.mark.parametrize("section, key", [("amplifier", "current_limit_peak"), ("amplifier", "current_limit_continuous"),
                                          ("limits", "ankle_range_deg"), ("safety", "max_motor_speed_rad_s"),
                                          ("safety", "sg_rail_nm"), ("safety", "max_sg_step_nm"),
                                          ("safety", "i2t_peak_duration_s"), ("safety", "stale_cycles")])
@pytest.mark.parametrize("value", [math.nan, math.inf, 1.0e9, -1.0, 0])
def test_safety_refuses_a_limit_that_would_disable_a_check(sim_cfg, section, key, value):
    sim_cfg[section][key] = value                  # bypassing the config loader, as a caller could
    with pytest.raises(ConfigError) as err:
        Safety(sim_cfg, 0.001)
    assert err.value.key == f"{section}.{key}"


def test_a_jump_limit_the_rail_would_always_beat_is_refused():
    sim = ROOT / "config" / "sim.yaml"
    for step in (225.0, 450.0):                    # the shipped rail 225 N m; at 450 SG_JUMP can never trip
        with pytest.raises(ConfigError) as err:
            load_config(sim, {"safety": {"max_sg_step_nm": step}})
        assert err.value.key == "safety.max_sg_step_nm" and "sg_rail_nm" in err.value.message
    assert load_config(sim, {"safety": {"max_sg_step_nm": 224.0}})["safety"]["max_sg_step_nm"] == 224.0


def test_the_current_clamp_holds_for_any_command(sim_cfg):
    s = Safety(sim_cfg, 0.001)
    peak = sim_cfg["amplifier"]["current_limit_peak"]
    for i1, i2 in [(1e300, -1e300), (16.0, -15.0001), (-1e9, 3.0), (math.nextafter(peak, 99), 0.0)]:
        s.limit_currents(i1, i2)
        assert max(abs(c) for c in s.current) <= peak
    for bad in (math.nan, math.inf, -math.inf):
        assert s.limit_currents(bad, 0.0) != 0 and s.current == [0.0, 0.0]


DEVICE_DEADLINES = [("hw-serial", "loop", "max_stall_s", 0.5), ("hw-serial", "loop", "max_consecutive_overruns", 1000),
                    ("hw-serial", "safety", "stale_cycles", 1000), ("hw-canopen", "safety", "stale_cycles", 101),
                    ("hw-serial", "serial", "link_timeout_s", 1.0), ("hw-serial", "serial", "watchdog_s", 1.0),
                    ("hw-canopen", "canopen", "heartbeat_consumer_ms", 5000),
                    ("hw-canopen", "canopen", "rpdo_timeout_ms", 0), ("hw-canopen", "canopen", "rpdo_timeout_ms", 101)]


@pytest.mark.parametrize("config, section, key, value", DEVICE_DEADLINES,
                         ids=[f"{c}-{k}-{v}" for c, _, k, v in DEVICE_DEADLINES])
def test_the_device_may_not_act_on_old_data_or_set_values_for_long(config, section, key, value):
    """The schema admits up to 10 s / 10^6 overruns / 1000 stale cycles / 1 s timeouts for simulated
    runs; on the device the loop would drive on a frozen sample, or the motors keep the last set
    values, that long (serial bench, TPDOs or samples lost while holding 10 deg: 1001 cycles on the
    frozen sample with stale_cycles 1000 and link_timeout_s 1.0, before LINK_LOST), so a hardware
    config is refused naming the key; the simulator keeps the range."""
    with pytest.raises(ConfigError, match=f"{section}.{key}: must be <= "):
        load_config(ROOT / "config" / f"{config}.yaml", {section: {key: value}})
    if section in ("loop", "safety"):
        assert load_config(ROOT / "config" / "sim.yaml", {section: {key: value}})[section][key] == value


def test_an_optional_bounded_number_set_to_null_is_unset_not_a_crash():
    """A bounded field whose kind admits None (a cogging effect's amplitude_2) may be written null: it
    stays unset (was a TypeError from comparing None with the bound); a value given is still held
    to the bound, refused naming the key."""
    from ankle_rt.params import PlantParams
    from sim_backend.effects.base import build_effects

    cfg = load_config(ROOT / "config" / "sim.yaml")
    plant = PlantParams.from_config(cfg)
    effect = {"type": "cogging", "amplitude": 0.05, "periods_per_rev": 486, "amplitude_2": None}
    assert build_effects([effect], plant, 1e-3)[0].a2 == 0.05       # unset: motor 1's amplitude
    with pytest.raises(ConfigError, match="sim.effects.0.amplitude_2"):
        build_effects([dict(effect, amplitude_2=-1.0)], plant, 1e-3)


@pytest.mark.parametrize("degrees", [40.5, 90.0])
def test_the_ankle_range_is_at_most_the_devices_range_of_motion(degrees):
    """Safety8: the paper states the ankle's range of motion, +/-40 deg in DP and IE, set by software
    limits alone (no end stop). Before, up to 90 was accepted: with 90, ``set_reference`` to 85 deg
    drove the simulated foot to 85 deg, no fault. Refused naming the key; 40 is accepted."""
    sim = ROOT / "config" / "sim.yaml"
    with pytest.raises(ConfigError) as err:
        load_config(sim, {"limits": {"ankle_range_deg": degrees}})
    assert err.value.key == "limits.ankle_range_deg" and "must be <= 40" in err.value.message
    assert load_config(sim, {"limits": {"ankle_range_deg": 40.0}})["limits"]["ankle_range_deg"] == 40.0


def test_a_configured_sine_the_motors_cannot_follow_is_refused():
    """Safety8: a configured profile is not rate-limited at run time (a commanded one is). A 5 Hz,
    0.6 rad DP sine was accepted: the PD ran between the +-15 A clamps (14.8 A RMS, the foot +-8 deg at
    5 Hz, below the oscillation detector's band) for 21 s until the I2t's OVERCURRENT. Now the sine's
    motor-side rate must stay below safety.max_motor_speed_rad_s (at 0.6 rad: 1.77 Hz); at 1.7 Hz the
    foot follows (+-30 deg) without reaching the peak current."""
    from ankle_rt.daemon import run_lockstep

    sim = ROOT / "config" / "sim.yaml"
    sine = {"profile": "sine", "sine": {"amplitude_dp": 0.6, "frequency_hz": 5.0}}
    with pytest.raises(ConfigError) as err:
        load_config(sim, {"reference": sine})
    assert err.value.key == "reference.sine.frequency_hz" and "max_motor_speed_rad_s" in err.value.message
    with pytest.raises(ConfigError) as err:
        load_config(sim, {"reference": {"profile": "chirp", "chirp": {"amplitude_dp": 0.6, "f1_hz": 5.0}}})
    assert err.value.key == "reference.chirp.f1_hz"
    cfg = load_config(sim, {"reference": {**sine, "sine": {"amplitude_dp": 0.6, "frequency_hz": 1.7}},
                            "sim": {"disturbances": []}})
    r = run_lockstep(cfg, 3.0)
    late = r["t"] > 1.0
    assert r.summary["fault"] == "NONE" and np.abs(r["current_cmd_1"][late]).max() < 12.0
    assert np.degrees(r["ankle_dp"][late]).max() > 28.0


def test_a_configured_gait_stride_the_motors_cannot_follow_is_refused():
    """A configured gait profile is not rate-limited at run time either: a 0.3 s stride at scale 2 held
    the 15 A clamp in 54 % of the cycles for 8 s with no fault. Its motor speed over the stride's table
    must stay below safety.max_motor_speed_rad_s (at scale 2: strides from 1.81 s); a 1.9 s stride at
    scale 2 is followed (-28 to +20 deg DP) at under 8 A, and the default stride is accepted."""
    from ankle_rt.daemon import run_lockstep

    sim = ROOT / "config" / "sim.yaml"
    with pytest.raises(ConfigError) as err:
        load_config(sim, {"reference": {"profile": "gait", "gait": {"stride_s": 0.3, "scale": 2.0}}})
    assert err.value.key == "reference.gait.stride_s" and "max_motor_speed_rad_s" in err.value.message
    load_config(sim, {"reference": {"profile": "gait"}})
    cfg = load_config(sim, {"reference": {"profile": "gait", "gait": {"stride_s": 1.9, "scale": 2.0}},
                            "sim": {"disturbances": []}})
    r = run_lockstep(cfg, 4.0)
    late = r["t"] > 1.0
    assert r.summary["fault"] == "NONE"
    assert max(np.abs(r["current_cmd_1"][late]).max(), np.abs(r["current_cmd_2"][late]).max()) < 8.0
    assert np.degrees(np.ptp(r["ankle_dp"][late])) > 40.0


def test_a_configured_csv_profile_is_rate_limited_like_a_commanded_one(tmp_path):
    """A configured CSV profile was played as written: a 5 Hz, 0.6 rad DP sine in the file held the PD
    at the 15 A clamp in 95 % of 10 s (RMS 14.7 A), no fault, as the configured sine did before its
    check (a file's rate cannot be checked like a formula's). Now it is limited to reference.max_rate_rad_s, approached from where
    the ankle is, as the same file started by a command is; and that limit itself must keep the motors
    below safety.max_motor_speed_rad_s (20 rad/s was accepted)."""
    from ankle_rt.daemon import run_lockstep

    t = np.arange(0.0, 3.0, 1e-3)
    path = tmp_path / "fast.csv"
    path.write_text("t,ref_dp,ref_ie\n" + "".join(f"{x:.3f},{0.6 * math.sin(2 * math.pi * 5.0 * x):.6f},0\n" for x in t))
    sim = ROOT / "config" / "sim.yaml"
    cfg = load_config(sim, {"reference": {"profile": "csv", "csv": {"path": str(path)}}, "sim": {"disturbances": []}})
    r = run_lockstep(cfg, 2.0)
    active = (r["state"][1:] == 1) & (r["state"][:-1] == 1)
    rate = np.abs(np.diff(r["ref_dp"]))[active] / np.diff(r["t"])[active]
    assert active.sum() > 1500 and rate.max() <= cfg["reference"]["max_rate_rad_s"] * (1 + 1e-9)
    assert r.summary["fault"] == "NONE" and r.summary["saturated_cycles"] == 0
    assert np.abs(r["ref_dp"]).max() > 0.1          # it follows the file, only slower
    with pytest.raises(ConfigError) as err:
        load_config(sim, {"reference": {"max_rate_rad_s": 20.0}})
    assert err.value.key == "reference.max_rate_rad_s" and "max_motor_speed_rad_s" in err.value.message


def test_a_configured_hold_is_approached_at_most_at_the_reference_rate_limit():
    """Safety9: a configured hold is approached from where the ankle is over reference.ramp_s, which
    accepts 0: a hold of (0.6, 0.3) rad with ramp_s 0 was a 34 / 17 deg step at activation under the
    PD, the 15 A clamp, MOTOR_JUMP 0.07 s after activation and the unpowered foot coasting on to
    116 deg. The approach now moves at most at reference.max_rate_rad_s, as a CSV profile's does."""
    from ankle_rt.daemon import run_lockstep

    sim = ROOT / "config" / "sim.yaml"
    cfg = load_config(sim, {"reference": {"profile": "hold", "hold": {"dp": 0.6, "ie": 0.3}, "ramp_s": 0.0},
                            "sim": {"disturbances": []}})
    r = run_lockstep(cfg, 1.0)
    active = (r["state"][1:] == 1) & (r["state"][:-1] == 1)
    rate = np.abs(np.diff(np.column_stack([r["ref_dp"], r["ref_ie"]]), axis=0))[active] / np.diff(r["t"])[active, None]
    assert active.sum() > 800 and rate.max() <= cfg["reference"]["max_rate_rad_s"] * (1 + 1e-9)
    assert r.summary["fault"] == "NONE" and r.summary["saturated_cycles"] == 0
    assert np.degrees(np.abs(r["ankle_dp"])).max() < cfg["limits"]["ankle_range_deg"]
    assert r["ref_dp"][-1] > 0.5                     # on its way to the hold, only slower


def test_a_velocity_filter_too_slow_for_walking_is_refused(tmp_path):
    """Safety9: estimation.velocity_cutoff_hz accepted down to 1 Hz, and every controller's damping
    acts on that filtered velocity. With config/walk.yaml (the gait phases' margins checked) 10 Hz
    faulted the walk at 100 kg normal cadence (OSCILLATION; 5 Hz: SG_MISMATCH at 75 kg with healthy
    gauges); 15 and 20 Hz walk all 108 strides of `bench walk` without a fault. Now at least 20 Hz,
    refused naming the key below; at 20 Hz the 100 kg wearer walks (on the classic torque loop: the
    shipped notched loop's gait-phase margins refuse the walk at 60 Hz and below)."""
    from ankle_rt.bench.walk import run_walk

    walk = ROOT / "config" / "walk.yaml"
    with pytest.raises(ConfigError) as err:
        load_config(walk, {"estimation": {"velocity_cutoff_hz": 10.0}})
    assert err.value.key == "estimation.velocity_cutoff_hz"
    path = write(tmp_path, {"include": [str(walk), str(ROOT / "config" / "torque-loop-classic.yaml")],
                            "estimation": {"velocity_cutoff_hz": 20.0}})
    assert run_walk(str(path), 100.0, "normal", strides=2).fault == "NONE"


def test_an_oscillation_hold_or_soft_start_that_faults_walking_is_refused(tmp_path):
    """Safety9, config/walk.yaml (`bench walk` wearers, 3 strides): safety.oscillation_hold_s was
    accepted down to 0: 0.1 s faulted the 100 kg walk (OSCILLATION, normal and fast cadence; 0.01 s
    every wearer), below the ~0.3 s a stable loop's saturated step keeps the band up, as the key's own
    description said. controller.soft_start_s was accepted up to 10 s, and the wearer walks while the
    output is scaled down: 10 s let the 100 kg wearer at fast cadence push the ankle into its range
    (ANKLE_RANGE; 4 s did not). Now at least 0.35 s and at most 2 s, refused naming the key beyond;
    at those bounds the 100 kg wearer walks."""
    from ankle_rt.bench.walk import run_walk

    walk = ROOT / "config" / "walk.yaml"
    for key, value in [(("safety", "oscillation_hold_s"), 0.1), (("controller", "soft_start_s"), 10.0)]:
        with pytest.raises(ConfigError) as err:
            load_config(walk, {key[0]: {key[1]: value}})
        assert err.value.key == ".".join(key)
    path = write(tmp_path, {"include": [str(walk)], "safety": {"oscillation_hold_s": 0.35},
                            "controller": {"soft_start_s": 2.0}})
    for cadence in ("normal", "fast"):
        assert run_walk(str(path), 100.0, cadence, strides=3).fault == "NONE"


def test_the_motors_must_render_the_wearers_walk_with_the_torque_loops_correction():
    """Safety9, config/walk.yaml (`bench walk`, 100 kg at fast cadence): the joint-torque loop's
    max_correction_dp was accepted up to 100 N m: on top of the wearer's push-off it held the 15 A clamp
    in 776 cycles (72 ms in a row; 50 N m: 14.7 A peak, none); an amplifier.current_limit_peak of 12 A
    held it in 580 cycles of 6 strides. The DP torque both motors give at the peak current must now
    cover the heaviest wearer's rendered walking moment (1.8 N m/kg x wearer.mass_kg) plus the
    correction, refused naming the key otherwise; a bench config that nobody walks on keeps its range."""
    walk = ROOT / "config" / "walk.yaml"
    for over, key in [({"controller": {"torque_loop": {"max_correction_dp": 100.0}}}, "controller.torque_loop.max_correction_dp"),
                      ({"amplifier": {"current_limit_peak": 12.0}}, "amplifier.current_limit_peak")]:
        with pytest.raises(ConfigError) as err:
            load_config(walk, over)
        assert err.value.key == key and "wearer.mass_kg" in err.value.message
    load_config(walk, {"controller": {"torque_loop": {"max_correction_dp": 40.0}}})
    load_config(ROOT / "config" / "sim.yaml", {"controller": {"type": "impedance",
                                                              "torque_loop": {"max_correction_dp": 100.0}}})


def test_the_ie_correction_must_fit_beside_the_walking_moment_on_each_motor(tmp_path):
    """Adv10: max_correction_ie had no walking bound. With config/torque-loop-lag-notch.yaml and
    max_correction_ie 100 (accepted) the IE loop's kick at toe-off held a motor at the 15 A clamp in 73
    cycles of 12 strides (100 kg fast). Each motor's share of the walking moment plus its share of
    either axis's clamp must fit in its peak torque: 100 is refused naming the key; the largest
    accepted value walks without touching the clamp."""
    from ankle_rt.bench.walk import run_walk

    walk, lag = ROOT / "config" / "walk.yaml", ROOT / "config" / "torque-loop-lag-notch.yaml"
    with pytest.raises(ConfigError) as err:
        load_config(walk, {"controller": {"torque_loop": {"max_correction_ie": 100.0}}})
    assert err.value.key == "controller.torque_loop.max_correction_ie" and "wearer.mass_kg" in err.value.message
    most = float(err.value.message.split("must be <= ")[1].split(" N m")[0])
    assert 20.0 <= most < 30.0          # the shipped 20 N m fits at 100 kg
    path = write(tmp_path, {"include": [str(walk), str(lag)],
                            "controller": {"torque_loop": {"max_correction_ie": most}}})
    run = run_walk(str(path), 100.0, "fast", strides=3)
    peak = load_config(path)["amplifier"]["current_limit_peak"]
    current = np.maximum(np.abs(run.columns["i1"]), np.abs(run.columns["i2"]))
    assert run.fault == "NONE" and current.max() < peak - 0.1


def test_a_gait_phase_dwell_longer_than_a_walking_phase_is_refused(tmp_path):
    """Safety9: controller.gait_phase.min_dwell_s was accepted up to 1 s, though no transition may
    happen before it and walking's shortest phase is 0.157 s (late stance, 100 kg fast, `bench walk`):
    0.3 s and 1 s faulted the 50 kg wearer at fast cadence (ANKLE_RANGE). Now at most 0.1 s, refused
    naming the key beyond; at 0.1 s that wearer walks."""
    from ankle_rt.bench.walk import run_walk

    walk = ROOT / "config" / "walk.yaml"
    with pytest.raises(ConfigError) as err:
        load_config(walk, {"controller": {"gait_phase": {"min_dwell_s": 0.3}}})
    assert err.value.key == "controller.gait_phase.min_dwell_s"
    path = write(tmp_path, {"include": [str(walk)], "controller": {"gait_phase": {"min_dwell_s": 0.1}}})
    assert run_walk(str(path), 50.0, "fast", strides=3).fault == "NONE"


def test_a_torque_loop_gain_that_limits_a_gait_phase_is_named_by_its_own_key():
    """Safety9: with the gait-phase controller a torque-loop gain that failed a phase's margin was
    named as a phase key that does not exist (controller.gait_phase.late_stance.cutoff_hz)."""
    from tests.daemon_helpers import lockstep_daemon

    cfg = load_config(ROOT / "config" / "walk.yaml", {"controller": {"torque_loop": {"cutoff_hz_dp": 1.0}}})
    with pytest.raises(ConfigError) as err:
        lockstep_daemon(cfg)                     # the phases' margins are checked when it is built
    assert err.value.key == "controller.torque_loop.cutoff_hz_dp"


def test_a_friction_feed_forward_the_loop_cannot_carry_is_refused(tmp_path):
    """Adv11: the stated friction was trusted. The feed-forward pushes with the motion by whatever the
    device lacks of it; stated 10 N m on the simulator's 0.28 (fraction 1, direction from the loop's
    error) tripped OSCILLATION after 7 strides at 50 kg, and 5 N m held 15 A in 233 cycles of 6
    strides at 100 kg fast. Now refused naming controller.friction_ff.fraction, unloaded beyond
    torque_constant x oscillation_rms_a and, where someone walks, beyond what the peak current leaves
    beside the walking moment and one clamp; the largest fraction accepted walks on the 0.28 plant
    without a fault and below the current clamp."""
    from ankle_rt.bench.walk import run_walk
    from ankle_rt.control.friction import FrictionFeedForward

    walk = ROOT / "config" / "walk.yaml"

    def stated(coulomb: float, fraction: float, mass: float) -> dict:
        return {"include": [str(walk)], "actuator": {"coulomb": coulomb}, "wearer": {"mass_kg": mass},
                "controller": {"friction_ff": {"enabled": True, "viscous": 0.0, "fraction": fraction,
                                               "error_band": 1e-9}}}

    for mass, coulomb, binds in ((50.0, 10.0, "safety.oscillation_rms_a"), (100.0, 1.5, "walking moment")):
        with pytest.raises(ConfigError) as err:
            FrictionFeedForward.from_config(load_config(write(tmp_path, stated(coulomb, 1.0, mass))))
        assert err.value.key == "controller.friction_ff.fraction" and binds in err.value.message
        most = float(err.value.message.split("must be <= ")[1].split(":")[0])
        path = write(tmp_path, stated(coulomb, most, mass))
        cfg = load_config(path)
        FrictionFeedForward.from_config(cfg)              # the largest named is accepted
        run = run_walk(str(path), mass, "fast", strides=3, plant_friction=0.28 / coulomb)
        current = np.maximum(np.abs(run.columns["i1"]), np.abs(run.columns["i2"]))
        assert run.fault == "NONE" and current.max() < cfg["amplifier"]["current_limit_peak"] - 0.1


def test_the_largest_friction_fraction_named_is_the_budget_over_the_stated_friction_and_is_accepted(tmp_path):
    """Adv12: with a stated 10 N m and the 1.66 N m unloaded budget the error named 0.165 and refused
    0.166 = 1.66 / 10 ("must be <= 0.166 ..., got 0.166" for the stated 1.66 x 0.1), the product
    0.166 x 10 rounding to 1.6600000000000001: the bound's comparison and its number allow for rounding."""
    from ankle_rt.control.friction import FrictionFeedForward

    def stated(fraction: float) -> dict:
        return {"include": [str(ROOT / "config" / "walk.yaml")], "actuator": {"coulomb": 10.0},
                "wearer": {"mass_kg": 50.0}, "controller": {"friction_ff": {"enabled": True, "viscous": 0.0,
                                                                               "fraction": fraction}}}

    with pytest.raises(ConfigError) as err:
        FrictionFeedForward.from_config(load_config(write(tmp_path, stated(1.0))))
    assert err.value.key == "controller.friction_ff.fraction" and err.value.message.startswith("must be <= 0.166:")
    FrictionFeedForward.from_config(load_config(write(tmp_path, stated(0.166))))
    with pytest.raises(ConfigError):
        FrictionFeedForward.from_config(load_config(write(tmp_path, stated(0.167))))


def test_a_friction_fraction_beyond_both_bounds_names_the_tighter():
    """Adv12: stated 10 N m at 100 kg exceeds both bounds; the error named the unloaded one's 0.166, and
    0.166 was then refused naming 0.09 (the walking budget's). Now the first error names the number
    both accept."""
    from ankle_rt.control.friction import FrictionFeedForward

    cfg = load_config(ROOT / "config" / "walk.yaml", {"actuator": {"coulomb": 10.0}, "wearer": {"mass_kg": 100.0},
                                                      "controller": {"friction_ff": {"enabled": True, "viscous": 0.0}}})
    with pytest.raises(ConfigError) as err:
        FrictionFeedForward.from_config(cfg)
    assert err.value.key == "controller.friction_ff.fraction" and "walking moment" in err.value.message
    most = float(err.value.message.split("must be <= ")[1].split(":")[0])
    assert 0.0 < most < 0.166
    cfg["controller"]["friction_ff"]["fraction"] = most
    FrictionFeedForward.from_config(cfg)                  # the number named is accepted


def test_the_walking_bound_counts_the_feed_forward_twice(tmp_path):
    """Adv12: counted once, a stated load coefficient of 0.5 at 75 kg was accepted at fraction 0.758 and,
    on a device without that friction, held 15 A in 2 cycles of 12 strides (normal cadence, seed 0;
    seed 2: 5; 85 kg fast: 5): braking the motion at push-off the feed-forward wound the DP correction
    to its clamp, then turned over with the velocity on top of it. Counted twice, the largest accepted
    walks below the clamp."""
    from ankle_rt.bench.walk import run_walk
    from ankle_rt.control.friction import FrictionFeedForward

    def stated(fraction: float) -> dict:
        return {"include": [str(ROOT / "config" / "walk.yaml")], "wearer": {"mass_kg": 75.0},
                "sim": {"effects": [{"type": "load_dependent_friction", "coefficient": 0.5}]},
                "controller": {"friction_ff": {"enabled": True, "model": "identified", "viscous": 0.0,
                                               "fraction": fraction}}}

    with pytest.raises(ConfigError) as err:
        FrictionFeedForward.from_config(load_config(write(tmp_path, stated(0.758))))
    assert err.value.key == "controller.friction_ff.fraction" and "twice" in err.value.message
    most = float(err.value.message.split("must be <= ")[1].split(":")[0])
    path = write(tmp_path, stated(most))
    run = run_walk(str(path), 75.0, "normal", strides=12, plant_friction=0.0)
    current = np.maximum(np.abs(run.columns["i1"]), np.abs(run.columns["i2"]))
    assert run.fault == "NONE" and current.max() < load_config(path)["amplifier"]["current_limit_peak"] - 0.1
