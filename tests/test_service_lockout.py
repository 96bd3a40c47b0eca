"""Issue 10 item 4: no client can lock the command channel; deactivate always gets through."""

from __future__ import annotations

import json
import socket

from ankle_rt.service.protocol import Deactivate, Pending
from ankle_rt.service.server import CommandServer
from tests.service_helpers import reply_of


class FakeClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def connect(path) -> socket.socket:
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.settimeout(5.0)  # a guard only
    sock.connect(str(path))
    return sock


def test_eight_half_line_clients_do_not_lock_out_deactivate(tmp_path):
    reached = []
    srv = CommandServer(tmp_path / "s", 0o600, lambda c: reached.append(c) or {"state": "safe"})
    squatters = [connect(srv.path) for _ in range(srv.max_clients)]
    for sock in squatters:
        sock.sendall(b'{"cmd": "sta')              # half a line, then nothing
    for _ in range(3):
        srv.poll()
    assert srv.client_count == srv.max_clients
    ctl = connect(srv.path)
    ctl.sendall(b'{"cmd": "deactivate"}\n')
    assert reply_of(srv, ctl) == {"ok": True, "state": "safe"}
    assert reached == [Deactivate()]
    srv.close()


def test_idle_and_half_line_clients_time_out(tmp_path):
    clock = FakeClock()
    srv = CommandServer(tmp_path / "s", 0o600, lambda c: {"state": "safe"}, client_timeout_s=2.0, clock=clock)
    idle, half, busy = (connect(srv.path) for _ in range(3))
    half.sendall(b'{"cmd"')
    srv.poll()
    assert srv.client_count == 3
    clock.t = 1.5
    busy.sendall(b'{"cmd": "status"}\n')
    reply_of(srv, busy)
    clock.t = 2.5                                   # idle and half are 2.5 s old, busy's request 1 s
    srv.poll()
    assert srv.client_count == 1 and srv.clients_timed_out == 2
    assert idle.recv(100) == b"" and half.recv(100) == b""
    srv.close()


def test_a_pending_reply_holds_its_client_but_nobody_else(tmp_path):
    ready = []
    srv = CommandServer(tmp_path / "s", 0o600,
                        lambda c: Pending(lambda: ready[0] if ready else None) if isinstance(c, Deactivate)
                        else {"state": "x"}, max_clients=2)
    slow, other = connect(srv.path), connect(srv.path)
    slow.sendall(b'{"cmd": "deactivate"}\n{"cmd": "status"}\n')
    for _ in range(5):
        srv.poll()
    other.sendall(b'{"cmd": "status"}\n')
    assert reply_of(srv, other) == {"ok": True, "state": "x"}
    third = connect(srv.path)                       # evicts `other` (idle), never the waiting client
    srv.poll()
    assert other.recv(100) == b""
    ready.append({"state": "done"})
    slow.setblocking(False)
    lines = b""
    for _ in range(50):
        srv.poll()
        try:
            lines += slow.recv(1000)
        except BlockingIOError:
            pass
    assert [json.loads(x) for x in lines.splitlines()] == [{"ok": True, "state": "done"}, {"ok": True, "state": "x"}]
    third.close()
    srv.close()
