"""The bridge firmware's protocol and safety logic in Python: the reference the C core
(hardware/firmware/core/bridge.c) implements, with the same interface as its ctypes wrapper
(``native_core.NativeCore``), so that the emulator's plant side drives either one.

Per tick the board calls :meth:`PythonCore.receive` / :meth:`PythonCore.poll` with the received
bytes (COMMAND updates the outputs, CONFIG reconfigures, HEARTBEAT is answered), :meth:`tick` (the
command watchdog), then :meth:`sample` with the sensors it latched; :meth:`take_tx` hands out the
frames to send (docs/serial-protocol.md, docs/firmware.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from hardware.serial_protocol import (FAULT_BAD_CONFIG, MAX_WATCHDOG_US, OUT_ENABLE_1, OUT_ENABLE_2, PAYLOADS,
                                      ST_ADC_STALE, ST_CONFIGURED, ST_QUADRATURE, ST_WATCHDOG, FrameWriter, MsgType, StreamParser)

BRIDGE_STATE_RUNNING = 2
PARSER_CAPACITY = 256     # as BP_PARSER_CAPACITY in frame.h


@dataclass(frozen=True)
class BridgeInputs:
    """The sensors latched at one tick (``bridge_inputs`` in bridge.h)."""
    time_us: int            # board time of the latch; SAMPLE.time_us counts from the CONFIG's
    enc_1: int
    enc_2: int
    sg_1: int
    sg_2: int
    joint_1: int
    joint_2: int
    inputs: int             # SAMPLE.inputs: ready lines, joint encoders valid
    status: int             # board flags: ST_ADC_STALE, ST_QUADRATURE

    def fields(self) -> tuple[int, ...]:
        return (self.time_us, self.enc_1, self.enc_2, self.sg_1, self.sg_2, self.joint_1, self.joint_2,
                self.inputs, self.status)


class PythonCore:
    """The bridge's protocol and safety logic (``bridge.h``) in Python.

    ``counter_bits`` (16/32) and ``modes`` are what the board is wired for, ``enable_off`` the enable
    line levels (bit 0/1) that disable each ESCON, ``code_range`` each output's (min, max) code,
    ``reset_codes`` what the outputs hold until the first CONFIG."""

    def __init__(self, rate_hz: int, counter_bits: int, modes: int, enable_off: int,
                 code_range: Sequence[tuple[int, int]], reset_codes: Sequence[int]):
        self.rate_hz = rate_hz
        self.period_us = round(1e6 / rate_hz)
        self.counter_bits = counter_bits
        self.modes = modes
        self.enable_off = enable_off
        self.code_range = tuple(code_range)
        self.parser = StreamParser(PARSER_CAPACITY)
        self.writer = FrameWriter()
        self.output = bytearray()
        self.configured = False
        self.watchdog_tripped = False
        self.watchdog_ticks = 1
        self.since_command = 0
        self.config_time_us = 0
        self.safe_codes = list(reset_codes)
        self.codes = list(reset_codes)
        self.enables = enable_off
        self.last_command_seq = 0
        self.latched = BridgeInputs(0, 0, 0, 0, 0, 0, 0, 0, 0).fields()
        self.commands = 0

    @property
    def crc_errors(self) -> int:
        return self.parser.crc_errors

    def _clamp(self, k: int, code: int) -> int:
        lo, hi = self.code_range[k]
        return lo if code < lo else (hi if code > hi else code)

    def _send(self, mtype: MsgType, *fields: int) -> None:
        self.output += self.writer.frame(mtype, *fields)

    def _go_safe(self) -> None:
        self.codes[0], self.codes[1] = self.safe_codes
        self.enables = self.enable_off

    def outputs_enabled(self) -> bool:
        """Whether an enable line is on (the watchdog has something to switch off)."""
        return bool((self.enables ^ self.enable_off) & (OUT_ENABLE_1 | OUT_ENABLE_2))

    def trip_watchdog(self) -> None:
        """Safe codes, enables off, status bit 0 until the next valid command."""
        self._go_safe()
        self.watchdog_tripped = True

    def restart(self) -> None:
        """After a hardware-watchdog reset with the state retained: buffers cleared, outputs safe,
        the watchdog status bit set if configured."""
        self.parser = StreamParser(PARSER_CAPACITY)
        self.output.clear()
        self._go_safe()
        self.since_command = 0
        self.watchdog_tripped = self.configured

    def receive(self, data: bytes | memoryview) -> int:
        """Take up to len(data) received bytes; how many (the rest after :meth:`poll` made room)."""
        n = min(len(data), self.parser.space())
        self.parser.feed(data[:n])
        return n

    def poll(self) -> int:
        """Act on the next complete frame: its type, or 0."""
        parser = self.parser
        if not parser.next_frame():
            return 0
        mtype = parser.mtype
        fields = PAYLOADS[mtype].unpack_from(parser.buf, parser.offset)
        if mtype == MsgType.CONFIG:
            self._configure(fields)
        elif mtype == MsgType.COMMAND and self.configured:
            self.commands += 1
            self.codes[0] = self._clamp(0, fields[0])
            self.codes[1] = self._clamp(1, fields[1])
            self.enables = fields[2] & (OUT_ENABLE_1 | OUT_ENABLE_2)
            self.last_command_seq = parser.seq
            self.since_command = 0
            self.watchdog_tripped = False
        elif mtype == MsgType.HEARTBEAT:
            self._send(MsgType.HEARTBEAT, BRIDGE_STATE_RUNNING if self.configured else 0,
                       (self.latched[0] // 1000) & 0xFFFFFFFF)
        return mtype

    def _configure(self, fields: tuple) -> None:
        rate_hz, watchdog_us, counter_bits, modes, safe_1, safe_2 = fields
        for index, ok in enumerate((rate_hz == self.rate_hz, 0 < watchdog_us <= MAX_WATCHDOG_US, counter_bits == self.counter_bits,
                                    modes == self.modes)):
            if not ok:   # the board's hardware cannot do what the host asks (field index in detail)
                self._send(MsgType.FAULT, FAULT_BAD_CONFIG, index)
                return
        self.watchdog_ticks = max(1, math.ceil(watchdog_us / self.period_us))
        self.config_time_us = self.latched[0]          # sample time counts from the configuration
        self.safe_codes[0], self.safe_codes[1] = self._clamp(0, safe_1), self._clamp(1, safe_2)
        self._go_safe()
        self.watchdog_tripped = False
        self.since_command = 0
        self.configured = True
        self._send(MsgType.CONFIG, *fields)            # the acknowledgement echoes the configuration
        self._send_sample()                            # this tick's sample, latched already

    def tick(self) -> None:
        """The command watchdog: no valid command for watchdog_ticks while an enable is on trips it."""
        if not self.configured:
            return
        self.since_command += 1
        if self.since_command > self.watchdog_ticks and self.outputs_enabled():
            self.trip_watchdog()

    def sample(self, fields: Sequence[int]) -> None:
        """Latch this tick's sensors (:meth:`BridgeInputs.fields`) and, once configured, send them."""
        self.latched = tuple(fields)
        if self.configured:
            self._send_sample()

    def _send_sample(self) -> None:
        time_us, e1, e2, s1, s2, j1, j2, inputs, board_status = self.latched
        status = (ST_CONFIGURED | (ST_WATCHDOG if self.watchdog_tripped else 0)
                  | (board_status & (ST_ADC_STALE | ST_QUADRATURE)))
        self._send(MsgType.SAMPLE, time_us - self.config_time_us, e1, e2, s1, s2, j1, j2, inputs, status,
                   self.last_command_seq)

    def take_tx(self) -> bytes:
        out = bytes(self.output)
        self.output.clear()
        return out
