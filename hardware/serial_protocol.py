"""The binary protocol between the daemon and the microcontroller bridge (docs/serial-protocol.md).

Every frame, little-endian::

    A5 5A | length u8 | version u8 | type u8 | seq u16 | payload (length bytes) | crc32 u32

``length`` counts the payload only and is fixed per message type; ``seq`` counts the sender's frames
(wraps at 2^16); ``crc32`` is CRC-32/ISO-HDLC (zlib's: poly 0x04C11DB7 reflected, init and xorout
0xFFFFFFFF; check value of b"123456789" = 0xCBF43926) over length..payload, i.e. everything between
the sync bytes and the CRC. Payload layouts are the ``struct`` formats below.

:class:`FrameWriter` packs frames into preallocated buffers; :class:`StreamParser` finds frames in a
byte stream, resynchronising after garbage: a candidate frame must have the sync bytes, this
version, a known type, that type's length and a matching CRC, otherwise the parser moves on by one
byte. Nothing is allocated per frame beyond the tuple ``struct.unpack_from`` returns.
"""

from __future__ import annotations

import enum
import struct
import zlib

SYNC = b"\xa5\x5a"
VERSION = 1
HEADER = struct.Struct("<2sBBBH")    # sync, length, version, type, seq
CRC = struct.Struct("<I")
SEQ_MODULUS = 1 << 16


class MsgType(enum.IntEnum):
    SAMPLE = 1       # bridge -> host, one per bridge tick
    COMMAND = 2      # host -> bridge, one per control cycle
    CONFIG = 3       # host -> bridge; the bridge echoes it back as its acknowledgement
    HEARTBEAT = 4    # either way, when there is nothing else to send
    FAULT = 5        # bridge -> host: the bridge detected a problem of its own


PAYLOADS: dict[MsgType, struct.Struct] = {
    # time_us, encoder 1, encoder 2 (raw counters), strain gauge 1, 2 (raw ADC), joint DP, IE (counts),
    # digital inputs, bridge status, seq of the last command the bridge applied
    MsgType.SAMPLE: struct.Struct("<QIIiiiiBBH"),
    # set value 1, 2 (codes), digital outputs, seq of the newest sample the host has
    MsgType.COMMAND: struct.Struct("<iiBH"),
    # rate_hz, watchdog_us, counter_bits, set-value modes, safe (zero-current) code 1, 2
    MsgType.CONFIG: struct.Struct("<HIBBii"),
    # state, uptime_ms
    MsgType.HEARTBEAT: struct.Struct("<BI"),
    # fault code, detail
    MsgType.FAULT: struct.Struct("<BH"),
}

# The longest command watchdog a bridge accepts (serial.watchdog_s is at most 1 s): a CONFIG asking for
# more (up to 71 min fits the field) would leave the outputs on long after the host is gone.
MAX_WATCHDOG_US = 1_000_000

# SAMPLE.inputs bits
IN_READY_1 = 0x01        # ESCON 1 ready output (electrical level)
IN_READY_2 = 0x02
IN_JOINT_VALID = 0x04    # the joint-encoder fields carry data
# SAMPLE.status bits
ST_WATCHDOG = 0x01       # no valid command within the watchdog time: set values zeroed, enables off
ST_ADC_STALE = 0x02      # a strain-gauge conversion did not finish this tick: the values are old
ST_QUADRATURE = 0x04     # a quadrature decoder saw an illegal transition
ST_CONFIGURED = 0x80     # the bridge runs with a CONFIG from this host
# COMMAND.outputs bits
OUT_ENABLE_1 = 0x01      # ESCON 1 enable line (electrical level)
OUT_ENABLE_2 = 0x02
# CONFIG.modes bits
MODE_PWM_1 = 0x01        # ESCON 1 set value as PWM duty (else analog)
MODE_PWM_2 = 0x02
# FAULT codes
FAULT_BAD_CONFIG = 1     # detail: index of the offending CONFIG field
FAULT_INTERNAL = 2       # detail: the bridge's own error number (ADC, DAC, clock)

MAX_PAYLOAD = max(s.size for s in PAYLOADS.values())
MAX_FRAME = HEADER.size + MAX_PAYLOAD + CRC.size
_SIZE_BY_TYPE = [-1] * 256
for _t, _s in PAYLOADS.items():
    _SIZE_BY_TYPE[_t] = _s.size


def frame_size(mtype: MsgType) -> int:
    return HEADER.size + PAYLOADS[mtype].size + CRC.size


def set_value_modes(mode_1: str, mode_2: str) -> int:
    """CONFIG.modes for the two amplifiers' set-value inputs ('analog' or 'pwm')."""
    return (MODE_PWM_1 if mode_1 == "pwm" else 0) | (MODE_PWM_2 if mode_2 == "pwm" else 0)


def crc32(data: bytes | bytearray | memoryview) -> int:
    """The frame CRC: CRC-32/ISO-HDLC (zlib.crc32)."""
    return zlib.crc32(data)


def encode_frame(mtype: MsgType, seq: int, *fields: int) -> bytes:
    """One frame as bytes (allocates; for tests and tools)."""
    buf = bytearray(frame_size(mtype))
    _pack(buf, memoryview(buf), mtype, seq, fields)
    return bytes(buf)


def _pack(buf: bytearray, view: memoryview, mtype: MsgType, seq: int, fields: tuple) -> None:
    payload = PAYLOADS[mtype]
    HEADER.pack_into(buf, 0, SYNC, payload.size, VERSION, mtype, seq % SEQ_MODULUS)
    payload.pack_into(buf, HEADER.size, *fields)
    end = HEADER.size + payload.size
    CRC.pack_into(buf, end, zlib.crc32(view[2:end]))


class FrameWriter:
    """Packs outgoing frames into one preallocated buffer per type and numbers them."""

    def __init__(self) -> None:
        self.seq = 0
        self._bufs = {t: bytearray(frame_size(t)) for t in MsgType}
        self._views = {t: memoryview(b) for t, b in self._bufs.items()}

    def frame(self, mtype: MsgType, *fields: int) -> bytearray:
        """The next frame of ``mtype`` (valid until the next call for the same type)."""
        buf = self._bufs[mtype]
        _pack(buf, self._views[mtype], mtype, self.seq, fields)
        self.seq = (self.seq + 1) % SEQ_MODULUS
        return buf


class StreamParser:
    """Finds valid frames in a byte stream fed in arbitrary pieces.

    Usage: ``feed(data)``, then call ``next_frame()`` until it returns None. For each frame it sets
    ``mtype``, ``seq`` and ``offset`` (of the payload in ``buf``); decode with
    ``PAYLOADS[mtype].unpack_from(parser.buf, parser.offset)`` before the next ``feed``.
    Counters: ``frames`` valid frames, ``crc_errors`` well-formed headers whose CRC failed,
    ``discarded`` bytes skipped while searching for a frame.
    """

    def __init__(self, capacity: int = 8192):
        self.buf = bytearray(capacity)
        self.view = memoryview(self.buf)
        self.capacity = capacity
        self.start = 0          # first unparsed byte
        self.end = 0            # one past the last byte fed
        self.mtype = 0
        self.seq = 0
        self.offset = 0
        self.frames = 0
        self.crc_errors = 0
        self.discarded = 0

    def feed(self, data: bytes | bytearray | memoryview) -> None:
        """Append received bytes. If the buffer would overflow, the oldest bytes are dropped."""
        n = len(data)
        if n > self.capacity:
            self.discarded += self.end - self.start + n - self.capacity
            data = memoryview(data)[n - self.capacity:]
            n = self.capacity
            self.start = self.end = 0
        elif self.end + n > self.capacity:
            self._compact()
            over = self.end + n - self.capacity
            if over > 0:
                self.discarded += over
                self.start += over
                self._compact()
        self.buf[self.end:self.end + n] = data
        self.end += n

    def space(self) -> int:
        """Bytes that can be fed without dropping any buffered ones."""
        return self.capacity - (self.end - self.start)

    def _compact(self) -> None:
        n = self.end - self.start
        if self.start:
            self.buf[0:n] = self.buf[self.start:self.end]
        self.start, self.end = 0, n

    def next_frame(self) -> bool:
        """Advance to the next valid frame; False when the buffered bytes hold no complete one."""
        buf = self.buf
        hs = HEADER.size
        while True:
            start, end = self.start, self.end
            if end - start < hs:
                return False
            i = buf.find(SYNC, start, end)
            if i < 0:
                keep = 1 if buf[end - 1] == SYNC[0] else 0   # a sync may straddle the next feed
                self.discarded += end - keep - start
                self.start = end - keep
                return False
            if i > start:
                self.discarded += i - start
                self.start = start = i
            if end - start < hs:
                return False
            length = buf[start + 2]
            mtype = buf[start + 4]
            if buf[start + 3] != VERSION or _SIZE_BY_TYPE[mtype] != length:
                self.discarded += 1
                self.start = start + 1
                continue
            crc_at = start + hs + length
            if end < crc_at + 4:
                return False
            if zlib.crc32(self.view[start + 2:crc_at]) != CRC.unpack_from(buf, crc_at)[0]:
                self.crc_errors += 1
                self.discarded += 1
                self.start = start + 1
                continue
            self.mtype = mtype
            self.seq = buf[start + 5] | (buf[start + 6] << 8)
            self.offset = start + hs
            self.start = crc_at + 4
            self.frames += 1
            return True
