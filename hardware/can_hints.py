"""What to do when a CAN interface will not open: python-can passes the kernel's bare error
(``[Errno 97] Address family not supported by protocol`` on a kernel without SocketCAN), which
does not tell a user that a module is missing or the interface is down."""

from __future__ import annotations

import errno

BITRATE_UP = "ip link set {channel} up type can bitrate 1000000 restart-ms 100"


def open_hint(exc: BaseException, interface: str, channel: str) -> str:
    """A sentence of advice for ``exc`` raised opening ``interface``/``channel`` ('' when none fits)."""
    code = getattr(exc, "errno", None)
    if code == errno.EAFNOSUPPORT:
        return ("this kernel has no SocketCAN support (no AF_CAN sockets): load it with `modprobe can can_raw` "
                "plus the adapter's driver (e.g. `modprobe gs_usb`, `peak_usb`, `mcp251x`), or use a kernel built "
                "with CONFIG_CAN; in a container the host's kernel decides. Without CAN hardware, the bench "
                "configs use python-can's `virtual` interface")
    if code == errno.ENODEV:
        return (f"there is no network interface {channel!r}: `ip link show` lists them; a real adapter comes up "
                f"with `{BITRATE_UP.format(channel=channel)}`, a virtual one for tests with "
                f"`modprobe vcan && ip link add dev {channel} type vcan && ip link set {channel} up`")
    if code == errno.ENETDOWN:
        return f"the interface {channel!r} is down: `{BITRATE_UP.format(channel=channel)}`"
    return ""


def describe_open_error(exc: BaseException, interface: str, channel: str) -> str:
    """``exc`` followed by the hint, for an error message."""
    hint = open_hint(exc, interface, channel)
    return f"{exc}" + (f"\n  hint: {hint}" if hint else "")
