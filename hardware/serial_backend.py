"""The serial backend: the ESCON amplifiers and the sensors behind a microcontroller bridge (pyserial).

The bridge owns the 1 kHz clock: it samples encoders, strain gauges and ready lines every tick and
sends a SAMPLE; it applies the newest COMMAND (set-value codes, enables) and zeroes its outputs when
no valid command arrives within its watchdog time (docs/serial-protocol.md).

Per cycle ``read`` drains the port into a preallocated parser, waits at most ``serial.sample_wait_s``
(less than one period) for a new sample if none is there yet, and converts the newest sample into
the frame. ``write`` packs one COMMAND into a preallocated buffer. If the loop did not call
``write`` since the last ``read`` (not active), ``read`` sends zero set values with the enables as
they are, so the bridge sees one command per cycle and its watchdog stays fed.

Faults (``frame.faults``; counts in :meth:`SerialBackend.counters`):

- CRC_ERROR: a corrupted frame was dropped this cycle.
- SEQUENCE_GAP: bridge frames were lost (the bridge numbers every frame it sends).
- STALE_SAMPLE: the sample did not advance in bridge time (hung acquisition) or the bridge flags
  a strain-gauge conversion as old.
- LINK_LOST: no new sample for ``serial.link_timeout_s``, or the port failed.
- AMP_NOT_READY, STRAIN_GAUGE_RAIL, ENCODER_FAULT (stuck counter or a quadrature error reported by
  the bridge), DEVICE_FAULT (the bridge's watchdog tripped or it sent a FAULT frame).

A cycle without a new sample keeps the previous values and ``seq``; the daemon's safety counts such
cycles (``safety.stale_cycles``) and the link timeout ends them.
"""

from __future__ import annotations

import math
import time
from typing import Protocol

from ankle_rt.backend import Backend, BackendError, BackendFault, SensorFrame, load_by_name
from ankle_rt.clock import Clock
from ankle_rt.config import Config
from hardware.config_values import config_error, required
from hardware.escon import enable_outputs, escon_amplifiers
from hardware.sensors import JointEncoders, MotorEncoders, StrainGauges, StuckEncoderDetector
from hardware.serial_protocol import (IN_JOINT_VALID, IN_READY_1, IN_READY_2, OUT_ENABLE_1, OUT_ENABLE_2,
                                      PAYLOADS, SEQ_MODULUS, ST_ADC_STALE, ST_QUADRATURE, ST_WATCHDOG,
                                      FrameWriter, MsgType, StreamParser, frame_size, set_value_modes)

# serial.emulator: lockstep opens the bench's in-process emulator, named here and imported only then:
# the driver never imports the emulators (they need the simulator, which a prosthesis install
# does not use).
LOCKSTEP_EMULATOR = "hardware.emulators.serial_emulator:open_lockstep"
MAX_LINK_LOAD = 0.70          # share of the baud rate the 1 kHz sample stream may use
BITS_PER_BYTE = 10            # UART: start + 8 data + stop
SAMPLE = PAYLOADS[MsgType.SAMPLE]
SAMPLE_FRAME = frame_size(MsgType.SAMPLE)


def link_load(cfg: Config) -> float:
    """Share of ``serial.baudrate`` the bridge's samples use at the control rate (the busier direction)."""
    bits = frame_size(MsgType.SAMPLE) * BITS_PER_BYTE * cfg["controller"]["rate_hz"]
    return bits / cfg["serial"]["baudrate"]


class SerialPort(Protocol):
    """What the backend uses of a pyserial port (``LockstepLink`` offers the same)."""

    @property
    def in_waiting(self) -> int: ...

    def read(self, size: int = 1) -> bytes: ...

    def write(self, data: bytes | bytearray) -> int | None: ...

    def close(self) -> None: ...


class SerialBackend(Backend):
    name = "serial"

    @property
    def simulated_plant(self) -> bool:
        """True only with the in-process lockstep emulator this backend started itself."""
        return self.emulator is not None

    def __init__(self, cfg: Config, clock: Clock, port: SerialPort | None = None):
        """``port``: an open pyserial-like port (tests); default: ``serial.port``, or the in-process
        lockstep emulator when ``serial.emulator`` is ``lockstep``."""
        super().__init__(cfg, clock)
        s = cfg["serial"]
        rate = cfg["controller"]["rate_hz"]
        self.period_ns = round(1e9 / rate)
        load = link_load(cfg)
        if load > MAX_LINK_LOAD:
            raise config_error(cfg, "serial.baudrate", f"{s['baudrate']} bit/s is too slow: the {rate} Hz samples "
                               f"({SAMPLE_FRAME} bytes) would use {load:.0%} of it (limit {MAX_LINK_LOAD:.0%})")
        if s["sample_wait_s"] * 1e9 >= self.period_ns:
            raise config_error(cfg, "serial.sample_wait_s", f"must be shorter than one period ({1.0 / rate:g} s)")
        for key in ("link_timeout_s", "watchdog_s"):      # one late sample or command must not trip them
            if s[key] * 1e9 < 2 * self.period_ns:
                raise config_error(cfg, f"serial.{key}", f"must be at least two periods ({2.0 / rate:g} s), "
                                   f"got {s[key]:g}")
        self.amps = escon_amplifiers(cfg)
        self.encoders = MotorEncoders.from_config(cfg)
        self.gauges = StrainGauges.from_config(cfg)
        self.joints = JointEncoders.from_config(cfg)
        self.stuck = StuckEncoderDetector.from_config(cfg, 1.0 / rate)
        self.link_timeout_ns = round(s["link_timeout_s"] * 1e9)
        if port is None:
            if s["emulator"] == "lockstep":
                port = load_by_name(LOCKSTEP_EMULATOR)(cfg)
            else:
                port = self._open(required(cfg, "serial.port", "the bridge's serial device"), s)
        self.port = port
        self.emulator = getattr(port, "emulator", None)     # in process: serviced by our own calls
        self.port_name = s["port"] if self.emulator is None else "lockstep emulator"
        self.parser = StreamParser()
        self.writer = FrameWriter()
        self.active = False
        self.commanded = True        # the CONFIG exchange stands for the first cycle's command
        self.sent = [0.0, 0.0]       # A, the quantised currents of the last command
        self.zero_codes = (self.amps[0].zero_code, self.amps[1].zero_code)
        self.disabled = enable_outputs(self.amps, (OUT_ENABLE_1, OUT_ENABLE_2), False)
        self.enabled = enable_outputs(self.amps, (OUT_ENABLE_1, OUT_ENABLE_2), True)
        self.latest: tuple | None = None     # fields of the newest sample, not yet converted
        self.last_frame_seq = -1             # bridge frame numbering (all types)
        self.sample_count = 0                # unwrapped frame number of the newest sample
        self.last_time_us = -1
        self.last_sample_ns = clock.now_ns()
        self.faults = BackendFault.NONE         # this cycle's, gathered while reading
        self.cycle_faults = BackendFault.NONE   # from writes between two reads
        self.link_down = False
        self.count = dict(crc_errors=0, frames_lost=0, stale_samples=0, cycles_without_sample=0,
                          link_lost=0, port_errors=0, device_faults=0, watchdog_trips=0, amp_not_ready=0,
                          strain_gauge_rail=0, encoder_faults=0, samples=0, seq_resyncs=0)
        self._configure(s)

    # -- configuration (not per cycle: may block up to serial.open_timeout_s) ----------------------
    @staticmethod
    def _open(name: str, s: dict) -> SerialPort:
        import serial

        try:
            # write_timeout=0: pyserial's finite write timeout raises when os.write was merely slow,
            # even after all bytes went out; a 22-byte frame into an empty OS buffer never blocks.
            return serial.serial_for_url(name, baudrate=s["baudrate"], timeout=s["sample_wait_s"],
                                         write_timeout=0)
        except (serial.SerialException, ValueError) as exc:
            raise BackendError(f"serial bridge: cannot open {name}: {exc}") from None

    def _config_fields(self, s: dict) -> tuple[int, ...]:
        return (self.cfg["controller"]["rate_hz"], round(s["watchdog_s"] * 1e6), self.encoders.counter_bits,
                set_value_modes(self.amps[0].mode, self.amps[1].mode), self.zero_codes[0], self.zero_codes[1])

    def _configure(self, s: dict) -> None:
        """Send CONFIG and wait for the bridge's echo of it."""
        fields = self._config_fields(s)
        names = ("controller.rate_hz", "serial.watchdog_s", "encoders.counter_bits", "escon.amplifiers.*.mode")
        self.port.write(self.writer.frame(MsgType.CONFIG, *fields))
        deadline = time.monotonic() + s["open_timeout_s"]
        parser = self.parser
        while time.monotonic() < deadline:
            data = self.port.read(max(1, min(self.port.in_waiting, parser.space())))
            if not data:
                if self.emulator is not None:
                    break                                  # in process: the answer is there or never comes
                continue
            parser.feed(data)
            while parser.next_frame():
                payload = PAYLOADS[parser.mtype].unpack_from(parser.buf, parser.offset)
                if parser.mtype == MsgType.FAULT:
                    field = names[payload[1]] if payload[1] < len(names) else f"field {payload[1]}"
                    raise BackendError(f"serial bridge on {self.port_name} refused its configuration "
                                       f"(fault {payload[0]}: {field} not supported by the bridge)")
                if parser.mtype == MsgType.CONFIG and payload == fields:
                    self.last_frame_seq = parser.seq
                    return
        raise BackendError(f"serial bridge on {self.port_name} did not acknowledge its configuration within "
                           f"{s['open_timeout_s']:g} s (wrong port or baud rate, or another protocol version?)")

    # -- lifecycle -------------------------------------------------------------------------------
    def activate(self) -> None:
        """Enables go on with the next command (zero set values until the loop writes)."""
        self.active = True

    def deactivate(self) -> None:
        """Zero set values and enables off, sent at once."""
        self.active = False
        self._command(self.zero_codes[0], self.zero_codes[1], self.disabled)
        self.sent[0] = self.sent[1] = 0.0

    def close(self) -> None:
        try:
            self.deactivate()
        finally:
            self.port.close()

    # -- per cycle -------------------------------------------------------------------------------
    def write(self, current_1: float, current_2: float) -> None:
        if not self.active:
            current_1 = current_2 = 0.0
        a1, a2 = self.amps
        c1 = a1.code(current_1)
        c2 = a2.code(current_2)
        self.sent[0] = a1.current(c1)
        self.sent[1] = a2.current(c2)
        self._command(c1, c2, self.enabled if self.active else self.disabled)

    def _command(self, code_1: int, code_2: int, outputs: int) -> None:
        self.commanded = True
        frame = self.writer.frame(MsgType.COMMAND, code_1, code_2, outputs, self.sample_count % SEQ_MODULUS)
        try:
            sent = self.port.write(frame)
        except Exception:          # pyserial raises SerialException/OSError when the device vanishes
            sent = -1
        if sent != len(frame):     # gone, or the OS buffer is full: the link cannot carry the commands
            self.count["port_errors"] += 1
            self.cycle_faults |= BackendFault.LINK_LOST

    def read(self, frame: SensorFrame) -> None:
        if not self.commanded:     # keep one command per cycle: zero set values, enables unchanged
            self._command(self.zero_codes[0], self.zero_codes[1], self.enabled if self.active else self.disabled)
            self.sent[0] = self.sent[1] = 0.0
        self.commanded = False
        self.faults = self.cycle_faults      # gathered while draining
        self.cycle_faults = BackendFault.NONE
        crc_before = self.parser.crc_errors
        try:
            new = (self._drain(self.port.in_waiting)
                   or self._drain(max(1, SAMPLE_FRAME - (self.parser.end - self.parser.start))))
        except Exception:          # the port failed (device unplugged): report, never raise in the loop
            self.count["port_errors"] += 1
            self.faults |= BackendFault.LINK_LOST
            new = False
        if self.parser.crc_errors != crc_before:
            self.count["crc_errors"] += self.parser.crc_errors - crc_before
            self.faults |= BackendFault.CRC_ERROR
        now = self.clock.now_ns()
        if new:
            self.last_sample_ns = now
            self.link_down = False
            self._convert(frame)
        else:
            self.count["cycles_without_sample"] += 1
            if now - self.last_sample_ns >= self.link_timeout_ns:
                if not self.link_down:
                    self.count["link_lost"] += 1
                    self.link_down = True
                self.faults |= BackendFault.LINK_LOST
        frame.faults = self.faults

    def _drain(self, n: int) -> bool:
        """Read up to ``n`` bytes (the port's timeout bounds the wait) and handle every complete
        frame; True if a new sample arrived."""
        port, parser = self.port, self.parser
        new = False
        while parser.next_frame():                    # frames left from an earlier read
            new = self._on_frame() or new
        while n > 0:
            data = port.read(min(n, parser.space()))
            if not data:
                break
            n -= len(data)
            parser.feed(data)
            while parser.next_frame():
                new = self._on_frame() or new
        return new

    def _on_frame(self) -> bool:
        parser = self.parser
        seq = parser.seq
        step = (seq - self.last_frame_seq) % SEQ_MODULUS if self.last_frame_seq >= 0 else 1
        if step == 0:
            return False                              # the same frame again: ignore
        if step > SEQ_MODULUS // 2:                   # numbering went back: the bridge restarted, or half
            self.count["seq_resyncs"] += 1            # the sequence space was lost; take it from here
            self.faults |= BackendFault.SEQUENCE_GAP
            step = 1
        elif step > 1:
            self.count["frames_lost"] += step - 1
            self.faults |= BackendFault.SEQUENCE_GAP
        self.last_frame_seq = seq
        mtype = parser.mtype
        if mtype == MsgType.SAMPLE:
            self.latest = SAMPLE.unpack_from(parser.buf, parser.offset)
            self.sample_count += step
            return True
        if mtype == MsgType.FAULT:
            self.count["device_faults"] += 1
            self.faults |= BackendFault.DEVICE_FAULT
        return False

    def _convert(self, frame: SensorFrame) -> None:
        """The newest sample into ``frame``, adding the faults it shows to ``self.faults``."""
        time_us, e1, e2, s1, s2, j1, j2, inputs, status, _cmd_seq = self.latest
        faults = self.faults
        if time_us <= self.last_time_us or status & ST_ADC_STALE:
            self.count["stale_samples"] += 1
            faults |= BackendFault.STALE_SAMPLE
        self.last_time_us = time_us
        frame.t = time_us * 1e-6
        frame.seq = self.sample_count
        self.count["samples"] += 1
        self.encoders.convert(e1, e2, frame.motor_pos)
        if self.gauges.convert(s1, s2, frame.sg_torque):
            self.count["strain_gauge_rail"] += 1
            faults |= BackendFault.STRAIN_GAUGE_RAIL
        if self.joints is not None:
            if inputs & IN_JOINT_VALID:
                self.joints.convert(j1, j2, frame.ankle_pos)
            else:
                frame.ankle_pos[0] = frame.ankle_pos[1] = math.nan
        r1 = self.amps[0].is_ready(bool(inputs & IN_READY_1))
        r2 = self.amps[1].is_ready(bool(inputs & IN_READY_2))
        frame.amp_ready[0] = r1
        frame.amp_ready[1] = r2
        if not (r1 and r2):
            self.count["amp_not_ready"] += 1
            faults |= BackendFault.AMP_NOT_READY
        if status & ST_WATCHDOG:
            self.count["watchdog_trips"] += 1
            faults |= BackendFault.DEVICE_FAULT
        if (self.stuck.update(self.encoders.moved, self.sent[0], self.sent[1], frame.sg_torque[0], frame.sg_torque[1])
                or status & ST_QUADRATURE):
            self.count["encoder_faults"] += 1
            faults |= BackendFault.ENCODER_FAULT
        self.faults = faults

    def counters(self) -> dict[str, int]:
        out = dict(self.count)
        out["bytes_discarded"] = self.parser.discarded
        out["frames"] = self.parser.frames
        return out
