"""systemd's notify protocol (sd_notify), without a package: one non-blocking datagram per message.

systemd passes ``$NOTIFY_SOCKET`` to a ``Type=notify`` service: a filesystem path, or an abstract
socket name when it starts with '@'. Messages are newline-separated ``KEY=value`` assignments such as
``READY=1``, ``STATUS=active, 1000 Hz``, ``WATCHDOG=1`` and ``STOPPING=1``. Without the variable
(running in a terminal, in tests) every call is a no-op. A failed send returns False and never
raises: losing a notification must not stop the control loop.
"""

from __future__ import annotations

import os
import socket
from typing import Mapping


def _address(value: str) -> str:
    return "\0" + value[1:] if value.startswith("@") else value


class Notifier:
    """Sends notifications to one socket; keeps its datagram socket open, so a send is one syscall."""

    def __init__(self, address: str | None):
        self.address = _address(address) if address else None
        self._sock: socket.socket | None = None

    @classmethod
    def from_env(cls, environ: Mapping[str, str] = os.environ) -> "Notifier":
        return cls(environ.get("NOTIFY_SOCKET") or None)

    @property
    def enabled(self) -> bool:
        return self.address is not None

    def notify(self, message: str) -> bool:
        """Send ``message``; True if it was sent, False when disabled or the send failed."""
        if self.address is None:
            return False
        try:
            if self._sock is None:
                self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
                self._sock.setblocking(False)
            self._sock.sendto(message.encode(), self.address)
        except OSError:
            return False
        return True

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


def notify(message: str) -> bool:
    """One-shot notification to ``$NOTIFY_SOCKET`` (no-op returning False when it is unset)."""
    notifier = Notifier.from_env()
    try:
        return notifier.notify(message)
    finally:
        notifier.close()


def watchdog_interval(environ: Mapping[str, str] = os.environ) -> float | None:
    """The watchdog timeout systemd expects pings within (s, from ``WATCHDOG_USEC``), or None when
    no watchdog is set up for this process (unset, unparsable, or ``WATCHDOG_PID`` names another
    process). Ping at half of it, as sd_watchdog_enabled(3) advises."""
    pid = environ.get("WATCHDOG_PID")
    if pid is not None and pid != str(os.getpid()):
        return None
    try:
        usec = int(environ.get("WATCHDOG_USEC", ""))
    except ValueError:
        return None
    return usec / 1e6 if usec > 0 else None
