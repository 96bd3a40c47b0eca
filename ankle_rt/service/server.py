"""The daemon's command server: a non-blocking Unix-domain stream socket speaking
:mod:`ankle_rt.service.protocol`.

It runs inside the control loop's thread (no thread of its own, so it never competes for the GIL):
the loop calls :meth:`CommandServer.poll` every few cycles. One poll is one ``poll(2)`` with a zero
timeout plus bounded work: at most ``max_accepts`` new connections, one ``recv`` of at most
``recv_bytes`` per ready client (none while a client has ``2 * MAX_LINE_BYTES`` unprocessed), and at
most ``lines_per_client`` requests answered per client, for at most ``max_clients`` clients; a reply
that a client does not read within ``max_pending_reply_bytes`` drops the client. Whatever the peers send
(random bytes, invalid UTF-8, half lines, endless lines, clients that vanish or never read their
replies) poll() never raises and never blocks; bad requests get an error reply naming the field.

No client can lock the others out. A client that sends no complete request for ``client_timeout_s``
(idle, or stuck in half a line) is disconnected. When all ``max_clients`` slots are taken, a new
connection evicts the client that has been idle longest, so ``ankle-rt ctl deactivate`` (or stop)
always gets through; it is read at once, in the poll that accepts it. A handler may answer with a
:class:`~ankle_rt.service.protocol.Pending` reply (a profile file loading off the loop thread): that
client's reply, and its later requests, wait until it is ready, without holding up anyone else.
"""

from __future__ import annotations

import os
import select
import socket
import stat
import time
from pathlib import Path
from typing import Callable

from ankle_rt.service.protocol import (
    MAX_LINE_BYTES, Command, CommandError, CommandLimits, Pending, error_reply, format_reply, parse_command,
)

Handler = Callable[[Command], "dict | Pending"]
"""The daemon's side: handler(command) -> reply data (or a Pending reply); raises CommandError to
refuse (e.g. in fault)."""


class ServiceError(RuntimeError):
    """The command socket cannot be opened (another daemon listens, or the path is unusable)."""


class _Client:
    __slots__ = ("sock", "fd", "inbuf", "outbuf", "discarding", "eof", "closed", "last_request", "pending")

    def __init__(self, sock: socket.socket, now: float):
        self.sock = sock
        self.last_request = now  # s (server clock) of the connection or its last complete request
        self.pending: Pending | None = None
        self.fd = sock.fileno()
        self.inbuf = bytearray()
        self.outbuf = bytearray()
        self.discarding = False  # inside an over-long line: drop bytes up to the next newline
        self.eof = False         # the peer finished sending: close once its replies are out
        self.closed = False


_READ = select.POLLIN | select.POLLPRI
_INBUF_LIMIT = 2 * MAX_LINE_BYTES  # stop reading a client whose unprocessed input reaches this


class CommandServer:
    """Listen on ``path`` (created with permissions ``mode``) and answer requests with ``handler``.

    Opening removes a stale socket file left by a dead daemon, but refuses (ServiceError) when
    another daemon still listens there or when the path is something other than a socket.
    """

    def __init__(self, path: str | Path, mode: int, handler: Handler, *, limits: CommandLimits | None = None,
                 max_clients: int = 8, max_accepts: int = 4, lines_per_client: int = 2,
                 recv_bytes: int = MAX_LINE_BYTES, max_pending_reply_bytes: int = 65536,
                 client_timeout_s: float = 10.0, clock: Callable[[], float] = time.monotonic):
        self.path = Path(path)
        self.client_timeout_s = client_timeout_s
        self.clock = clock
        self.clients_timed_out = 0
        self.clients_evicted = 0
        self.handler = handler
        self.limits = limits or CommandLimits()
        self.max_clients = max_clients
        self.max_accepts = max_accepts
        self.lines_per_client = lines_per_client
        self.recv_bytes = recv_bytes
        self.max_pending_reply_bytes = max_pending_reply_bytes
        self.commands_handled = 0
        """Valid requests handled so far (any command, status included): a liveness count of the
        command channel, for a lost-channel timeout measured on the daemon's own clock."""
        self.requests_rejected = 0
        self.handler_errors = 0
        self.last_handler_error = ""
        self._clients: dict[int, _Client] = {}
        self._poller = select.poll()
        self._listener = self._listen(mode)
        self._poller.register(self._listener.fileno(), _READ)

    # -- opening and closing ------------------------------------------------------------------------

    def _listen(self, mode: int) -> socket.socket:
        self._remove_stale()
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            sock.bind(str(self.path))
            os.chmod(self.path, mode)  # before listen(): nobody can connect with the wrong permissions
            sock.listen(self.max_clients)
            sock.setblocking(False)
        except OSError as exc:
            sock.close()
            raise ServiceError(f"cannot open the command socket {self.path}: {exc.strerror or exc}") from None
        return sock

    def _remove_stale(self) -> None:
        try:
            st_mode = self.path.lstat().st_mode
        except FileNotFoundError:
            return
        except OSError as exc:
            raise ServiceError(f"cannot use the command socket path {self.path}: {exc.strerror}") from None
        if not stat.S_ISSOCK(st_mode):
            raise ServiceError(f"{self.path} exists and is not a socket; refusing to replace it")
        probe = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        probe.settimeout(1.0)
        try:
            probe.connect(str(self.path))
        except ConnectionRefusedError:  # nobody listens: left behind by a daemon that died
            try:
                self.path.unlink(missing_ok=True)
            except OSError as exc:
                raise ServiceError(f"cannot remove the stale command socket {self.path}: {exc.strerror}") from None
            return
        except OSError as exc:
            raise ServiceError(f"cannot check the existing command socket {self.path}: {exc.strerror or exc}") from None
        finally:
            probe.close()
        raise ServiceError(f"another ankle-rt daemon is already listening on {self.path}; stop it first "
                           "(ankle-rt ctl stop, or systemctl stop ankle-rt)")

    def close(self) -> None:
        """Close every connection and remove the socket file."""
        for client in tuple(self._clients.values()):
            self._drop(client)
        if self._listener.fileno() >= 0:
            self._poller.unregister(self._listener.fileno())
            self._listener.close()
            self.path.unlink(missing_ok=True)

    def __enter__(self) -> "CommandServer":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def client_count(self) -> int:
        return len(self._clients)

    # -- the loop's entry point ---------------------------------------------------------------------

    def poll(self) -> int:
        """Handle pending I/O without blocking; returns the number of requests answered."""
        now = self.clock()
        for fd, events in self._poller.poll(0):
            if fd == self._listener.fileno():
                self._accept(now)
                continue
            client = self._clients.get(fd)
            if client is None:
                continue
            if events & select.POLLOUT:
                self._flush(client)
            if client.closed:
                continue
            if events & select.POLLNVAL or (events & (select.POLLERR | select.POLLHUP) and client.eof):
                self._drop(client)
            elif not client.eof:
                self._receive(client)
        answered = 0
        for client in tuple(self._clients.values()):
            answered += self._serve(client, now)
            if (not client.closed and client.pending is None and not client.outbuf
                    and now - client.last_request > self.client_timeout_s):
                self.clients_timed_out += 1
                self._drop(client)
        return answered

    # -- internals ----------------------------------------------------------------------------------

    def _accept(self, now: float) -> None:
        for _ in range(self.max_accepts):
            try:
                sock, _addr = self._listener.accept()
            except OSError:  # nothing pending (EAGAIN), or e.g. EMFILE: try again next poll
                return
            if len(self._clients) >= self.max_clients and not self._evict_idlest():
                try:
                    sock.send(format_reply(False, error=f"too many clients (at most {self.max_clients})", field="line"),
                              socket.MSG_DONTWAIT | socket.MSG_NOSIGNAL)
                except OSError:
                    pass
                sock.close()
                continue
            sock.setblocking(False)
            client = _Client(sock, now)
            self._clients[client.fd] = client
            self._poller.register(client.fd, _READ)
            self._receive(client)   # a one-shot client (ctl deactivate) has usually sent its line already

    def _evict_idlest(self) -> bool:
        """Make room: drop the client whose last request is oldest (not one awaiting a Pending reply)."""
        idle = [c for c in self._clients.values() if c.pending is None]
        if not idle:
            return False
        self.clients_evicted += 1
        self._drop(min(idle, key=lambda c: c.last_request))
        return True

    def _receive(self, client: _Client) -> None:
        room = min(self.recv_bytes, _INBUF_LIMIT - len(client.inbuf))
        if room <= 0:  # back-pressure: serve the backlog first (bounded memory per client)
            return
        try:
            data = client.sock.recv(room)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:  # ECONNRESET: the client vanished
            self._drop(client)
            return
        if data:
            client.inbuf += data
            return
        client.eof = True
        self._poller.modify(client.fd, select.POLLOUT if client.outbuf else 0)

    def _serve(self, client: _Client, now: float) -> int:
        """Answer at most ``lines_per_client`` complete lines of one client (fair and bounded)."""
        answered = 0
        inbuf = client.inbuf
        if client.pending is not None:
            reply = self._poll_pending(client.pending)
            if reply is None:
                return 0
            client.pending = None
            self._reply(client, reply)
        while answered < self.lines_per_client and not client.closed and client.pending is None:
            end = inbuf.find(b"\n")
            if end < 0:
                if len(inbuf) >= MAX_LINE_BYTES:
                    if not client.discarding:
                        self.requests_rejected += 1
                        self._reply(client, error_reply(CommandError("line", f"longer than {MAX_LINE_BYTES} bytes")))
                    client.discarding = True
                    inbuf.clear()
                elif client.eof:  # a half line at the end of the stream is never executed
                    inbuf.clear()
                break
            line = bytes(inbuf[:end + 1])
            del inbuf[:end + 1]
            if client.discarding:  # the tail of an over-long line, already answered
                client.discarding = False
            elif line.strip():
                answered += 1
                client.last_request = now
                reply = self._answer(line)
                if isinstance(reply, Pending):
                    client.pending = reply
                else:
                    self._reply(client, reply)
        if client.eof and not client.closed and not client.outbuf and not inbuf and client.pending is None:
            self._drop(client)
        return answered

    def _poll_pending(self, pending: Pending) -> bytes | None:
        try:
            data = pending.poll()
        except CommandError as exc:
            self.requests_rejected += 1
            return error_reply(exc)
        except Exception as exc:  # a daemon bug must not take the command channel down
            return self._internal_error(exc)
        return None if data is None else format_reply(True, **data)

    def _internal_error(self, exc: Exception) -> bytes:
        self.handler_errors += 1
        self.last_handler_error = f"{type(exc).__name__}: {exc}"
        return format_reply(False, error=f"internal error: {self.last_handler_error}", field="cmd")

    def _answer(self, line: bytes) -> "bytes | Pending":
        try:
            command = parse_command(line, self.limits)
        except CommandError as exc:
            self.requests_rejected += 1
            return error_reply(exc)
        self.commands_handled += 1
        try:
            data = self.handler(command)
            return data if isinstance(data, Pending) else format_reply(True, **data)
        except CommandError as exc:
            self.requests_rejected += 1
            return error_reply(exc)
        except Exception as exc:  # a daemon bug must not take the command channel (or the loop) down
            return self._internal_error(exc)

    def _reply(self, client: _Client, data: bytes) -> None:
        client.outbuf += data
        if len(client.outbuf) > self.max_pending_reply_bytes:  # the peer does not read its replies
            self._drop(client)
            return
        self._flush(client)

    def _flush(self, client: _Client) -> None:
        try:
            sent = client.sock.send(client.outbuf, socket.MSG_NOSIGNAL)
        except (BlockingIOError, InterruptedError):
            sent = 0
        except OSError:  # EPIPE / ECONNRESET: the client vanished
            self._drop(client)
            return
        del client.outbuf[:sent]
        read = 0 if client.eof else _READ
        self._poller.modify(client.fd, read | select.POLLOUT if client.outbuf else read)

    def _drop(self, client: _Client) -> None:
        if client.closed:
            return
        client.closed = True
        del self._clients[client.fd]
        self._poller.unregister(client.fd)
        client.sock.close()
