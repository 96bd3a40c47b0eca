"""Controller plugins: found through the entry-point group ``ankle_rt.controllers``, built from the
config, run by the daemon in lockstep, and always followed by the safety layer.

Entry points are made discoverable the way an installed package makes them: a ``*.dist-info``
directory with ``entry_points.txt`` on ``sys.path``.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ankle_rt.config import ConfigError, load_config
from ankle_rt.control.base import Controller
from ankle_rt.controller_registry import BUILTIN_CONTROLLERS, ENTRY_POINT_GROUP, available_controllers
from ankle_rt.daemon import run_lockstep
from ankle_rt.safety import Fault, State

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "ankle-rt-example-controller"


class HugeCurrent(Controller):
    """A broken plugin: asks for 1e9 A worth of torque."""

    def update(self, est, out_torque):
        out_torque[0] = 1e9 * self.context.torque_constant
        out_torque[1] = -1e9 * self.context.torque_constant


class NotANumber(Controller):
    """A broken plugin: NaN after 0.2 s of simulated time."""

    def update(self, est, out_torque):
        out_torque[0] = math.nan if est.t > 0.2 else 0.0
        out_torque[1] = 0.0


class RaisesInUpdate(Controller):
    """A broken plugin: its update raises."""

    def update(self, est, out_torque):
        raise ZeroDivisionError("plugin bug")


class RaisesTheCurrentLimit(Controller):
    """A hostile plugin: writes amplifier.current_limit_peak = 15 A, then asks for 1e9 A."""

    def __init__(self, context):
        super().__init__(context)
        try:
            context.cfg["amplifier"]["current_limit_peak"] = 15.0
        except TypeError as exc:
            type(self).refused = str(exc)

    def update(self, est, out_torque):
        out_torque[0] = 1e9 * self.context.torque_constant
        out_torque[1] = 0.0


def raising_factory(ctx):
    raise RuntimeError("cannot build")


def exiting_factory(ctx):
    raise SystemExit(0)     # a plugin calling sys.exit() must not end `run` silently with success


def install_entry_points(where: Path, entries: dict[str, str]) -> str:
    """Write a dist-info declaring ``entries`` in the controllers group under ``where``; return the
    directory to put on sys.path / PYTHONPATH."""
    dist = where / "ankle_rt_test_plugins-0.0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: ankle-rt-test-plugins\nVersion: 0.0\n")
    (dist / "entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\n"
                                           + "".join(f"{name} = {value}\n" for name, value in entries.items()))
    return str(where)


@pytest.fixture
def plugins(tmp_path, monkeypatch):
    """The example plugin and the broken test plugins, discoverable as entry points."""
    monkeypatch.syspath_prepend(str(EXAMPLE / "src"))
    monkeypatch.syspath_prepend(install_entry_points(tmp_path / "site", {
        "load_stiffening": "ankle_rt_example_controller:LoadStiffening",
        "huge_current": "tests.test_controller_plugins:HugeCurrent",
        "not_a_number": "tests.test_controller_plugins:NotANumber",
        "raises_limit": "tests.test_controller_plugins:RaisesTheCurrentLimit",
        "missing_module": "no_such_module_xyz:Controller",
    }))


def plugin_config(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "plugin.yaml"
    path.write_text(f"include: [{ROOT / 'config' / 'sim.yaml'}]\n" + body)
    return path


def test_builtins_are_registered_by_name_and_plugins_are_found(plugins):
    import ankle_rt.control.impedance  # noqa: F401  (a submodule must not shadow its factory's name)
    import ankle_rt.control.pd  # noqa: F401
    from ankle_rt.controller_registry import load_controller_factory

    for name in BUILTIN_CONTROLLERS:
        assert callable(load_controller_factory(name))
    found = available_controllers()
    assert {"pd", "impedance"} <= set(found) and found["pd"] == BUILTIN_CONTROLLERS["pd"]
    assert found["load_stiffening"] == "ankle_rt_example_controller:LoadStiffening"


def test_example_plugin_runs_the_section7_experiment_through_the_daemon(plugins, tmp_path):
    cfg = load_config(EXAMPLE / "run.yaml")
    assert cfg["controller"]["type"] == "load_stiffening"
    rec = run_lockstep(cfg, 2.0)
    assert rec.summary["fault"] == "NONE"
    t, ref, ankle = rec["t"], rec["ref_dp"], rec["est_ankle_dp"]
    settled = (t > 1.5) & (t < 2.0)                           # 10 deg DP step at 0.5 s, disturbance from 2 s
    assert ref[settled][0] == pytest.approx(math.radians(10.0), rel=1e-4)
    assert np.max(np.abs(ankle[settled] - ref[settled])) < math.radians(1.0)
    assert np.all(rec["state"][t > 0.5] == State.ACTIVE)


def test_plugin_parameters_are_checked_before_the_run(plugins, tmp_path):
    cfg = load_config(plugin_config(tmp_path, "controller: {type: load_stiffening, params: {stiffness: [60, -1], "
                                              "damping: [1, 1]}}\n"))
    with pytest.raises(ConfigError, match=r"controller.params.stiffness: expected \[DP, IE\]"):
        run_lockstep(cfg, 0.1)
    with pytest.raises(ConfigError, match="controller.type: unknown controller 'phase'.*load_stiffening"):
        load_config(plugin_config(tmp_path, "controller: {type: phase}\n"))
    cfg = load_config(plugin_config(tmp_path, "controller: {type: pd, params: {kp: 5}}\n"))
    with pytest.raises(ConfigError, match=r"controller.params: controller 'pd': the built-in controller 'pd' takes no"):
        run_lockstep(cfg, 0.1)
    cfg = load_config(plugin_config(tmp_path, "controller: {type: missing_module}\n"))
    with pytest.raises(ConfigError, match="cannot load no_such_module_xyz"):
        run_lockstep(cfg, 0.1)


def test_safety_clamps_a_plugin_asking_for_1e9_amperes(plugins, tmp_path):
    cfg = load_config(plugin_config(tmp_path, "controller: {type: huge_current}\n"))
    peak = cfg["amplifier"]["current_limit_peak"]
    rec = run_lockstep(cfg, 1.0)
    sent = np.concatenate([rec["current_cmd_1"], rec["current_cmd_2"]])
    assert np.max(np.abs(sent)) == pytest.approx(peak)          # clamped, never beyond the peak
    assert rec["torque_cmd_1"].max() > 1e8                       # what the plugin asked for is logged
    assert rec.summary["fault"] != "NONE"          # the first check it breaks (I2t, ankle range, motor speed) stops it
    after = rec["state"] == State.FAULT
    assert after.any() and np.all(rec["current_cmd_1"][after] == 0.0)


def test_a_plugin_cannot_raise_the_current_limit_through_the_config(plugins, tmp_path):
    cfg = load_config(plugin_config(tmp_path, "controller: {type: raises_limit}\namplifier: {current_limit_peak: 8.0}\n"))
    rec = run_lockstep(cfg, 0.3)
    assert rec["torque_cmd_1"].max() > 1e8                     # it asked for far more than 8 A
    assert np.max(np.abs(rec["current_cmd_1"])) == pytest.approx(8.0)   # the configured clamp held
    assert cfg["amplifier"]["current_limit_peak"] == 8.0
    assert "read-only" in RaisesTheCurrentLimit.refused and "current_limit_peak" in RaisesTheCurrentLimit.refused


def test_safety_faults_a_plugin_returning_nan(plugins, tmp_path):
    cfg = load_config(plugin_config(tmp_path, "controller: {type: not_a_number}\n"))
    rec = run_lockstep(cfg, 0.5)
    assert rec.summary["fault"] == Fault.OUTPUT_INVALID.name
    k = int(np.flatnonzero(rec["state"] == State.FAULT)[0])
    assert rec["t"][k] > 0.2 and rec["current_cmd_1"][k] == 0.0 and rec["current_cmd_2"][k] == 0.0
    assert np.all(np.isfinite(rec["current_cmd_1"])) and np.all(rec["current_cmd_1"][k:] == 0.0)


def test_cli_runs_a_plugin_found_on_the_python_path(tmp_path):
    site = install_entry_points(tmp_path / "site", {"load_stiffening": "ankle_rt_example_controller:LoadStiffening"})
    env = {"PYTHONPATH": f"{site}:{EXAMPLE / 'src'}:{ROOT}", "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-m", "ankle_rt.cli", "run", "--fast", "--duration", "1", "--no-plot",
                          "--no-log", "--config", str(EXAMPLE / "run.yaml")],
                         capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "controller load_stiffening" in out.stdout and "stopped after 1000 cycles" in out.stdout, out.stdout


def test_a_plugin_that_raises_gets_a_message_naming_it_not_a_traceback(tmp_path, monkeypatch, capsys):
    from ankle_rt.cli import main

    site = tmp_path / "site"
    monkeypatch.syspath_prepend(install_entry_points(site, {
        "syntax_error": "broken_syntax_xyz:C", "import_raises": "import_raises_xyz:C", "empty": ":",
        "factory_raises": "tests.test_controller_plugins:raising_factory",
        "factory_exits": "tests.test_controller_plugins:exiting_factory",
        "update_raises": "tests.test_controller_plugins:RaisesInUpdate"}))
    (site / "broken_syntax_xyz.py").write_text("def (\n")
    (site / "import_raises_xyz.py").write_text("raise RuntimeError('plugin import failed')\n")
    for name, reason in (("syntax_error", "SyntaxError"), ("import_raises", "plugin import failed"),
                         ("empty", "cannot load"), ("factory_raises", "failed to build: RuntimeError: cannot build"),
                         ("factory_exits", "failed to build: SystemExit")):
        assert main(["config", "check", str(plugin_config(tmp_path, f"controller: {{type: {name}}}\n"))]) == 2
        assert f"controller.type: controller '{name}'" in capsys.readouterr().err
        with pytest.raises(ConfigError, match=reason):
            run_lockstep(load_config(plugin_config(tmp_path, f"controller: {{type: {name}}}\n")), 0.1)
    cfg = plugin_config(tmp_path, "controller: {type: update_raises}\n")
    assert main(["run", "--fast", "--duration", "0.3", "--no-log", "--no-plot", "--config", str(cfg)]) == 1
    assert "the cycle raised ZeroDivisionError: plugin bug; the run ended in the safe state" in capsys.readouterr().err


class ResetRaises(Controller):
    """A broken plugin: its reset (called on activation) raises; its update would drive 5 A."""

    def reset(self, est):
        raise ValueError("plugin cannot reset")

    def update(self, est, out_torque):
        out_torque[0] = 5.0 * self.context.torque_constant
        out_torque[1] = 0.0


class Scribbler(Controller):
    """A buggy plugin: negates its 'copy' of the torque map in place and writes its own target into the
    reference (numpy aliasing); it carries on when refused."""

    def __init__(self, context):
        super().__init__(context)
        self.refused = []
        for write in (lambda: context.kin.R_inv_T.__imul__(-1.0), lambda: context.ref.__setitem__(0, 0.5)):
            try:
                write()
            except ValueError as exc:
                self.refused.append(str(exc))

    def update(self, est, out_torque):
        out_torque[0] = out_torque[1] = 0.0


def service_daemon():
    """A lockstep daemon that waits for ``activate`` (as a service does), tared after 0.3 s."""
    from tests.daemon_helpers import lockstep_daemon, run_cycles, variant

    daemon = lockstep_daemon(variant(load_config(ROOT / "config" / "sim.yaml"), safety={"auto_activate": False}))
    run_cycles(daemon, 300)
    return daemon


def test_a_plugin_whose_reset_raises_is_refused_and_not_activated():
    """Before: the reply was an error, yet the amplifiers were on and the daemon ACTIVE, driving 5 A."""
    from ankle_rt.control.base import ControllerContext
    from ankle_rt.service import protocol as proto
    from tests.daemon_helpers import run_cycles

    daemon = service_daemon()
    daemon.controller = ResetRaises(ControllerContext.from_config(daemon.cfg, daemon.kin, daemon.reference.ref))
    with pytest.raises(proto.CommandError) as refusal:
        daemon.handle(proto.Activate())
    run_cycles(daemon, 100)
    assert daemon.safety.state == State.CONFIGURED and not daemon.backend.active
    assert np.all(daemon.recorder.records["current_cmd_1"] == 0.0)
    assert "reset raised ValueError: plugin cannot reset" in str(refusal.value)
    daemon.close()


def test_a_plugin_cannot_change_the_maps_or_the_reference_the_next_controller_uses():
    """Before: the plugin's in-place negation reached the impedance controller switched in after it:
    commanded +5 deg, the foot ran the other way to ANKLE_RANGE at -40 deg 0.65 s after activation."""
    from ankle_rt.control.base import ControllerContext
    from ankle_rt.service import protocol as proto
    from tests.daemon_helpers import reply, run_cycles

    daemon = service_daemon()
    plugin = Scribbler(ControllerContext.from_config(daemon.cfg, daemon.kin, daemon.reference.ref))
    daemon.controller = plugin
    reply(daemon.handle(proto.SetController(type="impedance")))
    daemon.handle(proto.Activate())
    daemon.handle(proto.SetReference(dp=math.radians(5.0), ie=0.0, ramp=0.5))
    run_cycles(daemon, 1500)
    assert daemon.safety.fault == Fault.NONE
    assert abs(math.degrees(daemon.est.dp) - 5.0) < 1.0
    assert len(plugin.refused) == 2 and all("read-only" in why for why in plugin.refused)
    daemon.close()


class StiffHold(Controller):
    """A plugin with no soft start of its own: 400 N m/rad holding DP at +10 deg from its first cycle."""

    def update(self, est, out_torque):
        tau = 400.0 * (math.radians(10.0) - est.dp) - 2.0 * est.dp_vel
        r = self.context.kin.R_inv_T
        out_torque[0], out_torque[1] = r.item(0, 0) * tau, r.item(1, 0) * tau


def test_a_plugin_output_ramps_in_over_the_soft_start():
    """Before: 4.67 A on the first active cycle and the foot at 7.5 deg 0.1 s after activation. Now the
    output ramps in over controller.soft_start_s (0.2 s) as the built-ins' does, and the plugin still
    reaches its target."""
    from ankle_rt.control.base import ControllerContext
    from ankle_rt.service import protocol as proto
    from tests.daemon_helpers import run_cycles

    daemon = service_daemon()
    daemon.controller = StiffHold(ControllerContext.from_config(daemon.cfg, daemon.kin, daemon.reference.ref))
    daemon.handle(proto.Activate())
    run_cycles(daemon, 800)
    r = daemon.recorder.records
    active = np.flatnonzero(r["state"] == int(State.ACTIVE))
    current, ankle = np.abs(r["current_cmd_1"][active]), np.degrees(r["est_ankle_dp"][active])
    soft_s = daemon.cfg["controller"]["soft_start_s"]
    assert current[0] < 0.05 and ankle[100] < 2.0
    # never above the full output's scaled share while ramping
    ramp = np.arange(1, len(active) + 1) * daemon.dt / soft_s
    assert np.all(current[ramp < 1.0] <= 4.7 * ramp[ramp < 1.0] + 1e-9)
    assert daemon.safety.fault == Fault.NONE and abs(ankle[-1] - 10.0) < 2.0
    daemon.close()


class GaugeZeroer(StiffHold):
    """StiffHold (at 0 deg) that also "cleans" the gauges it reads: ``est.sg_dp = est.sg_ie = 0``."""

    def __init__(self, context):
        super().__init__(context)
        self.refused: list[str] = []

    def update(self, est, out_torque):
        try:
            est.sg_dp = est.sg_ie = 0.0
        except AttributeError as exc:
            if not self.refused:
                self.refused.append(str(exc))
        tau = -400.0 * est.dp - 2.0 * est.dp_vel
        r = self.context.kin.R_inv_T
        out_torque[0], out_torque[1] = r.item(0, 0) * tau, r.item(1, 0) * tau


def test_the_gauge_cross_check_sees_the_sensors_not_a_plugins_writes():
    """Safety8: a plugin could write the estimate's plain values between the sensor checks and the
    gauge cross-check of the same cycle. A DP gauge stuck at +15 N m from 1 s, hidden by a plugin that
    zeroes ``est.sg_dp``: before, no fault for the whole run (the cross-check compared the plugin's 0
    with the motors); now the plugin's view of the estimate refuses the write and the cross-check sees
    the stuck gauge: SG_MISMATCH within 0.2 s, and the log records the sensors' values."""
    from ankle_rt.clock import SimClock
    from ankle_rt.control.base import ControllerContext
    from ankle_rt.service import protocol as proto
    from tests.daemon_helpers import InjectingBackend, lockstep_daemon, run_cycles, variant

    cfg = variant(load_config(ROOT / "config" / "sim.yaml"), safety={"auto_activate": False})
    cfg["sim"]["disturbances"] = []

    def stuck(frame, cycle):
        frame.values[2] = 15.0 + daemon.estimator.offset[0]     # raw: tared, it reads 15 N m

    daemon = lockstep_daemon(cfg, backend=InjectingBackend(cfg, SimClock(), at=1000, mutate=stuck))
    run_cycles(daemon, 300)
    plugin = GaugeZeroer(ControllerContext.from_config(daemon.cfg, daemon.kin, daemon.reference.ref))
    daemon.controller = plugin
    daemon.handle(proto.Activate())
    run_cycles(daemon, 2000)
    r = daemon.recorder.records
    assert daemon.safety.fault == Fault.SG_MISMATCH
    t_fault = r["t"][np.flatnonzero(r["fault"])[0]]
    assert 1.0 < t_fault < 1.2
    assert plugin.refused and "read-only" in plugin.refused[0] and "sg_dp" in plugin.refused[0]
    late = r["t"] > 1.01
    assert np.all(np.abs(r["sg_torque_dp"][late & (r["t"] < t_fault)] - 15.0) < 1e-9)
    daemon.close()


class SlowHold(StiffHold):
    """StiffHold whose update takes 45 ms (the simulated clock moved on inside it) from its 100th call:
    each cycle overruns by less than loop.max_stall_s (50 ms)."""

    calls = 0

    def update(self, est, out_torque):
        super().update(est, out_torque)
        self.calls += 1
        if self.calls >= 100:
            self.clock.advance(45_000_000)


def test_overruns_in_a_row_fault_once_their_missed_time_passes_the_stall_limit():
    """Safety8: a plugin's update that takes 45 ms every cycle stays under the one-stall limit (50 ms),
    so only the overrun count stopped it: with loop.max_consecutive_overruns 50 (the most a device
    config may set) it controlled at 22 Hz on 45 ms old data for 2.5 s, the foot 10.4 deg past its
    10 deg target. The overruns in a row now share the stall limit: MISSED_DEADLINES once their missed
    deadlines add up to more than 50 ms, at the second slow cycle."""
    from ankle_rt.control.base import ControllerContext
    from ankle_rt.service import protocol as proto
    from tests.daemon_helpers import lockstep_daemon, run_cycles, variant

    cfg = variant(load_config(ROOT / "config" / "sim.yaml"), safety={"auto_activate": False},
                  loop={"max_consecutive_overruns": 50})
    cfg["sim"]["disturbances"] = []
    daemon = lockstep_daemon(cfg)
    run_cycles(daemon, 300)
    plugin = SlowHold(ControllerContext.from_config(daemon.cfg, daemon.kin, daemon.reference.ref))
    plugin.clock = daemon.clock
    daemon.controller = plugin
    daemon.handle(proto.Activate())
    run_cycles(daemon, 3000)
    assert daemon.safety.fault == Fault.MISSED_DEADLINES
    assert plugin.calls == 101 and daemon.loop.stats.overruns == 2
    r = daemon.recorder.records
    active = r["state"] == int(State.ACTIVE)
    assert np.degrees(r["ankle_dp"][active]).max() < 15.0
    daemon.close()
