"""``ankle-rt ctl`` against a real CommandServer: what goes on the wire, what it prints, exit codes."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest

from ankle_rt.cli import main
from ankle_rt.config import ConfigError
from ankle_rt.references import make_profile
from ankle_rt.service.protocol import (CommandError, ListControllers, SetController, SetGains, SetReference,
                                       StartProfile, Status)
from ankle_rt.service.server import CommandServer
from tests.service_helpers import repeating

SIM_CONFIG = Path(__file__).resolve().parent.parent / "config" / "sim.yaml"


@pytest.fixture
def daemon(tmp_path):
    """A CommandServer polled by a thread; its handler records commands and refuses 'reset'."""
    got = []

    def handle(command):
        got.append(command)
        if type(command).__name__ == "ResetFault":
            raise CommandError("cmd", "not in the fault state")
        if isinstance(command, StartProfile) and command.name != "csv":   # the daemon's own parameter check
            try:
                make_profile(command.name, command.params)
            except ConfigError as exc:
                raise CommandError(exc.key, exc.message) from None
        return {"state": "safe", "ankle_deg": [1.5, float("nan")], "loop": {"overruns": 0}}

    server = CommandServer(tmp_path / "ctl.sock", 0o600, handle)

    def serve():
        server.poll()
        time.sleep(0.001)

    with repeating(serve):
        yield server, got
    server.close()


def ctl(server, *argv):
    return main(["ctl", "--socket", str(server.path), *argv])


def test_status_prints_the_reply_readably(daemon, capsys):
    server, got = daemon
    assert ctl(server, "status") == 0
    assert got == [Status()]
    out = capsys.readouterr().out.splitlines()
    assert out == ["state: safe", "ankle_deg: 1.5, -", "loop.overruns: 0"]


def test_ref_takes_degrees_and_sends_rad(daemon):
    server, got = daemon
    assert ctl(server, "ref", "10", "-5", "--ramp", "2") == 0
    assert ctl(server, "ref", "--rad", "0.1", "0") == 0
    assert got == [SetReference(math.radians(10), math.radians(-5), 2.0), SetReference(0.1, 0.0)]


def test_gains_and_profile(daemon):
    server, got = daemon
    assert ctl(server, "gains", "--kp", "90", "--stiffness-ie", "3") == 0
    assert ctl(server, "profile", "csv", "path=r.csv", "rate=2") == 0
    assert got == [SetGains(kp=90.0, stiffness_ie=3.0), StartProfile("csv", {"path": str(Path("r.csv").resolve()), "rate": 2.0})]


def test_controllers_and_controller_switch(daemon):
    server, got = daemon
    assert ctl(server, "controllers") == 0
    assert ctl(server, "controller", "load_stiffening", "stiffness=60,30", "stiffening=0.5", "mode=a,b") == 0
    assert got == [ListControllers(), SetController("load_stiffening", {"stiffness": [60.0, 30.0], "stiffening": 0.5,
                                                                       "mode": "a,b"})]


def test_profile_angles_take_degrees_and_send_rad(daemon, capsys):
    server, got = daemon
    assert ctl(server, "profile", "sine", "amplitude_dp=5", "ie_phase=90", "frequency_hz=0.5") == 0
    assert ctl(server, "profile", "step", "dp=-3", "ie=2", "start_s=0.25") == 0
    assert ctl(server, "profile", "sine", "amplitude_dp=0.05", "--rad") == 0
    assert got == [StartProfile("sine", {"amplitude_dp": math.radians(5), "ie_phase": math.radians(90),
                                         "frequency_hz": 0.5}),
                   StartProfile("step", {"dp": math.radians(-3), "ie": math.radians(2), "start_s": 0.25}),
                   StartProfile("sine", {"amplitude_dp": 0.05})]
    assert ctl(server, "profile", "sine", "amplitude_dp=50") == 1
    err = capsys.readouterr().err
    assert "field 'params.amplitude_dp'" in err and "amplitude_dp=50 deg is 0.8727 rad" in err


def test_error_replies_exit_non_zero_naming_the_field(daemon, capsys):
    server, got = daemon
    assert ctl(server, "ref", "60", "0") == 1  # beyond the +/-40 deg range: rejected before the handler
    assert "field 'dp'" in capsys.readouterr().err and got == []
    assert ctl(server, "reset") == 1
    assert "field 'cmd': not in the fault state" in capsys.readouterr().err


def test_json_output(daemon, capsys):
    server, _ = daemon
    assert ctl(server, "--json", "gains") == 1  # no gain given
    assert '"field": "cmd"' in capsys.readouterr().out


def test_no_daemon_is_a_clear_message(tmp_path, capsys):
    assert main(["ctl", "--socket", str(tmp_path / "none.sock"), "status"]) == 3
    assert "no daemon is listening on" in capsys.readouterr().err


def test_socket_from_config(tmp_path, capsys):
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(f"include: [{SIM_CONFIG}]\nservice: {{socket_path: {tmp_path / 'x.sock'}}}\n")
    assert main(["ctl", "--config", str(cfg), "status"]) == 3
    assert str(tmp_path / "x.sock") in capsys.readouterr().err
