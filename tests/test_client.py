"""ankle_rt.client against real daemons: in lockstep (a Daemon on a SimClock with its socket, stepped
by a thread) and in real time (``ankle-rt run`` in a subprocess), including the example experiment
script and the controllers listed and switched at run time. Timeouts are guards, never assertions."""

from __future__ import annotations

import json
import math
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from ankle_rt.cli import main
from ankle_rt.client import SAMPLE_FIELDS, AnkleClient, CommandRefused, DaemonUnreachable
from ankle_rt.safety import State
from ankle_rt.service.link import ServiceLink
from ankle_rt.service.protocol import CommandError
from tests.daemon_helpers import lockstep_daemon, run_cycles, variant
from tests.service_helpers import daemon, repeating  # noqa: F401  (daemon: the real-time daemon fixture)
from tests.test_controller_plugins import plugins  # noqa: F401  (the example plugin as an entry point)

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture
def lockstep(sim_cfg, tmp_path):
    """A lockstep daemon (sim, hold at 0, waiting for activate) whose loop a thread keeps stepping;
    yields its socket path and the Daemon."""
    cfg = variant(sim_cfg, reference={"profile": "hold"}, sim={"disturbances": []}, safety={"auto_activate": False},
                  service={"client_timeout_s": 0.2})
    d = lockstep_daemon(cfg)
    d.recorder = None
    path = tmp_path / "ctl.sock"
    d.service = ServiceLink(cfg, d.handle, path=path, environ={})

    def step():
        run_cycles(d, 5)
        time.sleep(0.0005)

    try:
        with repeating(step):
            yield path, d
    finally:
        d.close()


def settle(ankle: AnkleClient, predicate, guard_s: float = 30.0) -> dict:
    """Status replies until ``predicate(status)`` holds (the guard only stops a hung test)."""
    end = time.monotonic() + guard_s
    while time.monotonic() < end:
        status = ankle.status()
        if predicate(status):
            return status
        time.sleep(0.02)
    raise AssertionError(f"never reached; last status {status}")


def test_client_drives_a_lockstep_daemon(lockstep):
    path, d = lockstep
    with AnkleClient.connect(socket_path=path, timeout_s=30.0) as ankle:
        assert ankle.state() == "configured"
        ankle.activate(tare_timeout_s=30.0)
        assert ankle.activated and ankle.state() == "active"
        ankle.set_reference(math.radians(8.0), math.radians(-3.0), ramp_s=0.2)
        status = settle(ankle, lambda s: abs(s["ankle_deg"][0] - 8.0) < 0.2 and abs(s["ankle_deg"][1] + 3.0) < 0.2)
        assert status["reference_deg"] == pytest.approx([8.0, -3.0])
        ankle.set_gains(kp=120.0, kd=4.0)
        settle(ankle, lambda s: s["gains"] == {"kp": 120.0, "kd": 4.0})
        assert ankle.gains() == {"kp": 120.0, "kd": 4.0}
        ankle.start_profile("step", dp=math.radians(2.0), ie=0.0, start_s=0.0)
        data = ankle.record(0.3, interval_s=0.01)
    assert d.safety.state == State.SAFE and ankle._sock is None           # leaving the block deactivated and closed
    assert set(data) == set(SAMPLE_FIELDS) and len({len(v) for v in data.values()}) == 1 and len(data["t"]) > 5
    assert np.all(data["state"] == "active") and np.all(np.diff(data["t"]) > 0)
    assert np.all(np.abs(data["ref_dp"] - math.radians(8.0)) <= math.radians(2.0) + 1e-9)


def test_refusals_raise_with_the_field_and_change_nothing(lockstep):
    path, d = lockstep
    with AnkleClient.connect(socket_path=path, timeout_s=30.0) as ankle:
        ankle.activate(tare_timeout_s=30.0)
        settle(ankle, lambda s: s["reference_deg"] == [0.0, 0.0])    # the configured hold, reached by a ramp
        with pytest.raises(CommandRefused) as exc:
            ankle.activate()
        assert exc.value.field == "cmd" and "ACTIVE" in exc.value.message
        for call, field in ((lambda: ankle.set_reference(1.5, 0.0), "dp"), (lambda: ankle.set_gains(kp=-1.0), "kp"),
                            (lambda: ankle.set_gains(bogus=1.0), "bogus"),
                            (lambda: ankle.set_gains(phase="late_stance", kp=100.0), "phase"),   # sent; PD has no phases
                            (lambda: ankle.start_profile("sine", frequency_hz=100.0), "params.frequency_hz")):
            with pytest.raises(CommandRefused) as exc:
                call()
            assert exc.value.field == field, exc.value
        with pytest.raises(CommandError) as exc:                 # never sent: not a finite number
            ankle.set_reference(math.nan, 0.0)
        assert exc.value.field == "dp" and not isinstance(exc.value, CommandRefused)
        status = ankle.status()
        assert status["reference_deg"] == [0.0, 0.0] and status["gains"]["kp"] == 90.0


def test_an_idle_connection_closed_by_the_daemon_is_reopened(lockstep):
    path, _ = lockstep
    with AnkleClient.connect(socket_path=path, timeout_s=30.0) as ankle:
        first = ankle._sock
        ankle.status()
        time.sleep(0.6)                                          # service.client_timeout_s is 0.2 s here
        assert ankle.status()["state"] == "configured"
        assert ankle._sock is not first


def test_unreachable_daemon(tmp_path):
    with pytest.raises(DaemonUnreachable, match="no daemon is listening on"):
        AnkleClient.connect(socket_path=tmp_path / "none.sock")


def test_controllers_are_listed_and_switched_when_not_active(lockstep, plugins):  # noqa: F811
    path, d = lockstep
    with AnkleClient.connect(socket_path=path, timeout_s=30.0) as ankle:
        listed = ankle.controllers()
        assert listed["current"] == "pd"
        assert {"pd", "impedance", "load_stiffening"} <= set(listed["controllers"])
        ankle.set_controller("impedance")
        assert ankle.status()["controller"] == "impedance" and "stiffness_dp" in ankle.gains()
        with pytest.raises(CommandRefused) as exc:               # the same checks as the config's
            ankle.set_controller("load_stiffening", stiffness=[60.0, -1.0], damping=[1.0, 1.0])
        assert exc.value.field == "params" and "stiffness" in exc.value.message
        with pytest.raises(CommandRefused) as exc:
            ankle.set_controller("no_such_controller")
        assert exc.value.field == "type" and "load_stiffening" in exc.value.message
        assert ankle.status()["controller"] == "impedance"         # a refused switch changes nothing
        ankle.set_controller("load_stiffening", stiffness=(60.0, 30.0), stiffening=0.5, damping=[1.5, 0.75])
        ankle.activate(tare_timeout_s=30.0)
        with pytest.raises(CommandRefused) as exc:
            ankle.set_controller("pd")
        assert exc.value.field == "cmd" and "while active" in exc.value.message
        ankle.set_reference(math.radians(5.0), 0.0, ramp_s=0.1)
        settle(ankle, lambda s: abs(s["ankle_deg"][0] - 5.0) < 0.5)   # the plugin holds the new reference
        assert type(d.controller).__name__ == "LoadStiffening" and d.cfg["controller"]["params"]["stiffening"] == 0.5


def test_ctl_controllers_and_the_switch_against_a_real_time_daemon(daemon, capsys):  # noqa: F811
    _, path = daemon
    ctl = ["ctl", "--socket", str(path), "--timeout", "30"]
    assert main([*ctl, "controllers"]) == 0
    out = capsys.readouterr().out
    assert "controllers.pd: ankle_rt.control:pd_controller" in out and "current: pd" in out
    assert main([*ctl, "controller", "impedance"]) == 0
    assert "controller: impedance" in capsys.readouterr().out
    assert main([*ctl, "controller", "pd", "kp=5"]) == 1
    assert "refused: field 'params': controller 'pd': the built-in controller 'pd' takes no params" \
        in capsys.readouterr().err
    with AnkleClient.connect(socket_path=path, timeout_s=30.0) as ankle:
        ankle.activate(tare_timeout_s=60.0)
        assert main([*ctl, "controller", "pd"]) == 1
        assert "cannot switch the controller while active" in capsys.readouterr().err
        assert ankle.status()["controller"] == "impedance"


def test_the_example_experiment_runs_against_a_real_time_daemon(daemon, tmp_path):  # noqa: F811
    proc, path = daemon
    out = tmp_path / "step.npz"
    result = subprocess.run([sys.executable, str(ROOT / "examples" / "step_experiment.py"), "--socket", str(path),
                             "--out", str(out), "--hold-s", "0.6"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert "samples saved to" in result.stdout
    data = np.load(out)
    assert set(data.files) == set(SAMPLE_FIELDS) | {"trial"}
    for trial in (0, 1):
        dp = data["est_ankle_dp"][data["trial"] == trial]
        assert len(dp) > 5 and abs(math.degrees(dp[-1]) - 10.0) < 1.0      # each step reached
        assert abs(math.degrees(dp[0])) < 1.0                              # from 0
    with AnkleClient(path, 30.0) as ankle:
        status = ankle.status()
    assert status["state"] == "safe" and status["gains"] == {"kp": 120.0, "kd": 3.0}


def test_a_switch_while_a_fault_is_latched_keeps_the_fault_and_the_current_limits(sim_cfg):
    from ankle_rt.safety import Fault
    from ankle_rt.service import protocol as proto

    cfg = variant(sim_cfg, reference={"profile": "hold"}, sim={"disturbances": []}, safety={"auto_activate": False})
    d = lockstep_daemon(cfg)
    run_cycles(d, 200)
    d._fault(Fault.COMMAND_LOST)
    pending = d.handle(proto.parse_command(b'{"cmd": "set_controller", "type": "impedance"}'))
    end = time.monotonic() + 30.0                 # a guard, not an assertion
    while (reply := pending.poll()) is None and time.monotonic() < end:
        run_cycles(d, 1)
    assert reply["controller"] == "impedance" and reply["state"] == "fault"
    assert d.safety.state == State.FAULT and d.safety.fault == Fault.COMMAND_LOST   # still latched
    with pytest.raises(CommandError, match="reset the fault first"):
        d.handle(proto.parse_command(b'{"cmd": "activate"}'))
    run_cycles(d, 50)
    assert np.all(d.recorder.records[-50:]["current_cmd_1"] == 0.0)      # no output while latched
    d.reset_fault()
    d.activate()
    run_cycles(d, 500)
    cur = d.recorder.records[-500:]
    peak = d.safety.i_peak
    assert np.all(np.abs(cur["current_cmd_1"]) <= peak) and np.all(np.abs(cur["current_cmd_2"]) <= peak)
    assert type(d.controller).__name__ == "ImpedanceController" and d.safety.state == State.ACTIVE
    d.close()



def _one_request_per_connection(listener: socket.socket, answers: list[bool]) -> None:
    """A daemon stand-in: per connection, read one request, answer it (or not: ``answers``), close."""
    for n, answer in enumerate(answers, start=1):
        conn, _ = listener.accept()
        with conn:
            conn.recv(65536)
            if answer:
                conn.sendall(json.dumps({"ok": True, "n": n}).encode() + b"\n")


def test_a_kept_connection_dropped_as_the_request_goes_out_is_retried_once(tmp_path, monkeypatch):
    path = tmp_path / "stub.sock"
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(str(path))
    listener.listen(4)
    server = threading.Thread(target=_one_request_per_connection, args=(listener, [True, True, False]), daemon=True)
    server.start()
    try:
        client = AnkleClient(path, timeout_s=10.0)
        assert client.request("status") == {"n": 1}          # the stand-in then closes that connection
        # the race: the daemon drops the idle connection after the client looked and before it sends
        monkeypatch.setattr(client, "_live_socket", lambda: client._sock or client._open())
        assert client.request("status") == {"n": 2}          # answered on a new connection
        with pytest.raises(DaemonUnreachable, match="closed the connection without a reply"):
            client.request("status")                          # the new connection unanswered too: no more tries
        server.join(timeout=10.0)
        assert not server.is_alive()                          # three connections: one retry each time, no more
    finally:
        listener.close()
