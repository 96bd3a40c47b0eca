"""A real daemon for service tests: `ankle-rt run` in real time, in a subprocess, with its command
socket in the test's tmp dir, and a blocking line client. Timeouts here are guards against a hung
daemon, never timing assertions."""

from __future__ import annotations

import contextlib
import json
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable, Iterator

import pytest

SIM_CONFIG = Path(__file__).resolve().parent.parent / "config" / "sim.yaml"

DAEMON_CONFIG = """\
include: [{sim}]
# the joint-torque loop needs 1 kHz (no margin at 250 Hz); the PD's kd 5 keeps 4.9 dB there, kd 3 8.6 dB
controller: {{rate_hz: 250, impedance: {{torque_feedback: "off"}}, step_gains: {{kd: 3.0}}}}
safety: {{auto_activate: false}}        # stays configured (amplifiers off) until told
reference: {{profile: hold}}            # activation holds the ankle at 0
sim: {{disturbances: []}}               # nothing else may move the ankle
loop: {{max_consecutive_overruns: 1000000, realtime: {{spin_us: 0}}}}   # a busy CI machine must not fault it
logging: {{enabled: false}}
"""


class LineClient:
    """A blocking client; the timeout is only a guard against a hung daemon."""

    def __init__(self, path: Path):
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.settimeout(60.0)
        self.sock.connect(str(path))
        self.buf = b""

    def request(self, line: bytes) -> dict:
        self.sock.sendall(line + b"\n")
        while b"\n" not in self.buf:
            chunk = self.sock.recv(65536)
            assert chunk, "the daemon closed the connection"
            self.buf += chunk
        reply, self.buf = self.buf.split(b"\n", 1)
        return json.loads(reply)

    def close(self) -> None:
        self.sock.close()


def start_daemon(tmp_path: Path, env: dict | None = None) -> tuple[subprocess.Popen, Path]:
    """Start the daemon and wait (guarded) until its socket answers."""
    cfg = tmp_path / "daemon.yaml"
    cfg.write_text(DAEMON_CONFIG.format(sim=SIM_CONFIG))
    path = tmp_path / "ctl.sock"
    proc = subprocess.Popen([sys.executable, "-m", "ankle_rt.cli", "run", "--config", str(cfg), "--socket", str(path),
                             "--duration", "600", "--no-plot"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        for _ in range(600):  # guard: up to a minute for start-up on a busy machine
            if proc.poll() is not None:
                pytest.fail(f"the daemon exited at start-up: {proc.communicate()}")
            try:
                client = LineClient(path)
                break
            except (FileNotFoundError, ConnectionRefusedError):
                time.sleep(0.1)
        else:
            pytest.fail("the daemon's socket never appeared")
        client.close()
    except BaseException:
        stop_daemon(proc)
        raise
    return proc, path


def stop_daemon(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.kill()
        proc.communicate()


@pytest.fixture
def daemon(tmp_path):
    proc, path = start_daemon(tmp_path)
    yield proc, path
    stop_daemon(proc)


def status(path: Path) -> dict:
    client = LineClient(path)
    try:
        reply = client.request(b'{"cmd":"status"}')
    finally:
        client.close()
    assert reply["ok"] is True
    return reply


def activate(client: LineClient) -> dict:
    """Activate once the strain gauges are tared (the daemon refuses before; guarded retries)."""
    return once_tared(client, b'{"cmd":"activate"}')


def once_tared(client: LineClient, request: bytes) -> dict:
    """The reply to ``request`` once the strain gauges are tared: activation and "hold here" are
    refused before (guarded retries)."""
    for _ in range(600):
        reply = client.request(request)
        if reply["ok"] or "tared" not in reply["error"]:
            return reply
        time.sleep(0.1)
    pytest.fail("the strain gauges were never tared")


def reply_of(srv, sock, polls: int = 200) -> dict:
    """The JSON reply to what ``sock`` sent, polling the in-process CommandServer ``srv`` (no timing)."""
    sock.setblocking(False)
    data = b""
    for _ in range(polls):
        srv.poll()
        try:
            data += sock.recv(65536)
        except BlockingIOError:
            pass
        if data.endswith(b"\n"):
            return json.loads(data)
    raise AssertionError(f"no reply (got {data!r})")


@contextlib.contextmanager
def repeating(step: Callable[[], None]) -> Iterator[None]:
    """Call ``step()`` over and over in a thread while the block runs (a server's polls, a lockstep
    daemon's cycles)."""
    stop = threading.Event()

    def run():
        while not stop.is_set():
            step()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()
