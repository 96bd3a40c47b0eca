"""Command fuzz: random bytes and malformed JSON on the socket never crash the server or the daemon,
never reach the controller, and never move the ankle.

The generators are seeded with a fixed default seed, so every run sends the same bytes; set
ANKLE_RT_FUZZ_SEED to try another one (the seed is printed; a failure report includes it). Every
generated line is malformed by construction: a corruption that happens to leave a valid command is
drawn again, so the tests can require an error reply for every line.
"""

from __future__ import annotations

import json
import os
import random
import socket

from ankle_rt.service.protocol import (MAX_LINE_BYTES, Command, CommandError, CommandLimits, SetGains, SetReference,
                                       parse_command)
from ankle_rt.service.server import CommandServer
from tests.service_helpers import LineClient, activate, daemon, reply_of, status  # noqa: F401  (daemon is a fixture)

GUARD_POLLS = 5000  # generous bound on polls while waiting; no wall-clock timing
DEFAULT_SEED = 20261123


def fuzz_seed() -> int:
    seed = int(os.environ.get("ANKLE_RT_FUZZ_SEED", DEFAULT_SEED))
    print(f"fuzz seed: {seed} (replay with ANKLE_RT_FUZZ_SEED={seed})")
    return seed


VALID = [b'{"cmd":"status"}', b'{"cmd":"set_reference","dp":0.1,"ie":0.0}', b'{"cmd":"set_gains","kp":50}',
         b'{"cmd":"start_profile","name":"sine","params":{"amplitude_dp":0.05}}']


def malformed_line(rng: random.Random) -> bytes:
    """One line of garbage: random bytes, broken JSON, wrong types, out-of-range or non-finite values."""
    kind = rng.randrange(9)
    if kind == 0:
        return bytes(rng.randrange(256) for _ in range(rng.randrange(1, 200)))
    if kind == 1:
        good = rng.choice(VALID)
        return good[:rng.randrange(len(good))]                       # truncated JSON
    if kind == 2:
        while True:   # one corrupted byte; drawn again when it still reads as a command ("kp":50 -> "kp":58)
            good = bytearray(rng.choice(VALID))
            good[rng.randrange(len(good))] = rng.randrange(256)
            if not is_command(bytes(good)):
                return bytes(good)
    if kind == 3:
        return b"[" * rng.randrange(1, 3000)                         # deep nesting
    if kind == 4:
        return json.dumps(rng.choice([None, 1, "status", [], {}, {"cmd": None}, {"cmd": ["status"]}])).encode()
    if kind == 5:
        value = rng.choice(["NaN", "Infinity", "-Infinity", "1e400", '"0.1"', "true", "null", "[]", "{}"])
        field = rng.choice(["dp", "ie", "ramp"])
        fields = {"dp": "0", "ie": "0", field: value}
        return ("{\"cmd\":\"set_reference\"," + ",".join(f'"{k}":{v}' for k, v in fields.items()) + "}").encode()
    if kind == 6:
        return json.dumps({"cmd": "set_reference", "dp": rng.uniform(0.7, 100) * rng.choice([-1, 1]),
                           "ie": 0.0}).encode()                     # beyond the ankle range
    if kind == 7:
        return json.dumps({"cmd": "set_gains", rng.choice(["kp", "kd", "stiffness_dp", "bogus"]):
                           rng.uniform(-1e6, -1e-9)}).encode()       # negative gains / unknown gain
    return json.dumps({"cmd": rng.choice(["fly", "ACTIVATE", "", "status "]), "x": 1}).encode()


def is_command(line: bytes) -> bool:
    """Whether the protocol accepts ``line`` as a command."""
    try:
        parse_command(line)
    except CommandError:
        return False
    return True


def fuzz_stream(rng: random.Random, lines: int) -> bytes:
    """Malformed lines, with a few over-long lines and invalid UTF-8 runs, joined by newlines."""
    out = bytearray()
    for _ in range(lines):
        out += malformed_line(rng) if rng.random() > 0.02 else b"x" * (MAX_LINE_BYTES + rng.randrange(5000))
        out += b"\n"
    return bytes(out)


def send_in_random_chunks(sock: socket.socket, data: bytes, rng: random.Random) -> None:
    pos = 0
    while pos < len(data):
        n = rng.randrange(1, 700)
        sock.sendall(data[pos:pos + n])
        pos += n


def test_every_generated_line_is_malformed():
    """The fuzz lines of many seeds are all refused by the protocol (what the daemon test relies on)."""
    for seed in range(200):
        rng = random.Random(seed)
        for _ in range(200):
            line = malformed_line(rng)
            assert not is_command(line), (seed, line)


# -- the server alone, in process -------------------------------------------------------------------

def test_server_survives_fuzz_and_only_valid_commands_reach_the_handler(tmp_path):
    rng = random.Random(fuzz_seed())
    reached: list[Command] = []
    server = CommandServer(tmp_path / "s", 0o600, lambda cmd: reached.append(cmd) or {"state": "configured"})
    for _ in range(6):
        clients = []
        for _ in range(rng.randrange(1, 5)):
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            sock.connect(str(server.path))
            sock.setblocking(False)
            clients.append(sock)
        for sock in clients:
            try:
                send_in_random_chunks(sock, fuzz_stream(rng, 40), rng)
            except BlockingIOError:
                pass  # the server has not read yet: the rest of this stream is simply never sent
            for _ in range(rng.randrange(0, 20)):
                server.poll()
            if rng.random() < 0.5:
                sock.close()  # vanish with requests and replies in flight
        for _ in range(200):
            server.poll()
        for sock in clients:
            sock.close()
    for _ in range(GUARD_POLLS):
        server.poll()
        if server.client_count == 0:
            break
    assert server.client_count == 0
    limit = CommandLimits().reference_limit_rad
    for cmd in reached:  # whatever got through is a complete, in-range command
        if isinstance(cmd, SetReference):
            assert abs(cmd.dp) <= limit and abs(cmd.ie) <= limit
        if isinstance(cmd, SetGains):
            assert cmd.given() and min(cmd.given().values()) >= 0.0
    assert server.requests_rejected > 0 and server.handler_errors == 0

    probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    probe.connect(str(server.path))
    probe.sendall(b'{"cmd":"status"}\n')
    assert reply_of(server, probe, GUARD_POLLS) == {"ok": True, "state": "configured"}
    server.close()


# -- a real daemon (`ankle-rt run`, real time, in a subprocess) ---------------------------------------

def test_daemon_survives_fuzz_and_rejects_bad_commands_without_moving(daemon):
    proc, path = daemon
    rng = random.Random(fuzz_seed())
    before = status(path)
    assert before["state"] == "configured" and before["motor_pos_rad"] == [0.0, 0.0]

    # 1. garbage from clients that come and go, some never reading their replies
    for _ in range(8):
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.settimeout(60.0)
        sock.connect(str(path))
        send_in_random_chunks(sock, fuzz_stream(rng, 60), rng)
        if rng.random() < 0.5:
            sock.shutdown(socket.SHUT_WR)
            while sock.recv(65536):  # read the error replies to the end
                pass
        sock.close()

    # 2. line by line: every malformed line gets an error reply naming a field
    client = LineClient(path)
    for _ in range(150):
        line = malformed_line(rng).replace(b"\n", b" ")
        if not line.strip():
            continue
        reply = client.request(line)
        assert reply["ok"] is False and reply["field"] and reply["error"], (line, reply)

    after = status(path)
    assert proc.poll() is None, "the daemon died"
    assert after["state"] in ("configured", "safe") and after["current_a"] == [0.0, 0.0]
    assert after["motor_pos_rad"] == [0.0, 0.0], "the ankle moved"

    # 3. active and holding: out-of-range and malformed commands are refused and change nothing
    # a corrupted line can still be a valid set_gains (its target applies once active): restore them
    assert client.request(json.dumps({"cmd": "set_gains", **before["gains"]}).encode())["ok"]
    assert client.request(b'{"cmd":"start_profile","name":"hold","params":{"dp":0,"ie":0}}')["ok"]
    assert activate(client) == {"ok": True, "state": "active"}
    refused = [  # (request, the field the error names, words in the message)
        (b'{"cmd":"set_reference","dp":0.9,"ie":0}', "dp", "outside the ankle range"),
        (b'{"cmd":"set_reference","dp":0,"ie":-2}', "ie", "outside the ankle range"),
        (b'{"cmd":"set_reference","dp":NaN,"ie":0}', "dp", "finite"),
        (b'{"cmd":"set_reference","dp":0.1,"ie":0,"ramp":-1}', "ramp", "between 0 and"),
        (b'{"cmd":"set_gains","kp":-5}', "kp", ">= 0"),
        (b'{"cmd":"set_gains","kp":1,"stiffness_dp":1}', "stiffness_dp", "unknown gain"),  # PD: nothing applied
        (b'{"cmd":"start_profile","name":"sine","params":{"frequency_hz":500}}', "params.frequency_hz", "must be <= 50"),
        (b'{"cmd":"start_profile","name":"sine","params":{"bogus":1}}', "params.bogus", "unknown key (expected one of"),
        (b'{"cmd":"start_profile","name":"csv","params":{"path":"/nonexistent/refs.csv"}}', "params.path", "cannot read"),
        (b'{"cmd":"start_profile","name":"fly"}', "name", "unknown profile"),
        (b'{"cmd":"start_profile","name":"step","params":{"dp":0.7}}', "params", "beyond the ankle range"),
        (b'{"cmd":"activate"}', "cmd", "cannot activate"),  # already active
        (b'{"cmd":"set_reference","dp":0.1,"ie":0', "line", "not valid JSON"),
    ]
    for line, field, words in refused:
        reply = client.request(line)
        assert reply["ok"] is False and reply["field"] == field and words in reply["error"], (line, reply)
    held = status(path)
    assert held["state"] == "active"
    assert held["reference_deg"] == [0.0, 0.0] and held["gains"] == before["gains"]
    assert max(abs(a) for a in held["ankle_deg"]) < 0.5

    assert client.request(b'{"cmd":"stop"}')["ok"]
    client.close()
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert "Traceback" not in err
