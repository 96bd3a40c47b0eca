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
    for _ in range(1000):  # guard: the reference moves at reference.max_rate_rad_s (2 rad/s), ~0.05 s here
        ref = status(path)["reference_deg"]
        if ref == pytest.approx([5.0, -3.0]):
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


def test_log_writer_thread_does_not_inherit_real_time_priority(tmp_path):
    """The unit leaves scheduling to the daemon so that only the loop runs SCHED_FIFO: the log
    writer thread, started after the daemon raised its priority, must drop back to normal."""
    import threading
    import time

    from ankle_rt.log.writer import LogWriter

    result = {}

    def loop_thread():
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
        except OSError as exc:
            result["refused"] = exc.strerror
            return
        writer = LogWriter(tmp_path / "run.arlog", {})
        for _ in range(5000):  # guard: the writer sets its policy as it starts
            result["writer"] = os.sched_getscheduler(writer._thread.native_id)
            if result["writer"] == os.SCHED_OTHER:
                break
            time.sleep(0.001)  # let the writer thread take the GIL
        result["loop"] = os.sched_getscheduler(0)
        writer.close()

    thread = threading.Thread(target=loop_thread)
    thread.start()
    thread.join()
    if "refused" in result:
        pytest.skip(f"SCHED_FIFO not allowed here ({result['refused']})")
    assert result == {"loop": os.SCHED_FIFO, "writer": os.SCHED_OTHER}
