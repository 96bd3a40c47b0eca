"""The microcontroller bridge, emulated: the simulated plant behind the serial protocol.

:class:`BridgeEmulator` is the bridge board: the simulated plant behind its sensors and outputs,
and a firmware core on top: ``core="python"`` (``bridge_core.PythonCore``, the reference) or
``core="c"`` (the firmware's own C core, compiled natively: ``native_core.NativeCore``). The plant
side (sensors, amplifiers, injected faults) is this one piece of code for both, so a test that passes
against one core and fails against the other has found a bug in one of them.

It takes received bytes (:meth:`~BridgeEmulator.receive`) and queues the bytes it answers with
(:meth:`~BridgeEmulator.take_output`). Lockstep: a COMMAND frame that answers the newest sample steps
the plant one tick (with the amplifier currents of the commanded set values, as the ESCONs configured
in ``escon:`` drive them) and queues the next SAMPLE, so the host's commands pace the plant and results
do not depend on machine load. A real bridge (and ``--free-run``) ticks on its own 1 kHz clock
instead; :meth:`~BridgeEmulator.tick` is that tick.

:class:`LockstepLink` puts an emulator on the master side of a pty pair (raw mode) and hands the
host a pyserial port on the slave side, wrapped so that every ``write`` services the emulator at
once and every read first waits until the emulator's answer has crossed the pty. The backend's own
``write``/``read`` therefore drive the emulator synchronously in one thread: no second thread
competes for the GIL and nothing depends on scheduling (docs/serial-protocol.md, "Emulator").

Fault injection (:data:`FAULTS`, by name, on/off or scheduled in plant time): dropped samples, a
corrupted CRC, line noise (random bytes between frames, random bit flips), a stuck encoder, a strain
gauge at its rail, an ESCON dropping ready, a frozen bridge (silent, commands ignored, outputs held
until its hardware watchdog resets it: outputs safe) and a stale bridge (repeats its last sample).
"""

from __future__ import annotations

import argparse
import math
import os
import random
import select
import signal
import sys
import time
import tty
from typing import TYPE_CHECKING

from ankle_rt.config import Config, ConfigError
from hardware.emulators.bridge_core import BridgeInputs, PythonCore
from hardware.escon import enable_outputs, escon_amplifiers
from hardware.emulators.fault_schedule import ScheduledFault, parse_schedule
from hardware.emulators.presence import Presence, until_text
from hardware.sensors import JointEncoders, MotorEncoders, StrainGauges
from hardware.serial_protocol import (HEADER, CRC, IN_JOINT_VALID, IN_READY_1, IN_READY_2, OUT_ENABLE_1,
                                      OUT_ENABLE_2, MsgType, StreamParser, set_value_modes)
from sim_backend.plant import SimulatedPlant

if TYPE_CHECKING:
    from hardware.emulators.native_core import NativeCore

FAULTS = ("drop", "corrupt", "noise", "stuck_encoder_1", "stuck_encoder_2", "sg_rail_1", "sg_rail_2",
          "not_ready_1", "not_ready_2", "frozen", "stale")
CORES = ("python", "c")
NOISE_BYTES = 24          # "noise": up to this many random bytes before each sample ...
NOISE_FLIP_EVERY = 8      # ... and one random bit flipped in one sample in this many (on average)
SETTLE_TIMEOUT_S = 5.0   # LockstepLink: longest wait for bytes to cross the pty (a safety net only)


def make_core(name: str, rate_hz: int, counter_bits: int, modes: int, amps: tuple) -> PythonCore | NativeCore:
    """The firmware core ``name`` (one of :data:`CORES`) for a board at ``rate_hz`` with
    ``counter_bits`` encoder counters, CONFIG set-value ``modes`` and these amplifiers' wiring."""
    if name not in CORES:
        raise ValueError(f"unknown bridge core {name!r} (expected one of: {', '.join(CORES)})")
    args = (rate_hz, counter_bits, modes, enable_outputs(amps, (OUT_ENABLE_1, OUT_ENABLE_2), False),
            [(a.codec.code_min, a.codec.code_max) for a in amps], [a.zero_code for a in amps])
    if name == "c":
        from hardware.emulators.native_core import NativeCore

        return NativeCore(*args)
    return PythonCore(*args)


class BridgeEmulator:
    """The bridge board with :class:`SimulatedPlant` behind it and a firmware core (``core``: one of
    :data:`CORES`) on top. ``cfg`` is the device's truth: plant parameters and the ESCON Studio
    settings, encoder and strain-gauge wiring it emulates."""

    def __init__(self, cfg: Config, *, lockstep: bool = True, enable_delay_s: float = 0.0, core: str = "python"):
        """``enable_delay_s``: how long an ESCON takes to follow its enable input (up to 8 ms on the
        ESCON 50/5's digital inputs; 0: at once). The set value acts at once either way."""
        self.plant = SimulatedPlant(cfg, getattr(cfg, "source", "config"))
        self.amps = escon_amplifiers(cfg)
        self.encoders = MotorEncoders.from_config(cfg)
        self.gauges = StrainGauges.from_config(cfg)
        self.joints = JointEncoders.from_config(cfg)
        bits = cfg["strain_gauges"]["adc_bits"]
        self.adc_min, self.adc_max = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
        self.rate_hz = cfg["controller"]["rate_hz"]
        self.period_us = round(1e6 / self.rate_hz)
        self.modes = set_value_modes(self.amps[0].mode, self.amps[1].mode)
        self.core_name = core
        self.core = make_core(core, self.rate_hz, cfg["encoders"]["counter_bits"], self.modes, self.amps)
        self.lockstep = lockstep
        self.output = bytearray()
        self.enable_delay_ticks = round(enable_delay_s * self.rate_hz)
        self.amp_enabled = [False, False]     # what the ESCONs follow, enable_delay_ticks behind the lines
        self._enable_countdown = [self.enable_delay_ticks, self.enable_delay_ticks]
        self.awaiting_command = False
        self.hung_ticks = 0                   # "frozen": ticks the firmware has not run
        self._hung_parser = StreamParser()    # "frozen" in lockstep: each command is still a period
        self.active: set[str] = set()
        self.schedule: list[ScheduledFault] = []
        self._stuck_counts: list[int | None] = [None, None]
        self.samples_dropped = 0
        self.samples_corrupted = 0
        self.watchdog_resets = 0                        # "frozen": resets by the hardware watchdog
        self.bytes_lost = 0                             # standalone: output the link could not take
        self.rng = random.Random(cfg["sim"]["seed"])   # line noise, reproducible
        self.inputs: BridgeInputs | None = None        # latched at the last tick (the sensor noise draws
                                                        # from the plant's generator: once per tick)

    # -- what the core drives ----------------------------------------------------------------------
    @property
    def codes(self) -> list[int]:
        """The set-value codes at the outputs now."""
        return self.core.codes

    @property
    def commands(self) -> int:
        return self.core.commands

    def enable_level(self, k: int) -> bool:
        """The electrical level of ESCON ``k``'s enable line (0 or 1) now."""
        return bool(self.core.enables & (OUT_ENABLE_1, OUT_ENABLE_2)[k])

    @property
    def enable_levels(self) -> list[bool]:
        return [self.enable_level(0), self.enable_level(1)]

    def outputs_enabled(self) -> bool:
        """Whether an enable line is on (the watchdog has something to switch off)."""
        return self.core.outputs_enabled()

    def trip_watchdog(self) -> None:
        """No valid command within the watchdog time: zero set values, enables off, status bit set."""
        self.core.trip_watchdog()

    # -- fault injection -------------------------------------------------------------------------
    def inject(self, name: str, on: bool = True) -> None:
        """Switch an injected fault (one of :data:`FAULTS`) on or off now."""
        if name not in FAULTS:
            raise ValueError(f"unknown fault {name!r} (expected one of: {', '.join(FAULTS)})")
        if on:
            self.active.add(name)
        else:
            self.active.discard(name)
        for k in (0, 1):
            stuck = f"stuck_encoder_{k + 1}" in self.active
            if stuck and self._stuck_counts[k] is None:
                self._stuck_counts[k] = self.plant.encoder_counts()[k]
            elif not stuck:
                self._stuck_counts[k] = None

    def add_schedule(self, spec: str) -> None:
        """``NAME@START[:STOP]`` with times in s of plant time (no STOP: until the end)."""
        self.schedule.append(parse_schedule(spec, FAULTS))

    def _apply_schedule(self) -> None:
        t = self.plant.t
        for name, start, stop in self.schedule:
            on = start <= t < stop
            if on != (name in self.active):
                self.inject(name, on)

    # -- the link ----------------------------------------------------------------------------------
    def receive(self, data: bytes) -> None:
        """Handle received bytes: frames are acted on as they complete (a frozen bridge ignores them)."""
        if "frozen" in self.active:        # the firmware hangs; in lockstep each command is still a period
            self._hung_parser.feed(data)
            while self._hung_parser.next_frame():
                if self._hung_parser.mtype == MsgType.COMMAND and self.lockstep:
                    self.tick()
            return
        core = self.core
        if not core.configured:                     # unconfigured, a board still latches every tick
            self._latch_sensors()                   # (lockstep does not tick it); nothing is sent
        view = memoryview(data)
        while len(view):
            taken = core.receive(bytes(view))
            view = view[taken:]
            handled = False
            while mtype := core.poll():
                handled = True
                self._collect()
                if (mtype == MsgType.COMMAND and core.configured and self.lockstep
                        and self.awaiting_command):   # the first command after a sample
                    self.awaiting_command = False
                    self.tick()
            if not taken and not handled:
                raise RuntimeError("bridge core took no bytes and found no frame")   # cannot happen: a bug

    def take_output(self) -> bytes:
        out = bytes(self.output)
        self.output.clear()
        return out

    def _collect(self) -> None:
        """Move the core's frames onto the link; samples pass the injected link faults."""
        data = self.core.take_tx()
        at = 0
        while at < len(data):
            end = at + HEADER.size + data[at + 2] + CRC.size
            frame = data[at:end]
            if data[at + 4] == MsgType.SAMPLE:
                self._send_sample(frame)
            else:
                self.output += frame
            at = end

    def _send_sample(self, frame: bytes) -> None:
        self.awaiting_command = True
        active = self.active
        if "drop" in active:
            self.samples_dropped += 1
        elif "corrupt" in active:
            self.samples_corrupted += 1
            self.output += frame
            self.output[-1] ^= 0xFF
        elif "noise" in active:
            rng = self.rng
            self.output += rng.randbytes(rng.randrange(NOISE_BYTES + 1))
            start = len(self.output)
            self.output += frame
            if rng.randrange(NOISE_FLIP_EVERY) == 0:
                self.samples_corrupted += 1
                self.output[start + rng.randrange(len(frame))] ^= 1 << rng.randrange(8)
        else:
            self.output += frame

    # -- one bridge tick -------------------------------------------------------------------------
    def amplifier_currents(self) -> tuple[float, float]:
        """A: what the two ESCONs drive now (zero when disabled or in fault)."""
        out = []
        codes = self.core.codes
        for k, amp in enumerate(self.amps):
            enabled = amp.is_enabled(self.enable_level(k)) if self.enable_delay_ticks == 0 else self.amp_enabled[k]
            on = enabled and f"not_ready_{k + 1}" not in self.active
            out.append(amp.current(codes[k]) if on else 0.0)
        return out[0], out[1]

    def _follow_enables(self) -> None:
        """The ESCONs take enable_delay_ticks to follow a change of their enable lines."""
        for k, amp in enumerate(self.amps):
            wanted = amp.is_enabled(self.enable_level(k))
            if wanted == self.amp_enabled[k]:
                self._enable_countdown[k] = self.enable_delay_ticks
            else:
                self._enable_countdown[k] -= 1
                if self._enable_countdown[k] <= 0:
                    self.amp_enabled[k] = wanted
                    self._enable_countdown[k] = self.enable_delay_ticks

    def tick(self) -> None:
        """One period of the bridge's clock: watchdog, plant step, sample.

        A frozen bridge sends nothing and applies no command, but the world goes on: the plant steps
        with the outputs as they were until the independent hardware watchdog (which outlives a
        firmware hang) resets the board after the command watchdog time: outputs safe, and the core,
        its state retained, flags the reset in the status once it runs again."""
        self._apply_schedule()
        core = self.core
        if not core.configured:
            return
        frozen = "frozen" in self.active
        if frozen:
            self.hung_ticks += 1
            if self.hung_ticks == core.watchdog_ticks + 1:
                core.restart()
                self.watchdog_resets += 1
        else:
            self.hung_ticks = 0
            core.tick()
        self._follow_enables()
        self.plant.step(*self.amplifier_currents())
        if not frozen:
            self._latch_sensors()
            self._collect()

    def _latch_sensors(self) -> None:
        """Latch the sensors and hand them to the core (which sends them once configured). Stale:
        the acquisition hangs, the old data and time are handed over again."""
        if self.inputs is None or "stale" not in self.active:
            self.inputs = self._latch()
        self.core.sample(self.inputs.fields())

    def _latch(self) -> BridgeInputs:
        """The board's sensors now, with the injected sensor faults."""
        active = self.active
        plant = self.plant
        c1, c2 = plant.encoder_counts()
        if self._stuck_counts[0] is not None:
            c1 = self._stuck_counts[0]
        if self._stuck_counts[1] is not None:
            c2 = self._stuck_counts[1]
        e1, e2 = self.encoders.raw_from_counts(c1, c2)
        s1, s2 = self.gauges.raw(*plant.strain_gauge_torques(), self.adc_min, self.adc_max)
        if "sg_rail_1" in active:
            s1 = self.adc_max
        if "sg_rail_2" in active:
            s2 = self.adc_max
        inputs = 0
        if self.amps[0].ready_level("not_ready_1" not in active):
            inputs |= IN_READY_1
        if self.amps[1].ready_level("not_ready_2" not in active):
            inputs |= IN_READY_2
        j1 = j2 = 0
        if self.joints is not None:
            j1, j2 = self.joints.raw(*plant.ankle_positions())
            inputs |= IN_JOINT_VALID
        return BridgeInputs(plant.ticks * self.period_us, e1, e2, s1, s2, j1, j2, inputs, 0)


class LockstepLink:
    """A pyserial-like port whose far end is a :class:`BridgeEmulator` on a pty pair (raw mode).

    ``write`` passes the bytes through the pty to the emulator and lets it answer at once;
    ``in_waiting`` and ``read`` first wait until the answer has crossed the pty. The emulator is
    thus serviced from the backend's own calls, deterministically, in the caller's thread.
    """

    def __init__(self, emulator: BridgeEmulator, baudrate: int = 2_000_000):
        import serial

        self.emulator = emulator
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        self.path = os.ttyname(slave)
        self.port = serial.Serial(self.path, baudrate=baudrate, timeout=0)
        os.close(slave)                      # pyserial holds its own descriptor of the slave
        os.set_blocking(master, False)
        self.master = master
        self.pending = 0                     # bytes the emulator sent that the host has not read
        self._backlog = bytearray()          # bytes the pty could not take yet

    # pyserial's interface, as far as the backend uses it
    @property
    def in_waiting(self) -> int:
        self._settle()
        return self.port.in_waiting

    def read(self, size: int = 1) -> bytes:
        self._settle()
        data = self.port.read(size)
        self.pending -= len(data)
        return data

    def write(self, data: bytes | bytearray) -> int:
        n = self.port.write(data)
        self._service(n)
        return n

    def close(self) -> None:
        self.port.close()
        os.close(self.master)

    # the emulator's side
    def _service(self, expected: int) -> None:
        received = bytearray()
        deadline = time.monotonic() + SETTLE_TIMEOUT_S
        while len(received) < expected and time.monotonic() < deadline:
            if select.select([self.master], [], [], SETTLE_TIMEOUT_S)[0]:
                received += os.read(self.master, 65536)
        self.emulator.receive(bytes(received))
        self._backlog += self.emulator.take_output()
        self._flush()

    def _flush(self) -> None:
        while self._backlog:
            try:
                n = os.write(self.master, self._backlog)
            except BlockingIOError:
                return
            del self._backlog[:n]
            self.pending += n

    def _settle(self) -> None:
        self._backlog += self.emulator.take_output()     # e.g. samples of free-running ticks
        self._flush()
        deadline = time.monotonic() + SETTLE_TIMEOUT_S
        while self.port.in_waiting < self.pending and time.monotonic() < deadline:
            select.select([self.port.fileno()], [], [], 0.01)


def open_lockstep(cfg: Config, core: str = "python") -> LockstepLink:
    """The bench in one process: an emulator configured like ``cfg`` (firmware ``core``) behind a pty pair."""
    return LockstepLink(BridgeEmulator(cfg, core=core), cfg["serial"]["baudrate"])


# -- ankle-rt emulate --transport serial ----------------------------------------------------------

def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def run_standalone(cfg: Config, args: argparse.Namespace) -> int:
    """Serve the bridge protocol on a serial device or a new pty until Ctrl-C, SIGTERM or ``--duration``.

    Lockstep (default): the plant steps on each command; the bridge's watchdog runs on wall time (no
    valid command for ``serial.watchdog_s`` zeroes the set values and drops the enables).
    ``--free-run``: the emulator ticks on its own clock at ``controller.rate_hz`` like the real
    bridge, commands only update the outputs, and the watchdog counts ticks.
    """
    free_run = bool(getattr(args, "free_run", False))
    emulator = BridgeEmulator(cfg, lockstep=not free_run, core=getattr(args, "core", "python"))
    try:
        for spec in args.inject:
            emulator.add_schedule(spec)
    except ValueError as exc:
        print(f"ankle-rt emulate: {exc}", file=sys.stderr)
        return 2
    port_name = args.port or cfg["serial"]["port"]
    if not port_name:
        raise ConfigError("no port: give --port PATH or --port pty", getattr(cfg, "source", None), "serial.port")
    if port_name == "pty":
        fd, slave = os.openpty()
        tty.setraw(fd)
        tty.setraw(slave)
        keep_open = slave        # keeps the pty alive between daemon runs
        where = f"{os.ttyname(slave)} (set serial.port to it)"
    else:
        import serial

        try:
            port = serial.Serial(port_name, baudrate=args.baudrate or cfg["serial"]["baudrate"], timeout=0)
        except serial.SerialException as exc:
            print(f"ankle-rt emulate: cannot open {port_name}: {exc}", file=sys.stderr)
            return 1
        keep_open = port
        fd = port.fileno()
        where = port_name
    os.set_blocking(fd, False)
    print(f"emulator: serial bridge on {where}, {'free-running' if free_run else 'lockstep'}, "
          f"{emulator.core_name} core ({until_text(args.duration)})", flush=True)
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        _serve(emulator, fd, cfg, args.duration, free_run)
    except KeyboardInterrupt:
        pass
    finally:
        if isinstance(keep_open, int):
            os.close(keep_open)
        else:
            keep_open.close()
    print(f"emulator: {emulator.plant.ticks} ticks, {emulator.commands} commands, "
          f"{emulator.core.crc_errors} CRC errors received, {emulator.samples_dropped} samples dropped, "
          f"{emulator.samples_corrupted} corrupted, {emulator.bytes_lost} bytes not sent (nobody reading)",
          flush=True)
    return 0


def _serve(emulator: BridgeEmulator, fd: int, cfg: Config, duration_s: float, free_run: bool) -> None:
    period_s = 1.0 / cfg["controller"]["rate_hz"]
    watchdog_s = cfg["serial"]["watchdog_s"]
    now = time.monotonic()
    end = now + duration_s if duration_s else math.inf
    next_tick = now + period_s
    last_command, seen = now, 0
    presence = Presence("commands")
    while now < end:
        wait = max(0.0, next_tick - now) if free_run else 0.001
        if select.select([fd], [], [], wait)[0]:
            try:
                emulator.receive(os.read(fd, 4096))
            except OSError:              # pty: no process has the slave open right now
                time.sleep(0.01)
        now = time.monotonic()
        if free_run and now >= next_tick:
            emulator.tick()
            next_tick = max(next_tick + period_s, now)   # a late tick is not caught up: the clock slips
        elif not free_run:
            if emulator.commands != seen:
                seen, last_command = emulator.commands, now
            elif now - last_command > watchdog_s and emulator.outputs_enabled():
                emulator.trip_watchdog()
        _send(fd, emulator.take_output(), emulator)
        presence.update(emulator.commands, now)


def _send(fd: int, data: bytes, emulator: BridgeEmulator) -> None:
    """Write without blocking; what the OS buffer cannot take is lost, as from a UART with nobody
    listening (a free-running bridge whose host is gone must not hang)."""
    view = memoryview(data)
    while len(view):
        try:
            view = view[os.write(fd, view):]
        except (BlockingIOError, OSError):
            emulator.bytes_lost += len(view)
            return
