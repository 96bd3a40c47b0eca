"""What the command socket costs the control loop: one CommandServer.poll() when nothing arrived,
when a client sends a status request (answered by the real Daemon.handle), and when a client floods
the socket with garbage. Prints figures (µs per poll: median, p99, max); asserts nothing.

    python benchmarks/bench_service.py [--polls N]

The loop polls every service.poll_period_s (10 ms by default), so at 1 kHz one cycle in ten pays
the idle cost, and a cycle that answers a request pays the request cost. The GC is frozen and
disabled, as in the daemon's loop.
"""

from __future__ import annotations

import argparse
import gc
import socket
import tempfile
import time
from pathlib import Path

import numpy as np

from ankle_rt.clock import SimClock
from ankle_rt.config import load_config
from ankle_rt.daemon import Daemon
from ankle_rt.paths import default_config_path
from ankle_rt.service.protocol import CommandLimits
from ankle_rt.service.server import CommandServer


def timed_polls(server: CommandServer, polls: int, before=None) -> np.ndarray:
    """µs per poll() call; ``before()`` runs (untimed) ahead of each poll."""
    out = np.empty(polls)
    for i in range(polls):
        if before is not None:
            before()
        t0 = time.perf_counter_ns()
        server.poll()
        out[i] = (time.perf_counter_ns() - t0) / 1000.0
    return out


def report(name: str, us: np.ndarray) -> None:
    print(f"{name:<44} median {np.median(us):7.1f} us   p99 {np.percentile(us, 99):7.1f} us   max {us.max():8.1f} us")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--polls", type=int, default=5000)
    args = parser.parse_args()

    cfg = load_config(default_config_path())
    daemon = Daemon(cfg, SimClock())
    daemon.run(0.2)  # some loop statistics for the status replies
    gc.collect()
    gc.freeze()
    gc.disable()  # as inside the daemon's loop
    with tempfile.TemporaryDirectory() as tmp:
        server = CommandServer(Path(tmp) / "s", 0o600, daemon.handle, limits=CommandLimits.from_config(cfg))
        report("idle poll (no client)", timed_polls(server, args.polls))

        client = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        client.connect(str(server.path))
        server.poll()
        client.setblocking(False)

        def status_request():
            try:
                while client.recv(65536):
                    pass
            except BlockingIOError:
                pass
            client.send(b'{"cmd":"status"}\n')

        report("poll answering one status request", timed_polls(server, args.polls, status_request))

        rng = np.random.default_rng(0)
        garbage = rng.integers(0, 256, 1 << 20, dtype=np.uint8).tobytes()

        def flood():
            try:
                while client.recv(65536):
                    pass
            except BlockingIOError:
                pass
            try:
                client.send(garbage[rng.integers(0, len(garbage) - 8192):][:8192])
            except BlockingIOError:
                pass

        report("poll under a flood of random bytes", timed_polls(server, args.polls, flood))
        client.close()
        server.close()
    daemon.close()


if __name__ == "__main__":
    main()
