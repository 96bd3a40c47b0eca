"""The first-day stumbles of issue 22, each pinned: one fault time, the missed-deadlines hint of a
simulated real-time run, and the CLI details a new user meets first."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from ankle_rt.cli import main
from ankle_rt.clock import SimClock
from ankle_rt.daemon import run_lockstep
from ankle_rt.commands import run as run_cmd
from ankle_rt.log.summary import summarize
from ankle_rt.safety import Fault, State
from tests.daemon_helpers import InjectingBackend, lockstep_daemon, run_cycles, variant

ROOT = Path(__file__).resolve().parent.parent


class WallLikeClock(SimClock):
    """A simulated clock that the daemon takes for the real one (a real-time run, deterministically)."""

    simulated = False


def stall_at(daemon, t_s: float, stall_ns: int) -> None:
    """Make the controller's cycle at sample time ``t_s`` take ``stall_ns`` (a busy machine)."""
    update = daemon.controller.update

    def slow(est, out):
        update(est, out)
        if abs(est.t - t_s) < 0.5e-3:             # the one cycle nearest t_s
            daemon.clock.advance(stall_ns)
    daemon.controller.update = slow


def test_a_missed_deadline_fault_has_one_time_in_safety_log_and_summary(sim_cfg):
    daemon = lockstep_daemon(sim_cfg)
    run_cycles(daemon, 400)
    stall_at(daemon, 0.45, 80_000_000)          # one 80 ms stall > loop.max_stall_s
    run_cycles(daemon, 200)
    rec = daemon.recorder.records
    assert daemon.safety.fault == Fault.MISSED_DEADLINES
    first = int(np.flatnonzero(rec["fault"] != Fault.NONE)[0])
    assert rec["t"][first] > 0.45 + 0.05        # the first record carrying it comes after the stall
    assert daemon.safety.fault_time == rec["t"][first]
    assert summarize(rec)["fault"]["t"] == daemon.safety.fault_time
    assert daemon.status()["fault_time_s"] == daemon.safety.fault_time
    daemon.close()


def test_a_missed_deadline_fault_in_the_run_s_last_cycle_is_still_recorded_with_its_time(sim_cfg):
    daemon = lockstep_daemon(sim_cfg)
    update = daemon.controller.update

    def slow_at_the_end(est, out):
        update(est, out)
        if est.t >= 0.39:
            daemon.clock.advance(80_000_000)    # the stall runs past the end of the run
    daemon.controller.update = slow_at_the_end
    daemon.run(0.4)
    rec = daemon.recorder.records
    assert daemon.safety.state == State.FAULT and daemon.safety.fault == Fault.MISSED_DEADLINES
    assert rec["fault"][-1] == Fault.MISSED_DEADLINES and rec["fault"][-2] == Fault.NONE
    assert daemon.safety.fault_time == rec["t"][-1]
    daemon.close()


def test_a_simulated_real_time_run_that_misses_deadlines_says_what_to_do(sim_cfg, capsys):
    daemon = lockstep_daemon(sim_cfg, backend=None)
    daemon.clock = WallLikeClock()
    daemon.safety.trip(Fault.MISSED_DEADLINES, 2.5)
    assert run_cmd._exit_code(daemon) == 1
    err = capsys.readouterr().err
    assert "ended in FAULT at t = 2.500 s: MISSED_DEADLINES" in err
    for what in ("--fast", "loop.realtime.priority", "loop.max_consecutive_overruns", "loop.max_stall_s",
                 "sim.max_stall_s / sim.max_consecutive_overruns (now 0.5 s / 50)"):
        assert what in err
    daemon.close()


def on_hardware(cfg):
    """``cfg`` as a run on the prosthesis through the serial bridge (the plant is not simulated here)."""
    hw = cfg.deep_copy()
    hw["backend"] = "serial"
    hw["serial"]["emulator"] = "none"
    return hw


class DeviceBackend(InjectingBackend):
    """A backend that does not say its plant is simulated (a real device, as the daemon must see it)."""

    simulated_plant = False


def test_sim_overrun_limits_need_the_backend_to_say_its_plant_is_simulated(sim_cfg):
    # the config says sim (hw-*.yaml include sim.yaml), but the backend handed in drives a device
    daemon = lockstep_daemon(sim_cfg, backend=DeviceBackend(sim_cfg, WallLikeClock()))
    assert not daemon.simulated_plant
    assert daemon.overrun_limits is sim_cfg["loop"]
    assert daemon.loop.max_consecutive == sim_cfg["loop"]["max_consecutive_overruns"]
    assert daemon.log_metadata()["sim_disturbances"] is None
    daemon.close()


def test_a_replayed_reference_is_refused_for_a_device(sim_cfg):
    """A reference generator handed to the daemon is played as given (no rate limit: a replay of
    recorded references): only on a simulated plant; a device follows configured or commanded ones."""
    from ankle_rt.daemon import Daemon
    from ankle_rt.references import Hold, ReferenceGenerator

    clock = WallLikeClock()
    backend = DeviceBackend(sim_cfg, clock)
    with pytest.raises(ValueError, match="only to a simulated plant"):
        Daemon(sim_cfg, clock, backend=backend, reference=ReferenceGenerator(Hold(0.3, 0.0)))
    assert not backend.active
    replayed = ReferenceGenerator(Hold(0.3, 0.0))
    daemon = lockstep_daemon(sim_cfg, backend=InjectingBackend(sim_cfg, SimClock()), reference=replayed)
    assert daemon.reference is replayed
    daemon.close()


def test_transports_count_as_hardware_unless_they_started_their_own_emulator(sim_cfg):
    from ankle_rt.backend import ForwardingBackend
    from hardware.serial_backend import SerialBackend
    from sim_backend.backend import SimBackend

    clock = SimClock()
    assert SimBackend(sim_cfg, clock).simulated_plant
    assert ForwardingBackend(SimBackend(sim_cfg, clock)).simulated_plant
    serial = SerialBackend.__new__(SerialBackend)   # only the attribute the property reads
    serial.emulator = None
    assert not serial.simulated_plant


@pytest.mark.parametrize("where", ["simulated plant, real time", "simulated plant, lockstep", "hardware, real time"])
def test_a_busy_host_stalls_a_simulated_real_time_run_without_a_fault_but_never_the_hardware(sim_cfg, where):
    cfg = on_hardware(sim_cfg) if where.startswith("hardware") else sim_cfg
    clock = SimClock() if where.endswith("lockstep") else WallLikeClock()
    daemon = lockstep_daemon(cfg, backend=InjectingBackend(sim_cfg, clock))
    tolerant = where == "simulated plant, real time"
    assert daemon.overrun_limits is (cfg["sim"] if tolerant else cfg["loop"])
    run_cycles(daemon, 400)
    stall_at(daemon, 0.45, 300_000_000)          # 0.3 s: above loop.max_stall_s, below sim.max_stall_s
    run_cycles(daemon, 400)
    assert daemon.safety.state == (State.ACTIVE if tolerant else State.FAULT)
    assert daemon.loop.stats.overruns == 1
    if tolerant:                                  # beyond sim.max_stall_s it still faults
        stall_at(daemon, daemon.est.t + 0.1, 600_000_000)
        run_cycles(daemon, 300)
        assert daemon.safety.fault == Fault.MISSED_DEADLINES
    daemon.close()


@pytest.mark.parametrize("case", ["lockstep", "other fault", "hardware"])
def test_the_hint_is_only_for_a_simulated_real_time_run_that_missed_deadlines(sim_cfg, capsys, case):
    daemon = lockstep_daemon(sim_cfg)
    if case != "lockstep":
        daemon.clock = WallLikeClock()
    if case == "hardware":
        daemon.cfg = on_hardware(daemon.cfg)
    daemon.safety.trip(Fault.ANKLE_RANGE if case == "other fault" else Fault.MISSED_DEADLINES, 1.0)
    assert run_cmd._exit_code(daemon) == 1
    assert "hint:" not in capsys.readouterr().err
    daemon.close()


def test_bench_impedance_plot_takes_an_optional_path():
    from ankle_rt.cli import build_parser

    parse = build_parser().parse_args
    assert parse(["bench", "impedance", "--plot"]).plot == "impedance-bench.png"   # as docs/daemon.md writes it
    assert parse(["bench", "impedance", "--plot", "loops.png"]).plot == "loops.png"
    assert parse(["bench", "impedance"]).plot is None


def test_profile_hold_without_angles_holds_the_ankle_where_it_is(sim_cfg):
    from ankle_rt.service import protocol as proto

    daemon = lockstep_daemon(sim_cfg)
    run_cycles(daemon, 1500)                     # the section 7 step: DP at 10 deg, IE at 5 deg
    here = daemon.est.ankle_pos.copy()
    assert math.degrees(here[0]) > 9.0
    daemon.handle(proto.parse_command(b'{"cmd": "start_profile", "name": "hold"}'))
    run_cycles(daemon, 300)
    rec = daemon.recorder.records[-300:]
    assert np.max(np.abs(rec["ref_dp"] - here[0])) < math.radians(0.1)
    assert np.max(np.abs(rec["ankle_dp"] - here[0])) < math.radians(0.5)
    daemon.handle(proto.parse_command(b'{"cmd": "start_profile", "name": "hold", "params": {"dp": 0.0}}'))
    run_cycles(daemon, 300)                      # an axis given moves; the other stays
    assert abs(daemon.reference.ref[0]) < 1e-9 and abs(daemon.reference.ref[1] - here[1]) < math.radians(0.1)
    daemon.close()


def test_hold_here_is_refused_while_the_ankle_estimate_is_not_valid(sim_cfg):
    from ankle_rt.service import protocol as proto

    cfg = sim_cfg.deep_copy()
    cfg["safety"]["auto_activate"] = False
    cfg["estimation"]["tare_samples"] = 50
    daemon = lockstep_daemon(cfg)
    run_cycles(daemon, 10)                       # still taring
    assert not daemon.est.tared
    hold = proto.parse_command(b'{"cmd": "start_profile", "name": "hold"}')
    with pytest.raises(proto.CommandError) as err:
        daemon.handle(hold)
    assert err.value.field == "params.dp" and "tared" in str(err.value)
    daemon.handle(proto.parse_command(b'{"cmd": "start_profile", "name": "hold", "params": {"dp": 0.0, "ie": 0.0}}'))
    run_cycles(daemon, 50)
    daemon.est.ie = math.nan                     # a broken reading
    with pytest.raises(proto.CommandError) as err:
        daemon.handle(proto.parse_command(b'{"cmd": "start_profile", "name": "hold", "params": {"dp": 0.0}}'))
    assert err.value.field == "params.ie" and "nan" in str(err.value)
    daemon.close()


class RepeatsTwoSamples(InjectingBackend):
    """The simulator, except that cycles 300 and 500 read the previous sample again (a late wake-up)."""

    def read(self, frame):
        if self.cycle + 1 in (300, 500):
            self.cycle += 1
            return
        super().read(frame)


def test_csv_and_mcap_exports_hold_the_same_cycles_with_times_in_shortest_form(sim_cfg, tmp_path, capsys):
    path = tmp_path / "run.arlog"
    run_lockstep(sim_cfg, 0.8, backend=RepeatsTwoSamples(sim_cfg, SimClock()), log_path=path)
    csv_out, mcap_out = tmp_path / "run.csv", tmp_path / "run.mcap"
    args = ["log", "export", str(path), "--csv", str(csv_out)]
    if importlib.util.find_spec("mcap") is not None:
        args += ["--mcap", str(mcap_out)]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "wrote 798 rows" in printed
    lines = csv_out.read_text(encoding="utf-8").splitlines()
    times = [line.split(",")[0] for line in lines[1:]]
    assert len(times) == 798 and times[:4] == ["0.0", "0.001", "0.002", "0.003"]
    assert all(repr(float(text)) == text for text in times)       # exact and shortest
    if "--mcap" in args:
        assert "wrote 798 messages" in printed and printed.count("2 record(s) repeating") == 2
        from mcap.reader import make_reader
        with mcap_out.open("rb") as handle:
            t_mcap = [json.loads(m.data)["t"] for _, _, m in make_reader(handle).iter_messages()]
        assert t_mcap == [float(text) for text in times]


def test_ctl_status_prints_angles_in_degrees_and_tiny_values_as_zero():
    from ankle_rt.commands.ctl import format_fields, status_for_people

    status = {"state": "active", "ankle_deg": [10.0, -5.0], "reference_deg": [10.0, -5.0],
              "motor_pos_rad": [math.pi, 0.5], "motor_vel_rad_s": [-3.44837e-84, -4.94066e-324], "current_a": [1.5, -0.25]}
    lines = format_fields(status_for_people(status))
    assert "motor_pos_deg: 180, 28.6479" in lines
    assert "motor_vel_deg_s: 0, 0" in lines
    assert "ankle_deg: 10, -5" in lines and "current_a: 1.5, -0.25" in lines
    rad = format_fields(status_for_people(status, rad=True))
    assert "motor_pos_rad: 3.14159, 0.5" in rad and "ankle_rad: 0.174533, -0.0872665" in rad
    assert not any("_deg" in line for line in rad)


def test_ctl_status_prints_the_gait_phases_equilibria_in_degrees():
    from ankle_rt.commands.ctl import format_fields, status_for_people

    status = {"gait_phase": {"phase": "safe", "time_in_phase_s": 0.5,
                             "params": {"late_stance": {"stiffness_dp": 150.0, "equilibrium_dp": -0.55,
                                                        "equilibrium_ie": 0.0}}}}
    lines = format_fields(status_for_people(status))
    assert "gait_phase.params.late_stance.equilibrium_dp_deg: -31.5127" in lines
    assert "gait_phase.params.late_stance.stiffness_dp: 150" in lines
    rad = format_fields(status_for_people(status, rad=True))
    assert "gait_phase.params.late_stance.equilibrium_dp_rad: -0.55" in rad
    assert status["gait_phase"]["params"]["late_stance"]["equilibrium_dp"] == -0.55    # the reply is not changed


def test_presence_says_when_a_daemon_connects_and_when_it_has_gone():
    import io

    from hardware.emulators.presence import Presence

    out, now = io.StringIO(), [100.0]
    p = Presence("commands", gone_s=1.0, stream=out, clock=lambda: now[0])
    for t, count in ((100.5, 0), (101.0, 1), (101.5, 40), (102.4, 40), (102.6, 40), (103.0, 41)):
        p.update(count, t)
    lines = out.getvalue().splitlines()
    assert lines == ["emulator: daemon connected (commands arriving) at 1.0 s",
                     "emulator: daemon gone (no commands for 1 s) at 2.6 s",
                     "emulator: daemon connected (commands arriving) at 3.0 s"]
    assert p.sessions == 2


@pytest.mark.slow
def test_a_standalone_serial_emulator_reports_its_daemon_and_ends_on_duration(tmp_path):
    import os
    import re
    import subprocess
    import sys

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    emu = subprocess.Popen([sys.executable, "-m", "ankle_rt.cli", "emulate", "--transport", "serial", "--port", "pty",
                            "--duration", "8"], stdout=subprocess.PIPE, text=True, env=env)
    try:
        first = emu.stdout.readline()
        assert "stops after 8 s" in first
        pty = re.search(r"(/dev/pts/\d+)", first).group(1)
        cfg = tmp_path / "d.yaml"
        cfg.write_text(f"include: [{ROOT / 'config' / 'hw-serial.yaml'}]\nserial: {{port: {pty}}}\n"
                       "safety: {auto_activate: true}\nservice: {enabled: false}\n")
        subprocess.run([sys.executable, "-m", "ankle_rt.cli", "run", "--config", str(cfg), "--duration", "1",
                        "--no-log"], env=env, capture_output=True, timeout=60)
        rest, _ = emu.communicate(timeout=60)    # ends by itself once --duration has passed
    finally:
        if emu.poll() is None:
            emu.kill()
    assert emu.returncode == 0
    assert "daemon connected (commands arriving)" in rest and "daemon gone (no commands for 1 s)" in rest
    assert re.search(r"emulator: [1-9]\d* ticks", rest)


def test_progress_off_a_terminal_prints_a_plain_line_every_few_seconds():
    import io

    from ankle_rt.progress import LINE_S, Progress

    now, piped = [100.0], io.StringIO()
    with Progress("sweep", 10, stream=piped, clock=lambda: now[0]) as bar:
        now[0] += LINE_S - 1.0
        bar.update(2, "2/10 batches")
        assert piped.getvalue() == ""                 # a short command prints nothing extra
        now[0] += 1.0
        bar.update(5, "5/10 batches")
        now[0] += 1.0
        bar.update(6)                                 # the next line only LINE_S later
    assert piped.getvalue() == f"sweep:  50% 0:{LINE_S:02.0f} elapsed, ETA 0:{LINE_S:02.0f}  5/10 batches\n"
    assert "\r" not in piped.getvalue()


def test_progress_off_a_terminal_keeps_printing_through_a_long_step(monkeypatch):
    import io
    import time

    from ankle_rt import progress

    monkeypatch.setattr(progress, "LINE_S", 0.05)
    piped = io.StringIO()
    with progress.Progress("diagnose", 4, stream=piped) as bar:
        bar.update(1, "fitting")                      # then no update for a while: one long step
        guard = time.monotonic() + 30.0
        while piped.getvalue().count("\n") < 2 and time.monotonic() < guard:
            time.sleep(0.01)
    lines = piped.getvalue().splitlines()
    assert len(lines) >= 2 and all(line.startswith("diagnose:  25% ") and line.endswith("fitting") for line in lines)
    assert not bar._ticker.is_alive()                 # closed with the command


def test_progress_on_a_terminal_or_switched_off_starts_no_thread():
    import io

    from ankle_rt.progress import Progress

    class TTY(io.StringIO):
        def isatty(self):
            return True

    assert Progress("x", 1, stream=TTY())._ticker is None
    assert Progress("x", 1, stream=io.StringIO(), enabled=False)._ticker is None


def test_a_run_plot_names_its_outcome_and_marks_activation_deactivation_and_fault(sim_cfg, tmp_path):
    from ankle_rt.log.summary import plot_run, run_outcome, state_marks
    from ankle_rt.service import protocol as proto

    daemon = lockstep_daemon(sim_cfg)
    run_cycles(daemon, 800)
    daemon.handle(proto.parse_command(b'{"cmd": "deactivate"}'))
    run_cycles(daemon, 100)
    daemon.handle(proto.parse_command(b'{"cmd": "activate"}'))
    run_cycles(daemon, 100)
    daemon.loop.on_overrun_limit()               # as after a stall
    run_cycles(daemon, 50)
    rec = daemon.recorder.records
    daemon.close()
    marks = state_marks(rec)
    assert len(marks["activate"]) == 2 and len(marks["deactivate"]) == 2 and len(marks["fault"]) == 1
    assert marks["fault"][0] == daemon.safety.fault_time and marks["deactivate"][-1] == marks["fault"][0]
    assert run_outcome(rec) == f"FAULT MISSED_DEADLINES at t = {daemon.safety.fault_time:.3f} s"
    assert run_outcome(rec[:700]) == "ended ACTIVE"
    pytest.importorskip("matplotlib")
    import matplotlib.pyplot as plt

    titles = []
    real_savefig = plt.Figure.savefig

    def keep_title(fig, *a, **kw):
        titles.append(fig._suptitle.get_text())
        labels = [line.get_label() for line in fig.axes[1].get_lines()]
        titles.append(labels)
        return real_savefig(fig, *a, **kw)
    plt.Figure.savefig = keep_title
    try:
        png = tmp_path / "run.png"
        assert plot_run(rec, 0.1, str(png), "sim.yaml: sim, controller pd") == f"plot: {png}"
    finally:
        plt.Figure.savefig = real_savefig
    assert png.stat().st_size > 0
    assert titles[0] == f"sim.yaml: sim, controller pd\n{run_outcome(rec)}"
    assert {"activate", "deactivate", run_outcome(rec)} <= set(titles[1])


def test_plot_axes_name_their_units():
    from ankle_rt.identification.validation import _axis_label
    from ankle_rt.sweep.report import axis_label
    from ankle_rt.sweep.spec import load_study

    study = load_study(ROOT / "config" / "sweeps" / "section7-robustness.yaml", runs=4)
    labels = {p.key: axis_label(study, p.column) for p in study.parameters}
    assert labels["sim.effects.0.delay"] == "sim.effects.0.delay (s)"
    assert labels["transmission.cable_stiffness"] == "transmission.cable_stiffness (factor)"
    assert _axis_label("current_cmd_1", False) == "current_cmd_1 (A)"
    assert _axis_label("motor_pos_1", True) == "motor_pos_1 - start (rad)"
    assert _axis_label("motor_speed_2", True) == "motor_speed_2 (rad/s)"


def test_progress_polls_work_that_cannot_report_itself(monkeypatch):
    import io
    import time

    from ankle_rt import progress

    class TTY(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setattr(progress, "REDRAW_S", 0.01)
    done, screen = [0.0], TTY()
    with progress.Progress("run --fast", 10.0, stream=screen, poll=lambda: done[0]):
        guard = time.monotonic() + 30.0
        done[0] = 5.0                                 # nobody calls update: the ticker reads it
        while " 50%" not in screen.getvalue() and time.monotonic() < guard:
            time.sleep(0.01)
    assert "run --fast [############............]  50%" in screen.getvalue()


def test_a_long_lockstep_run_shows_progress_off_a_terminal(monkeypatch, capsys):
    from ankle_rt import progress

    monkeypatch.setattr(progress, "LINE_S", 0.02)
    assert main(["run", "--fast", "--duration", "4", "--no-log"]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("run --fast: ")]
    assert lines and all(" elapsed, ETA " in line for line in lines)


class PhasedPlugin:
    """A plugin-like controller with attributes of its own named ``phase`` and ``gait``."""

    phase = "swing"
    gait = "walking"

    def reset(self, est):
        pass

    def update(self, est, out):
        out[0] = out[1] = 0.0


def test_a_plugins_own_phase_attribute_never_reaches_the_logs_gait_phase_code(sim_cfg):
    daemon = lockstep_daemon(sim_cfg, controller=PhasedPlugin())
    run_cycles(daemon, 200)                      # the record's gait_phase is one byte: a str would stop the loop
    assert daemon.safety.state == State.ACTIVE
    assert np.all(daemon.recorder.records["gait_phase"] == 0)
    assert daemon.status()["gait_phase"] is None
    daemon.close()


class TakesAnyGains(PhasedPlugin):
    """A plugin whose set_gains takes any names (what it is given is kept)."""

    def __init__(self):
        self.given = []

    def set_gains(self, **gains):
        self.given.append(gains)


def test_the_daemon_checks_equilibrium_angles_from_any_caller_for_any_controller(sim_cfg):
    from ankle_rt.control.gains import GainError

    plugin = TakesAnyGains()
    daemon = lockstep_daemon(sim_cfg, controller=plugin)
    for bad in (math.nan, 5.0, -daemon.safety.ankle_limit - 1e-6):
        with pytest.raises(GainError) as err:
            daemon.set_gains(phase="safe", equilibrium_dp=bad)
        assert err.value.gain == "equilibrium_dp" and "ankle range" in str(err.value)
    with pytest.raises(GainError):
        daemon.set_gains(equilibrium_ie=1e3, kp=1.0)
    assert plugin.given == []                    # nothing reached the controller
    daemon.set_gains(phase="safe", equilibrium_dp=0.1)
    assert plugin.given == [{"phase": "safe", "equilibrium_dp": 0.1}]
    daemon.close()


def test_list_controllers_imports_the_registry_off_the_loop_thread(sim_cfg, monkeypatch):
    import sys
    import threading
    import time

    from ankle_rt.service import protocol as proto

    importers = []

    class Watch:                                  # records the thread that imports the registry
        def find_spec(self, name, path=None, target=None):
            if name == "ankle_rt.controller_registry":
                importers.append((name, threading.current_thread()))
            return None

    daemon = lockstep_daemon(sim_cfg)
    monkeypatch.delitem(sys.modules, "ankle_rt.controller_registry")   # as in a daemon that never built one
    monkeypatch.setattr(sys, "meta_path", [Watch(), *sys.meta_path])
    pending = daemon.handle(proto.parse_command(b'{"cmd": "list_controllers"}'))
    end = time.monotonic() + 30.0                 # a guard, not an assertion
    while (reply := pending.poll()) is None and time.monotonic() < end:
        time.sleep(0.001)
    assert "impedance" in reply["controllers"]
    assert importers and all(thread is not threading.current_thread() for _, thread in importers)
    daemon.close()


def test_hold_here_and_activation_hold_the_angle_the_impedance_law_acts_on(sim_cfg):
    """With angle_source joint_encoders the law compares the reference with the joint encoders: hold
    here (and a later activation) must hold their angle, not the estimate through the cables, else
    K times the difference comes as a torque step."""
    from ankle_rt.service import protocol as proto

    offset = math.radians(2.0)                  # the joint encoders read 2 deg more than the cables say

    def shift(frame, cycle):
        frame.ankle_pos[0] += offset

    cfg = variant(sim_cfg, reference={"profile": "hold"}, sim={"disturbances": []})
    cfg["controller"]["type"] = "impedance"
    cfg["controller"]["impedance"]["angle_source"] = "joint_encoders"
    daemon = lockstep_daemon(cfg, backend=InjectingBackend(cfg, SimClock(), at=0, mutate=shift))
    run_cycles(daemon, 1000)
    assert daemon.safety.state == State.ACTIVE
    assert daemon.ankle_now() == (daemon.est.joint_dp, daemon.est.joint_ie)
    assert abs(daemon.est.joint_dp - daemon.est.dp) > 0.9 * offset
    before = daemon.torque.copy()
    daemon.handle(proto.parse_command(b'{"cmd": "start_profile", "name": "hold"}'))
    run_cycles(daemon, 5)
    assert abs(daemon.reference.ref[0] - daemon.est.joint_dp) < math.radians(0.05)
    assert np.max(np.abs(daemon.torque - before)) < 0.5   # N m: no step of K x 2 deg
    daemon.deactivate()
    run_cycles(daemon, 5)
    daemon.activate()
    assert abs(daemon.reference.ref[0] - daemon.est.joint_dp) < math.radians(0.05)
    daemon.close()
