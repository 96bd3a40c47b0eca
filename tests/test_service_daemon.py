"""The service layer wired into the real daemon (`ankle-rt run`, real time, subprocess): systemd
notifications from the loop, `ankle-rt ctl` end to end, one daemon per socket."""

from __future__ import annotations

import os
import socket
import subprocess
import sys

import pytest

from ankle_rt.cli import main
from tests.service_helpers import LineClient, activate, daemon, start_daemon, status, stop_daemon  # noqa: F401


def datagrams_until(sock: socket.socket, wanted: bytes, limit: int = 1000) -> list[bytes]:
    """Notifications received up to and including the first containing ``wanted`` (recv timeout = guard)."""
    got = []
    for _ in range(limit):
        got.append(sock.recv(4096))
        if wanted in got[-1]:
            return got
    pytest.fail(f"no {wanted!r} among {got[-5:]}")


def test_daemon_notifies_systemd_from_the_loop(tmp_path):
    notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    notify.bind(str(tmp_path / "notify"))
    notify.settimeout(60.0)
    env = {**os.environ, "NOTIFY_SOCKET": str(tmp_path / "notify"), "WATCHDOG_USEC": "400000"}
    proc, path = start_daemon(tmp_path, env)
    try:
        first = datagrams_until(notify, b"READY=1")
        assert first[-1].startswith(b"READY=1\nSTATUS=running sim at 250 Hz")
        datagrams_until(notify, b"WATCHDOG=1")
        datagrams_until(notify, b"WATCHDOG=1")  # pings keep coming while the loop is healthy
        client = LineClient(path)
        assert activate(client) == {"ok": True, "state": "active"}
        assert b"STATUS=active" in datagrams_until(notify, b"STATUS=")[-1]
        assert client.request(b'{"cmd":"deactivate"}')["ok"]
        assert b"STATUS=safe" in datagrams_until(notify, b"STATUS=")[-1]
        assert client.request(b'{"cmd":"stop"}') == {"ok": True, "state": "safe"}
        client.close()
        assert datagrams_until(notify, b"STOPPING=1")[-1].startswith(b"STOPPING=1")
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
        assert not path.exists()  # the socket file is removed on the way out
    finally:
        stop_daemon(proc)
        notify.close()


def test_ctl_against_the_daemon(daemon, capsys):
    proc, path = daemon
    assert main(["ctl", "--socket", str(path), "status"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert "state: configured" in out and any(line.startswith("loop.compute.p99_us: ") for line in out)
    assert main(["ctl", "--socket", str(path), "ref", "5", "-3", "--ramp", "0"]) == 0
    for _ in range(100):  # guard: the reference updates on the next cycle
        ref = status(path)["reference_deg"]
        if ref != [0.0, 0.0]:
            break
    assert ref == pytest.approx([5.0, -3.0])
    assert main(["ctl", "--socket", str(path), "ref", "45", "0"]) == 1
    assert "field 'dp'" in capsys.readouterr().err
    assert status(path)["reference_deg"] == pytest.approx([5.0, -3.0])
    assert main(["ctl", "--socket", str(path), "gains", "--kp", "60"]) == 0
    assert main(["ctl", "--socket", str(path), "stop"]) == 0
    assert proc.wait(timeout=120) == 0
    assert main(["ctl", "--socket", str(path), "status"]) == 3
    assert "no daemon is listening" in capsys.readouterr().err


def test_second_daemon_on_the_same_socket_refuses_to_start(daemon, tmp_path):
    proc, path = daemon
    second = subprocess.run([sys.executable, "-m", "ankle_rt.cli", "run", "--config", str(tmp_path / "daemon.yaml"),
                             "--socket", str(path), "--duration", "5", "--no-plot"],
                            capture_output=True, text=True, timeout=120)
    assert second.returncode == 1
    assert f"another ankle-rt daemon is already listening on {path}" in second.stderr
    assert status(path)["state"] == "configured" and proc.poll() is None
