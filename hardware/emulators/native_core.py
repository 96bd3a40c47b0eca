"""The bridge firmware's portable C core (hardware/firmware/core/), compiled natively and loaded with
ctypes: firmware in the loop. :class:`NativeCore` offers the interface of the Python core in
``bridge_core`` (``PythonCore``), so the emulator's plant side drives either; only the protocol
and safety logic differ between the two, and the same tests run against both.

The shared library is built on first use with the host's C compiler (``cc``/``gcc``) into a cache
file named after a hash of the sources, so a changed core is rebuilt and parallel test processes
share one build. Without a compiler :func:`load_library` raises :class:`CoreBuildError` naming what
is missing (CI installs gcc; the tests fail, they do not skip).
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Sequence

from hardware.serial_protocol import PAYLOADS, MsgType

FIRMWARE_DIR = Path(__file__).resolve().parent.parent / "firmware"
SOURCES = ("core/frame.c", "core/bridge.c", "host/core_api.c")
HEADERS = ("core/frame.h", "core/bridge.h")
CFLAGS = ("-std=c11", "-O2", "-Wall", "-Wextra", "-Werror", "-fPIC", "-shared")


class CoreBuildError(RuntimeError):
    """The native core could not be built (no compiler, or it failed)."""


class Caps(ctypes.Structure):
    """bridge_caps: what the emulated board can do and how it is wired."""
    _fields_ = [("rate_hz", ctypes.c_uint16), ("counter_bits", ctypes.c_uint8), ("modes", ctypes.c_uint8),
                ("enable_off", ctypes.c_uint8), ("code_min", ctypes.c_int32 * 2), ("code_max", ctypes.c_int32 * 2),
                ("reset_code", ctypes.c_int32 * 2)]


class Inputs(ctypes.Structure):
    """bridge_inputs: the sensors latched at one tick."""
    _fields_ = [("time_us", ctypes.c_uint64), ("enc", ctypes.c_uint32 * 2), ("sg", ctypes.c_int32 * 2),
                ("joint", ctypes.c_int32 * 2), ("inputs", ctypes.c_uint8), ("status", ctypes.c_uint8)]


class View(ctypes.Structure):
    """host_bridge_view: the core's state as the emulator and the tests look at it."""
    _fields_ = [("configured", ctypes.c_uint8), ("watchdog_tripped", ctypes.c_uint8), ("enables", ctypes.c_uint8),
                ("outputs_enabled", ctypes.c_uint8), ("code", ctypes.c_int32 * 2), ("commands", ctypes.c_uint32),
                ("watchdog_ticks", ctypes.c_uint32), ("tx_dropped", ctypes.c_uint32), ("frames", ctypes.c_uint32),
                ("crc_errors", ctypes.c_uint32), ("discarded", ctypes.c_uint32), ("tx_seq", ctypes.c_uint16)]


def _compiler() -> str:
    for name in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if name and shutil.which(name):
            return name
    raise CoreBuildError("cannot build the bridge firmware core natively: no C compiler found "
                         "(install gcc, e.g. apt-get install gcc, or set CC)")


def library_path() -> Path:
    """Where the shared library for the current sources is (built or not)."""
    digest = hashlib.sha256()
    for rel in SOURCES + HEADERS:
        digest.update((FIRMWARE_DIR / rel).read_bytes())
    digest.update(" ".join(CFLAGS).encode())
    cache = Path(os.environ.get("ANKLE_RT_CORE_CACHE", tempfile.gettempdir()))
    return cache / f"ankle-rt-bridge-core-{digest.hexdigest()[:16]}.so"


def build_library() -> Path:
    """Compile the core into a shared library (once per source version); its path."""
    out = library_path()
    if out.exists():
        return out
    cc = _compiler()
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f"{out.name}.{os.getpid()}.tmp")
    cmd = [cc, *CFLAGS, "-o", str(tmp), *(str(FIRMWARE_DIR / s) for s in SOURCES)]
    result = subprocess.run(cmd, capture_output=True, text=True)
    if result.returncode != 0:
        raise CoreBuildError(f"building the bridge firmware core failed ({' '.join(cmd)}):\n{result.stderr}")
    os.replace(tmp, out)          # atomic: a parallel build of the same sources loses nothing
    return out


_LIB: ctypes.CDLL | None = None


def load_library() -> ctypes.CDLL:
    """The native core (built if needed), its signatures declared and its layouts checked."""
    global _LIB
    if _LIB is not None:
        return _LIB
    lib = ctypes.CDLL(str(build_library()))
    p, u8p, sz = ctypes.c_void_p, ctypes.c_char_p, ctypes.c_size_t
    for name, res, args in (
            ("bridge_init", None, [p, ctypes.POINTER(Caps)]), ("bridge_restart", None, [p]),
            ("bridge_receive", sz, [p, u8p, sz]), ("bridge_poll", ctypes.c_int, [p]),
            ("bridge_tick", None, [p]), ("bridge_sample", None, [p, ctypes.POINTER(Inputs)]),
            ("bridge_trip_watchdog", None, [p]), ("bridge_take_tx", sz, [p, u8p, sz]),
            ("host_bridge_view_get", None, [p, ctypes.POINTER(View)]),
            ("bp_parser_init", None, [p]), ("bp_parser_feed", sz, [p, u8p, sz]),
            ("bp_parser_next", ctypes.c_int, [p]), ("bp_parser_payload", ctypes.c_void_p, [p]),
            ("host_parser_seq", ctypes.c_uint16, [p]), ("host_parser_counts", None, [p, ctypes.c_uint32 * 3]),
            ("bp_crc32", ctypes.c_uint32, [u8p, sz])):
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = res, args
    for name, struct in (("caps", Caps), ("inputs", Inputs), ("view", View)):
        size = getattr(lib, f"host_sizeof_{name}")
        size.restype = sz
        if size() != ctypes.sizeof(struct):
            raise CoreBuildError(f"native core: struct {name} is {size()} bytes in C, {ctypes.sizeof(struct)} in ctypes")
    for name in ("host_sizeof_bridge", "host_sizeof_parser"):
        getattr(lib, name).restype = sz
    _LIB = lib
    return lib


class NativeCore:
    """One instance of the C core (bridge.h) with the interface of ``bridge_core.PythonCore``."""

    TX_CHUNK = 512

    def __init__(self, rate_hz: int, counter_bits: int, modes: int, enable_off: int,
                 code_range: Sequence[tuple[int, int]], reset_codes: Sequence[int]):
        self.lib = lib = load_library()
        self._mem = ctypes.create_string_buffer(lib.host_sizeof_bridge())
        self._ptr = ctypes.cast(self._mem, ctypes.c_void_p)
        caps = Caps(rate_hz=rate_hz, counter_bits=1 if counter_bits == 16 else 2, modes=modes, enable_off=enable_off)
        for k in (0, 1):
            caps.code_min[k], caps.code_max[k] = code_range[k]
            caps.reset_code[k] = reset_codes[k]
        lib.bridge_init(self._ptr, ctypes.byref(caps))
        self._inputs = Inputs()
        self._view = View()
        self._tx = ctypes.create_string_buffer(self.TX_CHUNK)

    def _state(self) -> View:
        self.lib.host_bridge_view_get(self._ptr, ctypes.byref(self._view))
        return self._view

    @property
    def configured(self) -> bool:
        return bool(self._state().configured)

    @property
    def watchdog_tripped(self) -> bool:
        return bool(self._state().watchdog_tripped)

    @property
    def codes(self) -> list[int]:
        v = self._state()
        return [v.code[0], v.code[1]]

    @property
    def enables(self) -> int:
        return self._state().enables

    @property
    def commands(self) -> int:
        return self._state().commands

    @property
    def watchdog_ticks(self) -> int:
        return self._state().watchdog_ticks

    @property
    def crc_errors(self) -> int:
        return self._state().crc_errors

    def outputs_enabled(self) -> bool:
        return bool(self._state().outputs_enabled)

    def receive(self, data: bytes) -> int:
        return self.lib.bridge_receive(self._ptr, data, len(data))

    def poll(self) -> int:
        return self.lib.bridge_poll(self._ptr)

    def tick(self) -> None:
        self.lib.bridge_tick(self._ptr)

    def sample(self, fields: Sequence[int]) -> None:
        i = self._inputs
        (i.time_us, i.enc[0], i.enc[1], i.sg[0], i.sg[1], i.joint[0], i.joint[1], i.inputs, i.status) = fields
        self.lib.bridge_sample(self._ptr, ctypes.byref(i))

    def trip_watchdog(self) -> None:
        self.lib.bridge_trip_watchdog(self._ptr)

    def restart(self) -> None:
        self.lib.bridge_restart(self._ptr)

    def take_tx(self) -> bytes:
        out = b""
        while True:
            n = self.lib.bridge_take_tx(self._ptr, self._tx, self.TX_CHUNK)
            if not n:
                return out
            out += self._tx.raw[:n]


class NativeParser:
    """The C stream parser alone (bp_parser), for feeding it garbage in process."""

    def __init__(self) -> None:
        self.lib = lib = load_library()
        self._mem = ctypes.create_string_buffer(lib.host_sizeof_parser())
        self._ptr = ctypes.cast(self._mem, ctypes.c_void_p)
        lib.bp_parser_init(self._ptr)
        self._counts = (ctypes.c_uint32 * 3)()

    def feed(self, data: bytes) -> int:
        """Take up to len(data) bytes; how many were taken."""
        return self.lib.bp_parser_feed(self._ptr, data, len(data))

    def next_frame(self) -> tuple[int, int, bytes] | None:
        """(type, seq, payload) of the next valid frame, or None."""
        mtype = self.lib.bp_parser_next(self._ptr)
        if not mtype:
            return None
        size = PAYLOADS[MsgType(mtype)].size
        return mtype, self.lib.host_parser_seq(self._ptr), ctypes.string_at(self.lib.bp_parser_payload(self._ptr), size)

    def counts(self) -> tuple[int, int, int]:
        """(frames, crc_errors, discarded)."""
        self.lib.host_parser_counts(self._ptr, self._counts)
        return tuple(self._counts)
