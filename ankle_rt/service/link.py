"""The one object the control loop drives to talk to the outside: the command socket and systemd.

The loop calls :meth:`ServiceLink.tick` once per cycle with its clock time and its health. That is
two float comparisons on most cycles; every ``service.poll_period_s`` it polls the command server
(bounded, non-blocking work; the daemon's handler runs inside it, in the loop thread), and while the
loop is healthy it pings systemd's watchdog at half the ``WatchdogSec`` interval. No thread: a loop
that stalls or stops being healthy stops the pings, and systemd restarts the service.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Mapping, Any

from ankle_rt.service.protocol import CommandLimits
from ankle_rt.service.sdnotify import Notifier, watchdog_interval
from ankle_rt.service.server import CommandServer, Handler

SERVICE_RUNTIME_DIR = Path("/run/ankle-rt")
"""The unit's RuntimeDirectory (systemd creates it, owned by the service user)."""


def socket_path(cfg: Mapping[str, Any]) -> Path:
    """``service.socket_path``, or for ``auto``: /run/ankle-rt/control.sock when that directory
    exists (the installed service), else $XDG_RUNTIME_DIR/ankle-rt.sock, else
    /tmp/ankle-rt-<uid>.sock. The daemon and ``ankle-rt ctl`` resolve it the same way."""
    configured = cfg["service"]["socket_path"]
    if configured != "auto":
        return Path(configured)
    if SERVICE_RUNTIME_DIR.is_dir():
        return SERVICE_RUNTIME_DIR / "control.sock"
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime:
        return Path(runtime) / "ankle-rt.sock"
    return Path(f"/tmp/ankle-rt-{os.getuid()}.sock")


def socket_mode(cfg: Mapping[str, Any]) -> int:
    """``service.socket_mode`` as permission bits (written '0660' or 0660 in YAML)."""
    mode = cfg["service"]["socket_mode"]
    return int(mode, 8) if isinstance(mode, str) else mode


class ServiceLink:
    """Command socket + systemd notification for one daemon run. ``handler`` is Daemon.handle."""

    def __init__(self, cfg: Mapping[str, Any], handler: Handler, *, path: str | Path | None = None,
                 environ: Mapping[str, str] = os.environ):
        svc = cfg["service"]
        self.path = Path(path) if path is not None else socket_path(cfg)
        self.server = CommandServer(self.path, socket_mode(cfg), handler, limits=CommandLimits.from_config(cfg),
                                    client_timeout_s=svc["client_timeout_s"]) if svc["enabled"] else None
        self.notifier = Notifier.from_env(environ)
        interval = watchdog_interval(environ) if svc["watchdog"] else None
        self.ping_period = interval / 2.0 if interval else None
        """s between WATCHDOG=1 pings (half of WatchdogSec), or None when no watchdog is armed."""
        self.poll_period_s = svc["poll_period_s"]
        self.command_timeout_s = svc["command_timeout_s"]
        self._next_poll = float("-inf")
        self._next_ping = float("-inf")
        self._seen = 0
        self._last_command_t = None

    def tick(self, now: float, healthy: bool) -> None:
        """Call every cycle with the loop clock ``now`` (s) and whether the loop keeps its deadlines
        and sensors (the watchdog is fed only while ``healthy``). Never blocks, never raises on input."""
        if now >= self._next_poll:
            self._next_poll = now + self.poll_period_s
            server = self.server
            if server is not None:
                server.poll()
                if server.commands_handled != self._seen:
                    self._seen = server.commands_handled
                    self._last_command_t = now
        if healthy and self.ping_period is not None and now >= self._next_ping:
            self._next_ping = now + self.ping_period
            self.notifier.notify("WATCHDOG=1")

    def command_channel_lost(self, now: float) -> bool:
        """True when ``service.command_timeout_s`` > 0 and no valid request came for longer than it.
        Counted from :meth:`mark_command_channel` (call it on activation), or the last request."""
        if self.command_timeout_s <= 0.0 or self._last_command_t is None:
            return False
        return now - self._last_command_t > self.command_timeout_s

    def mark_command_channel(self, now: float) -> None:
        """Restart the lost-channel timer (on activation)."""
        self._last_command_t = now

    def ready(self, status: str) -> None:
        """Tell systemd start-up is complete (READY=1): the loop runs and takes commands."""
        self.notifier.notify(f"READY=1\nSTATUS={status}")

    def status(self, status: str) -> None:
        """A one-line state shown by ``systemctl status`` (call on state changes, not every cycle)."""
        self.notifier.notify(f"STATUS={status}")

    def stopping(self, status: str = "stopping") -> None:
        self.notifier.notify(f"STOPPING=1\nSTATUS={status}")

    def close(self) -> None:
        if self.server is not None:
            self.server.close()
        self.notifier.close()
