"""``ankle-rt config check`` (full validation without hardware, what would run, exit code) and
``ankle-rt ctl watch`` (the live view against a real daemon; Ctrl-C and a closed pipe end it cleanly)."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest

from ankle_rt.cli import EXIT_BROKEN_PIPE, main
from ankle_rt.commands.ctl import watch_view
from tests.service_helpers import LineClient, activate, daemon, once_tared  # noqa: F401  (daemon is a fixture)

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "config"


@pytest.mark.parametrize("name, backend", [("sim.yaml", "sim"), ("hw-serial.yaml", "serial on /dev/ttyACM0"),
                                           ("hw-canopen.yaml", "canopen on socketcan:can0"),
                                           ("bench-serial.yaml", "serial (in-process lockstep emulator)")])
def test_shipped_configs_are_valid_and_say_what_would_run(name, backend, capsys):
    assert main(["config", "check", str(CONFIGS / name)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{CONFIGS / name}: valid\n")
    assert f"backend:     {backend}" in out and "controller:  pd, step_gains kp 90" in out
    assert "bus load" not in out          # the backends' start-up reports are not part of it


def test_the_service_config_of_the_deploy_steps_is_valid(tmp_path, capsys):
    cfg = tmp_path / "config.yaml"       # what README / docs/service.md write to /etc/ankle-rt/config.yaml
    cfg.write_text(f"include: [{CONFIGS / 'hw-serial.yaml'}, {CONFIGS / 'service.yaml'}]\n")
    assert main(["config", "check", str(cfg)]) == 0
    out = capsys.readouterr().out
    assert "until stopped" in out and "waits for ankle-rt ctl activate" in out and "/var/log/ankle-rt" in out
    assert "/run/ankle-rt/control.sock" in out   # the service's socket, also before systemd made its directory


@pytest.mark.parametrize("body, key", [
    ("foot: {mass: -1}\n", "foot.mass: must be >= 0"),
    ("controller: {type: phase}\n", "controller.type: unknown controller 'phase'"),
    ("escon:\n  amplifiers:\n    - {mode: analog, current_at_min: -1, current_at_max: 1, sign: 1}\n"
     "    - {mode: analog, current_at_min: -1, current_at_max: 1, sign: 1}\n", "escon.amplifiers.0"),
    ("serial: {baudrate: 9600}\n", "serial.baudrate"),
    ("controller: {impedance: {torque_feedback: off}}\n", "unquoted on/off/yes/no as true/false: quote it"),
])
def test_an_invalid_config_exits_2_naming_the_key(tmp_path, capsys, body, key):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(f"include: [{CONFIGS / 'hw-serial.yaml'}]\n{body}")
    assert main(["config", "check", str(cfg)]) == 2
    captured = capsys.readouterr()
    assert key in captured.err and f"{cfg}: INVALID" in captured.err and "Traceback" not in captured.err
    assert captured.out == ""


def test_watch_view_shows_degrees_and_names_units():
    status = {"state": "fault", "fault": "ankle_range", "fault_description": "ankle angle beyond the software limit",
              "fault_time_s": 1.25, "t": 2.5, "ankle_deg": [10.0, -5.0], "reference_deg": [10.0, -5.0],
              "motor_pos_rad": [3.141592653589793, 0.0], "motor_vel_rad_s": [0.0, 0.0], "sg_torque_nm": [0.5, 0.0],
              "current_a": [0.0, 0.0], "controller": "pd", "gains": {"kp": 90.0, "kd": 5.0},
              "loop": {"cycles": 10, "overruns": 0, "period_error": {"p99_us": 4.0}}}
    text = "\n".join(watch_view(status, Path("/x.sock")))
    assert "state: FAULT   fault: ankle_range (ankle angle beyond the software limit, at t = 1.25 s)" in text
    assert "position" in text and "180.000" in text and "deg" in text and "controller: pd   gains: kp 90, kd 5" in text


def test_watch_follows_a_running_daemon_and_ends_cleanly(daemon, capsys):  # noqa: F811
    proc, path = daemon
    client = LineClient(path)
    assert once_tared(client, b'{"cmd":"start_profile","name":"hold"}')["ok"]     # hold here: needs the tare
    assert activate(client)["ok"]
    assert main(["ctl", "--socket", str(path), "watch", "--count", "2", "--interval", "0.05"]) == 0
    out = capsys.readouterr().out
    assert out.count("ankle-rt ctl watch") == 2 and "state: ACTIVE   fault: none" in out and "reference" in out

    cmd = [sys.executable, "-m", "ankle_rt.cli", "ctl", "--socket", str(path), "watch", "--interval", "0.05"]
    closed = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    closed.stdout.close()                                    # `ankle-rt ctl watch | head` after head exits
    assert closed.wait(timeout=120) == EXIT_BROKEN_PIPE
    assert b"Traceback" not in closed.stderr.read()

    # SIGINT at its default in the child: a suite started in the background by a non-interactive shell
    # inherits it ignored (bash's rule for `cmd &`), and Python then installs no KeyboardInterrupt
    default_sigint = lambda: signal.signal(signal.SIGINT, signal.SIG_DFL)  # noqa: E731
    interrupted = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                   preexec_fn=default_sigint)
    assert interrupted.stdout.readline().startswith("ankle-rt ctl watch")   # it is drawing
    interrupted.send_signal(signal.SIGINT)
    out, err = interrupted.communicate(timeout=120)
    assert interrupted.returncode == 0 and "Traceback" not in err, err

    assert client.request(b'{"cmd":"stop"}')["ok"]
    client.close()
    proc.communicate(timeout=120)
    assert main(["ctl", "--socket", str(path), "watch", "--count", "1"]) == 3   # the daemon is gone


def test_an_impedance_config_is_summarised_with_its_torque_feedback_mode(tmp_path, capsys):
    cfg = tmp_path / "imp.yaml"          # impedance has a string key (torque_feedback) among its gains
    cfg.write_text(f"include: [{CONFIGS / 'sim.yaml'}]\ncontroller: {{type: impedance}}\n")
    assert main(["config", "check", str(cfg)]) == 0
    out = capsys.readouterr().out
    assert "controller:  impedance, stiffness_dp 20" in out and "torque_feedback auto" in out


@pytest.mark.parametrize("reply", [b"[1, 2]\n", b'"text"\n', b"5\n"])
def test_ctl_names_a_reply_that_is_json_but_not_an_object(tmp_path, capsys, reply):
    import socket
    import threading

    path = tmp_path / "s.sock"
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(path))
    server.listen(1)

    def answer():
        conn, _ = server.accept()
        conn.recv(4096)
        conn.sendall(reply)
        conn.close()

    thread = threading.Thread(target=answer)
    thread.start()
    try:
        assert main(["ctl", "--socket", str(path), "status"]) == 3
    finally:
        thread.join(10)
        server.close()
    assert "is not a JSON object" in capsys.readouterr().err
