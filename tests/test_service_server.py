"""The command server on real AF_UNIX sockets, and sd_notify against a fake NOTIFY_SOCKET."""

from __future__ import annotations

import json
import os
import socket
import stat
from pathlib import Path

import pytest

from ankle_rt.config import load_config
from ankle_rt.service import sdnotify
from ankle_rt.service.protocol import MAX_LINE_BYTES, CommandError, SetReference, Status
from ankle_rt.service.server import CommandServer, ServiceError

SIM_CONFIG = Path(__file__).resolve().parent.parent / "config" / "sim.yaml"
GUARD_POLLS = 2000  # generous bound on polls while waiting for a reply; no wall-clock timing


class Recorder:
    """A stand-in for Daemon.handle that remembers what reached it."""

    def __init__(self):
        self.commands = []

    def __call__(self, command):
        self.commands.append(command)
        if isinstance(command, SetReference) and command.ie < 0:
            raise CommandError("cmd", "refused in the current state")
        if isinstance(command, SetReference) and command.ie > 0.5:
            raise RuntimeError("daemon bug")
        return {"state": "safe", "got": type(command).__name__}


@pytest.fixture
def server(tmp_path):
    handler = Recorder()
    srv = CommandServer(tmp_path / "ctl.sock", 0o660, handler)
    srv.handler_log = handler.commands
    yield srv
    srv.close()


def connect(srv) -> socket.socket:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(5.0)  # a guard only: the test fails rather than hangs
    sock.connect(str(srv.path))
    return sock


def read_replies(srv, sock, count: int) -> list[dict]:
    """Poll the server until ``count`` reply lines arrived on ``sock``."""
    sock.setblocking(False)
    data = b""
    for _ in range(GUARD_POLLS):
        srv.poll()
        try:
            chunk = sock.recv(65536)
        except BlockingIOError:
            continue
        if not chunk:
            break
        data += chunk
        if data.count(b"\n") >= count:
            break
    lines = data.splitlines()
    assert len(lines) == count, data
    return [json.loads(line) for line in lines]


def test_socket_has_configured_permissions_and_is_removed_on_close(tmp_path):
    path = tmp_path / "ctl.sock"
    srv = CommandServer(path, 0o640, Recorder())
    assert stat.S_ISSOCK(path.lstat().st_mode) and stat.S_IMODE(path.stat().st_mode) == 0o640
    srv.close()
    assert not path.exists()


def test_requests_get_replies_in_order(server):
    sock = connect(server)
    sock.sendall(b'{"cmd":"status"}\n{"cmd":"set_reference","dp":0.1,"ie":0.0}\n\n{"cmd":"fly"}\n')
    replies = read_replies(server, sock, 3)
    assert replies[0] == {"ok": True, "state": "safe", "got": "Status"}
    assert replies[1]["got"] == "SetReference"
    assert replies[2]["ok"] is False and replies[2]["field"] == "cmd" and "fly" in replies[2]["error"]
    assert server.handler_log == [Status(), SetReference(0.1, 0.0)]
    assert server.commands_handled == 2 and server.requests_rejected == 1


def test_handler_refusals_and_bugs_become_error_replies(server):
    sock = connect(server)
    sock.sendall(b'{"cmd":"set_reference","dp":0,"ie":-0.1}\n{"cmd":"set_reference","dp":0,"ie":0.6}\n{"cmd":"status"}\n')
    refused, bug, status = read_replies(server, sock, 3)
    assert refused == {"ok": False, "error": "refused in the current state", "field": "cmd"}
    assert bug["ok"] is False and "internal error: RuntimeError: daemon bug" in bug["error"]
    assert status["ok"] is True and server.handler_errors == 1


def test_line_split_across_sends_is_one_request(server):
    sock = connect(server)
    sock.sendall(b'{"cmd":"sta')
    for _ in range(5):
        server.poll()
    assert server.handler_log == []
    sock.sendall(b'tus"}\n')
    assert read_replies(server, sock, 1)[0]["ok"] is True


def test_over_long_line_gets_one_error_and_the_stream_recovers(server):
    sock = connect(server)
    sock.sendall(b"x" * (3 * MAX_LINE_BYTES) + b'\n{"cmd":"status"}\n')
    too_long, status = read_replies(server, sock, 2)
    assert too_long["field"] == "line" and "longer than" in too_long["error"]
    assert status["ok"] is True and server.handler_log == [Status()]


def test_invalid_utf8_names_the_line(server):
    sock = connect(server)
    sock.sendall(b"\xff\xfe\xfd\n")
    reply = read_replies(server, sock, 1)[0]
    assert reply["field"] == "line" and "UTF-8" in reply["error"]


def test_half_line_at_end_of_stream_is_never_executed(server):
    sock = connect(server)
    sock.sendall(b'{"cmd":"status"}\n{"cmd":"activate"}')
    sock.shutdown(socket.SHUT_WR)
    assert read_replies(server, sock, 1)[0]["got"] == "Status"
    for _ in range(10):
        server.poll()
    assert server.handler_log == [Status()] and server.client_count == 0


def test_vanishing_and_non_reading_clients_are_dropped(server):
    gone = connect(server)
    gone.sendall(b'{"cmd":"status"}\n' * 50)
    gone.close()
    deaf = connect(server)
    deaf.sendall(b'{"cmd":"status"}\n' * 4000)  # far more replies than the server buffers for it
    live = connect(server)
    for _ in range(GUARD_POLLS):
        server.poll()
        if server.client_count == 1:
            break
    assert server.client_count == 1
    live.sendall(b'{"cmd":"status"}\n')
    assert read_replies(server, live, 1)[0]["ok"] is True
    deaf.close()


def test_work_per_poll_is_bounded(server):
    sock = connect(server)
    sock.sendall(b'{"cmd":"status"}\n' * 100)
    server.poll()  # accept
    answered = [server.poll() for _ in range(3)]
    assert all(n <= server.lines_per_client for n in answered)
    assert sum(answered) > 0


def test_a_full_server_evicts_the_idlest_client(tmp_path):
    srv = CommandServer(tmp_path / "s", 0o600, Recorder(), max_clients=2)
    socks = [connect(srv) for _ in range(2)]
    srv.poll()
    late = connect(srv)
    srv.poll()
    assert srv.client_count == 2 and srv.clients_evicted == 1
    assert socks[0].recv(1000) == b""          # the oldest idle client was disconnected
    late.sendall(b'{"cmd":"status"}\n')
    assert read_replies(srv, late, 1)[0]["ok"] is True
    srv.close()


def test_stale_socket_is_replaced(tmp_path):
    path = tmp_path / "ctl.sock"
    dead = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    dead.bind(str(path))
    dead.close()  # the file stays, nobody listens: what a killed daemon leaves behind
    srv = CommandServer(path, 0o600, Recorder())
    sock = connect(srv)
    sock.sendall(b'{"cmd":"status"}\n')
    assert read_replies(srv, sock, 1)[0]["ok"] is True
    srv.close()


def test_refuses_to_start_beside_a_running_daemon(server):
    with pytest.raises(ServiceError, match="another ankle-rt daemon is already listening"):
        CommandServer(server.path, 0o600, Recorder())
    sock = connect(server)  # the first one is untouched
    sock.sendall(b'{"cmd":"status"}\n')
    assert read_replies(server, sock, 1)[0]["ok"] is True


def test_refuses_to_replace_a_regular_file(tmp_path):
    path = tmp_path / "ctl.sock"
    path.write_text("precious")
    with pytest.raises(ServiceError, match="not a socket"):
        CommandServer(path, 0o600, Recorder())
    assert path.read_text() == "precious"


def test_unusable_directory_is_a_clear_error(tmp_path):
    with pytest.raises(ServiceError, match="cannot open the command socket"):
        CommandServer(tmp_path / "missing" / "ctl.sock", 0o600, Recorder())


# -- sd_notify -----------------------------------------------------------------------------------------

@pytest.fixture
def notify_socket(tmp_path):
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(str(tmp_path / "notify"))
    sock.settimeout(5.0)
    yield sock
    sock.close()


def test_notify_sends_one_datagram(notify_socket, monkeypatch):
    monkeypatch.setenv("NOTIFY_SOCKET", notify_socket.getsockname())
    assert sdnotify.notify("READY=1\nSTATUS=active")
    assert notify_socket.recv(1000) == b"READY=1\nSTATUS=active"


def test_notifier_keeps_its_socket_and_reaches_abstract_sockets():
    name = f"ankle-rt-test-{os.getpid()}"
    sink = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sink.bind("\0" + name)
    sink.settimeout(5.0)
    notifier = sdnotify.Notifier("@" + name)
    assert notifier.notify("WATCHDOG=1") and notifier.notify("WATCHDOG=1")
    assert sink.recv(100) == b"WATCHDOG=1" and sink.recv(100) == b"WATCHDOG=1"
    notifier.close()
    sink.close()


def test_notify_is_a_no_op_without_systemd(monkeypatch):
    monkeypatch.delenv("NOTIFY_SOCKET", raising=False)
    assert sdnotify.notify("READY=1") is False
    assert not sdnotify.Notifier.from_env().enabled


def test_notify_failure_returns_false(tmp_path):
    assert sdnotify.Notifier(str(tmp_path / "nobody-listens")).notify("READY=1") is False


@pytest.mark.parametrize("env, expected", [
    ({}, None), ({"WATCHDOG_USEC": "2000000"}, 2.0), ({"WATCHDOG_USEC": "junk"}, None),
    ({"WATCHDOG_USEC": "0"}, None), ({"WATCHDOG_USEC": "500000", "WATCHDOG_PID": str(os.getpid())}, 0.5),
    ({"WATCHDOG_USEC": "500000", "WATCHDOG_PID": "1"}, None),
])
def test_watchdog_interval(env, expected):
    assert sdnotify.watchdog_interval(env) == expected


# -- the loop's link: polling cadence, watchdog from health, lost command channel ----------------------

def link_cfg(tmp_path, **service):
    """config/sim.yaml with the socket in the test's tmp dir."""
    return load_config(SIM_CONFIG, {"service": {"socket_path": str(tmp_path / "ctl.sock"), **service}})


def test_link_polls_at_its_period_and_pings_only_while_healthy(tmp_path, notify_socket):
    from ankle_rt.service.link import ServiceLink
    cfg = link_cfg(tmp_path, poll_period_s=0.01)
    env = {"NOTIFY_SOCKET": notify_socket.getsockname(), "WATCHDOG_USEC": "1000000"}
    link = ServiceLink(cfg, Recorder(), environ=env)
    assert link.ping_period == 0.5
    sock = connect(link.server)
    link.tick(0.0, healthy=True)        # polls (accepts) and pings
    assert notify_socket.recv(100) == b"WATCHDOG=1"
    sock.sendall(b'{"cmd":"status"}\n')
    link.tick(0.005, healthy=True)      # before the next poll period: the request waits
    assert link.server.commands_handled == 0
    link.tick(0.010, healthy=False)     # polls, answers; unhealthy: no ping
    assert link.server.commands_handled == 1 and json.loads(sock.recv(1000))["ok"] is True
    link.tick(0.6, healthy=False)
    link.tick(0.7, healthy=True)        # healthy again: pings
    notify_socket.settimeout(0.0)
    assert notify_socket.recv(100) == b"WATCHDOG=1"
    with pytest.raises(BlockingIOError):
        notify_socket.recv(100)         # exactly one ping since the first: none while unhealthy
    link.ready("active")
    link.close()
    assert notify_socket.recv(100) == b"READY=1\nSTATUS=active"
    assert not (tmp_path / "ctl.sock").exists()


def test_link_without_watchdog_or_socket(tmp_path):
    from ankle_rt.service.link import ServiceLink
    link = ServiceLink(link_cfg(tmp_path, enabled=False, watchdog=False), Recorder(), environ={"WATCHDOG_USEC": "1000000"})
    assert link.server is None and link.ping_period is None and not (tmp_path / "ctl.sock").exists()
    link.tick(0.0, healthy=True)
    link.close()


def test_link_detects_a_lost_command_channel(tmp_path):
    from ankle_rt.service.link import ServiceLink
    link = ServiceLink(link_cfg(tmp_path, command_timeout_s=0.5), Recorder(), environ={})
    link.mark_command_channel(1.0)
    assert not link.command_channel_lost(1.4)
    sock = connect(link.server)
    sock.sendall(b'{"cmd":"status"}\n')
    for i in range(20):
        link.tick(1.4 + i * 0.01, healthy=True)
    assert link.server.commands_handled == 1
    assert not link.command_channel_lost(1.8) and link.command_channel_lost(2.0)
    link.close()


def test_socket_path_and_mode_from_config(tmp_path, monkeypatch):
    from ankle_rt.service import link
    cfg = link_cfg(tmp_path, socket_mode=0o600)
    assert link.socket_path(cfg) == tmp_path / "ctl.sock" and link.socket_mode(cfg) == 0o600
    cfg["service"]["socket_mode"] = "0640"
    assert link.socket_mode(cfg) == 0o640
    cfg["service"]["socket_path"] = "auto"
    monkeypatch.setattr(link, "SERVICE_RUNTIME_DIR", tmp_path / "absent")
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    assert link.socket_path(cfg) == tmp_path / "ankle-rt.sock"
    monkeypatch.delenv("XDG_RUNTIME_DIR")
    assert link.socket_path(cfg) == Path(f"/tmp/ankle-rt-{os.getuid()}.sock")
    monkeypatch.setattr(link, "SERVICE_RUNTIME_DIR", tmp_path)
    assert link.socket_path(cfg) == tmp_path / "control.sock"


def test_loop_statistics_for_status_replies_match_the_full_histogram():
    """Status replies (answered inside the loop) summarise the timing histograms from the bins up to
    the maximum only; the percentiles must equal those of the whole histogram, overflow included."""
    import numpy as np
    from ankle_rt.loop_stats import MAX_US, Histogram

    rng = np.random.default_rng(7)
    for spread_ns, overflow in ((300_000, False), (3_000_000, True)):
        h = Histogram()
        for v in rng.integers(0, spread_ns, 3000):
            h.add_ns(int(v))
        if overflow:
            h.add_ns((MAX_US + 50_000) * 1000)
        full = np.cumsum(h.counts)
        for q, key in ((50, "p50_us"), (99, "p99_us"), (99.9, "p99.9_us")):
            idx = int(np.searchsorted(full, max(q / 100 * h.n, 1), side="left"))
            expected = h.max_ns / 1000 if idx >= h.top else min(idx + 1.0, h.max_ns / 1000)
            assert h.summary()[key] == expected
