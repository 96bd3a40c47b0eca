"""The friction feed-forward cannot make an accepted config oscillate: it may cancel at most the friction
the config states (an over-compensation is a force pushing with the motion: a limit cycle no linear
margin sees), and its viscous terms count in the sampled loop's gain margin (a negative damping on the
motors). docs/daemon.md, "Friction feed-forward"."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from ankle_rt.config import ConfigError, load_config
from ankle_rt.control import build_controller
from ankle_rt.control.friction import FrictionFeedForward
from ankle_rt.control.pd import MotorPD
from ankle_rt.daemon import run_lockstep
from ankle_rt.kinematics import Kinematics
from ankle_rt.params import TransmissionParams
from ankle_rt.paths import default_config_path


def _build(overrides: dict | None = None, path=None) -> None:
    """Load and build the controller, as `config check` and `run` do (ConfigError naming the key)."""
    cfg = load_config(path or default_config_path(), overrides)
    build_controller(cfg, Kinematics.from_params(TransmissionParams(**cfg["transmission"])), np.zeros(2))


def _late_swing(run) -> tuple[float, str]:
    """(peak-to-peak set current of motor 1 over the run's second half, A; the fault's name)."""
    i1 = run["current_cmd_1"]
    return float(np.ptp(i1[len(i1) // 2:])), run.summary["fault"]


def test_an_over_compensating_coulomb_feed_forward_limit_cycles_and_is_refused():
    """Before: friction_ff.coulomb 3 N m (the identified 0.28 x 10) passed config check, and under the
    shipped PD the motors limit-cycled at 9 Hz, +-3 A, with no fault (100 N m: 4 Hz, +-15 A, the ankle
    swinging 28 deg). Now it is refused at load and when the controller is built, naming the key."""
    cfg = load_config(default_config_path())
    kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
    c = cfg["controller"]
    pd = MotorPD(kin, np.zeros(2), **c["step_gains"], dt=1e-3, ramp_s=c["gain_ramp_s"],
                 soft_start_s=c["soft_start_s"], friction=FrictionFeedForward(3.0, cfg["actuator"]["damping"], 0.05))
    pd.ref = np.zeros(2)
    swing, fault = _late_swing(run_lockstep(cfg, 3.0, controller=pd))   # what the setting does
    assert swing > 4.0 and fault == "NONE"

    with pytest.raises(ConfigError, match=r"controller\.friction_ff\.coulomb: the feed-forward exceeds"):
        _build({"controller": {"friction_ff": {"enabled": True, "coulomb": 3.0}}})
    with pytest.raises(ConfigError, match=r"controller\.friction_ff\.viscous"):
        _build({"controller": {"friction_ff": {"enabled": True, "viscous": 6.0}}})
    # the identified values themselves (the defaults) are accepted and settle
    shipped = load_config(default_config_path(), {"controller": {"friction_ff": {"enabled": True}}})
    swing, fault = _late_swing(run_lockstep(shipped, 3.0))
    assert swing < 0.5 and fault == "NONE"


def test_an_identified_model_with_more_friction_than_the_config_states_is_refused(tmp_path):
    """model: identified from a file whose friction exceeds the plant the running config states (and
    checks its margin on) names controller.friction_ff.model_file."""
    base = default_config_path()
    (tmp_path / "model.yaml").write_text(yaml.safe_dump({"include": [str(base)], "actuator": {"coulomb": 1.5}}))
    (tmp_path / "run.yaml").write_text(yaml.safe_dump({
        "include": [str(base)], "controller": {"friction_ff": {"enabled": True, "model": "identified",
                                                               "model_file": "model.yaml"}}}))
    with pytest.raises(ConfigError, match=r"controller\.friction_ff\.model_file: the feed-forward exceeds"):
        _build(path=tmp_path / "run.yaml")


def test_the_feed_forwards_viscous_term_counts_in_the_gain_margin():
    """Open-loop impedance at the shipped gains with the feed-forward on: its viscous term cancels the
    motors' damping, and with the friction range's half viscous friction the loop is unstable. Before
    it passed config check (in the simulator the ankle rang at 19 deg peak to peak with no fault); now
    it is refused, the reply naming the feed-forward, while the same gains without the feed-forward
    and more damping with it are accepted. set_gains of the PD counts it too."""
    open_loop = {"type": "impedance", "impedance": {"torque_feedback": "off"}}
    with pytest.raises(ConfigError, match=r"controller\.impedance\.\w+: .*with the friction feed-forward's viscous"):
        _build({"controller": {**open_loop, "friction_ff": {"enabled": True}}})
    _build({"controller": open_loop})
    damped = {"type": "impedance", "impedance": {"torque_feedback": "off", "damping_dp": 5.0, "damping_ie": 2.0}}
    _build({"controller": {**damped, "friction_ff": {"enabled": True}}})

    cfg = load_config(default_config_path(), {"controller": {"friction_ff": {"enabled": True}}})
    kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
    with_ff = MotorPD(kin, np.zeros(2), kp=90.0, kd=5.0, dt=1e-3, ramp_s=0.2,
                      friction=FrictionFeedForward.from_config(cfg), margin_cfg=cfg)
    without = MotorPD(kin, np.zeros(2), kp=90.0, kd=5.0, dt=1e-3, ramp_s=0.2, margin_cfg=cfg)
    without.check_gains(kd=0.2)
    with pytest.raises(ValueError, match="friction feed-forward's viscous 0.112"):
        with_ff.check_gains(kd=0.2)
