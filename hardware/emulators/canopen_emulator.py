"""The CANopen device emulator: the ankle I/O node as a canopen LocalNode with the simulated plant behind it.

The node answers SDO and NMT like the real I/O module (canopen's SdoServer and NmtSlave on the same
EDS) and runs the plant in lockstep with the SYNC: on each SYNC in OPERATIONAL it applies the set
values of the last RPDO (CiA 401 synchronous outputs), steps the plant one control tick (not on the
first SYNC, which marks t = 0), samples the sensors and sends its TPDOs. Outside OPERATIONAL the
outputs hold their error values (set values zero, enables off; 0x6443/0x6444, 0x6206/0x6207).

Physical time is the SYNC count: the plant steps on every SYNC, also while the node is stopped, hung
or bus-off (then with the outputs it holds), and the heartbeat runs on the same clock in lockstep.

No threads: :meth:`CanopenEmulator.service` handles whatever is waiting on the emulator's bus.
- In tests, :class:`LockstepBus` gives the backend a bus whose ``send`` lets the emulator handle the
  frame before returning, so emulator and backend run in one thread, deterministically
  (python-can's ``virtual`` bus delivers in-process).
- Standalone (``ankle-rt emulate --transport canopen``, the bench's second computer),
  :meth:`CanopenEmulator.serve` blocks on the bus and sends heartbeats on the real clock.

Fault injection (:class:`InjectedFaults`): dropped TPDOs, a stuck encoder, a strain gauge at its rail,
an amplifier dropping ready, a frozen node (no heartbeat, no PDOs, no answers) and a bus-off.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass

import can
import canopen

from ankle_rt.config import Config
from hardware.can_hints import describe_open_error
from hardware.canopen_pdo import (COUNTER_1, COUNTER_2, DIGITAL_IN, DIGITAL_OUT, ENABLE_BITS, HEARTBEAT_BASE,
                                  READY_BITS, SET_VALUE_1, SET_VALUE_2, STRAIN_1, STRAIN_2, SYNC_COB_ID,
                                  ANALOG_CODE_SHIFT, PdoLayout, analog_codec, compile_pdo, counter_bits)
from hardware.escon import escon_amplifiers
from hardware.emulators.fault_schedule import ScheduledFault, parse_schedule
from hardware.emulators.presence import Presence, until_text
from hardware.sensors import MotorEncoders, StrainGauges
from sim_backend.plant import SimulatedPlant

NMT_PRE_OPERATIONAL, NMT_OPERATIONAL = 0x7F, 0x05
NMT_RESET_NODE = 0x81         # NMT command (0x82: reset communication)
EMCY_BASE = 0x80
SDO_RX_BASE = 0x600           # client -> server SDO requests
NMT_FRAME_BYTES, SDO_FRAME_BYTES = 2, 8
EMCY_RPDO_TIMEOUT = bytes((0x50, 0x82, 0x10, 0, 0, 0, 0, 0))   # 0x8250 RPDO timeout, error register: communication
EMCY_ERROR_RESET = bytes(8)
CAN_ERR_BUSOFF = 0x40         # error class bit of a bus-off error frame (linux/can/error.h)
ADC_MIN, ADC_MAX = -32768, 32767   # INTEGER16 analog inputs (0x6401)


@dataclass
class InjectedFaults:
    """What the emulated node does wrong. Set fields directly, or by name with :meth:`set` (the
    names ``--inject`` takes: :data:`FAULTS`); :meth:`clear` undoes all."""

    drop_tpdos: int = 0           # drop this many of the next TPDO frames
    stuck_encoder: int = 0        # 1 or 2: that counter stops counting; 0: none
    strain_gauge_rail: int = 0    # 1 or 2: that analog input sits at its positive rail
    amp_not_ready: int = 0        # 1 or 2: that ESCON drops ready (and drives no current)
    frozen: bool = False          # the node hangs: no heartbeat, no PDOs, no SDO answers, outputs held
    bus_off: bool = False         # the bus went off: an error frame, then silence both ways

    def clear(self) -> None:
        self.drop_tpdos = self.stuck_encoder = self.strain_gauge_rail = self.amp_not_ready = 0
        self.frozen = self.bus_off = False

    def set(self, name: str, on: bool) -> None:
        """Switch the fault ``name`` (one of :data:`FAULTS`) on or off."""
        if name not in FAULTS:
            raise ValueError(f"unknown fault {name!r} (expected one of: {', '.join(FAULTS)})")
        base, _, channel = name.rpartition("_")
        if name == "drop":
            self.drop_tpdos = DROP_ALL if on else 0
        elif name in ("frozen", "bus_off"):
            setattr(self, name, on)
        else:
            field = {"stuck_encoder": "stuck_encoder", "sg_rail": "strain_gauge_rail", "not_ready": "amp_not_ready"}[base]
            if on:
                setattr(self, field, int(channel))
            elif getattr(self, field) == int(channel):
                setattr(self, field, 0)


FAULTS = ("drop", "stuck_encoder_1", "stuck_encoder_2", "sg_rail_1", "sg_rail_2", "not_ready_1", "not_ready_2",
          "frozen", "bus_off")
DROP_ALL = 1 << 62            # "drop" switched on: every TPDO until switched off


class CanopenEmulator:
    """The ankle I/O node on ``bus`` with a :class:`SimulatedPlant` behind it (see module docstring)."""

    def __init__(self, cfg: Config, bus: can.BusABC, eds: str, *, realtime: bool = False):
        """``cfg`` gives the plant, the ESCON map and the sensor calibration; ``realtime`` sends
        heartbeats on the monotonic clock (standalone) instead of on the SYNC count (lockstep)."""
        self.plant = SimulatedPlant(cfg, getattr(cfg, "source", "config"))
        self.dt = self.plant.dt
        self.amps = escon_amplifiers(cfg, analog_codec())
        self.strain = StrainGauges.from_config(cfg)
        self.realtime = realtime
        self.bus = bus
        self.node_id = cfg["canopen"]["io_node_id"]
        self.network = canopen.Network(bus)           # no connect(): no Notifier thread
        self.node = canopen.LocalNode(self.node_id, canopen.import_od(eds, self.node_id))
        self.network.add_node(self.node)
        self.counter_bits = counter_bits(self.node.object_dictionary)
        self.encoders = MotorEncoders.from_config(cfg, self.counter_bits)
        self._heartbeat_ms = 0
        # heartbeats are sent by service() (no timer thread): catch writes of 0x1017 instead
        self.node._write_callbacks.remove(self.node.nmt.on_write)
        self.node.add_write_callback(self._on_write)
        self.network.subscribe(0, self._after_nmt)    # after the NmtSlave's own handler
        self.faults = InjectedFaults()
        self.schedule: list[ScheduledFault] = []
        self.counts = {"sync": 0, "rpdo": 0, "rpdo_bad_length": 0, "tpdo_sent": 0, "tpdo_dropped": 0,
                       "heartbeats": 0, "rpdo_timeouts": 0, "bad_frames": 0, "tx_dropped": 0}
        self.outputs = {SET_VALUE_1: self.amps[0].zero_code << ANALOG_CODE_SHIFT,
                        SET_VALUE_2: self.amps[1].zero_code << ANALOG_CODE_SHIFT, DIGITAL_OUT: 0}
        self._pending = dict(self.outputs)
        self._tpdos: tuple[PdoLayout, ...] = ()
        self._rpdos: dict[int, PdoLayout] = {}
        self._synced = False
        self._stuck_raw = [0, 0]
        self._next_heartbeat = 0.0
        self._bus_off_sent = False
        self._rpdo_timeout_s = 0.0
        self._last_rpdo = 0.0
        self._rpdo_timed_out = False
        self.boot()

    def _on_write(self, index: int, subindex: int, od, data: bytes) -> None:
        if index == 0x1017:
            self._heartbeat_ms = int.from_bytes(data[:2], "little")

    # -- NMT ---------------------------------------------------------------------------------------
    @property
    def state(self) -> str:
        return self.node.nmt.state

    def boot(self) -> None:
        """Power-up: boot-up message, PRE-OPERATIONAL, outputs at their error values."""
        self.node.nmt._state = NMT_PRE_OPERATIONAL
        self._safe_outputs()
        self._send(HEARTBEAT_BASE + self.node_id, b"\x00")

    def _after_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if self.node.nmt._state == NMT_OPERATIONAL:
            self._start_pdos()
            return
        if self.node.nmt._state == 0:              # reset node / communication: defaults, boot again
            reset_all = data[0] == NMT_RESET_NODE
            for index in list(self.node.data_store):
                if reset_all or 0x1000 <= index <= 0x1FFF:
                    del self.node.data_store[index]
            self._heartbeat_ms = 0
            self.boot()
        self._safe_outputs()

    def _start_pdos(self) -> None:
        """Compile the PDO mapping as the master configured it (SDO writes into this node's OD) and
        start the RPDO deadline monitoring (0x1400 sub5)."""
        node = self.node
        self._rpdo_timeout_s = node.sdo[0x1400][5].raw * 1e-3
        self._last_rpdo = self._now()
        node.tpdo.read()
        node.rpdo.read()
        self._tpdos = tuple(compile_pdo(m, "emulated node") for m in node.tpdo.map.values() if m.enabled and m.map)
        self._rpdos = {}
        for m in node.rpdo.map.values():
            if m.enabled and m.map:
                layout = compile_pdo(m, "emulated node")
                self._rpdos[layout.cob_id] = layout
                self.network.subscribe(layout.cob_id, self._on_rpdo)

    def _safe_outputs(self) -> None:
        """CiA 401 error behaviour: outputs in error mode take their error values."""
        get = self.node.sdo
        for obj, mode, value in ((SET_VALUE_1, get[0x6443][1].raw, get[0x6444][1].raw),
                                 (SET_VALUE_2, get[0x6443][2].raw, get[0x6444][2].raw)):
            if mode:
                self.outputs[obj] = self._pending[obj] = value
        mode = get[0x6206][1].raw
        value = get[0x6207][1].raw
        out = self.outputs[DIGITAL_OUT]
        self.outputs[DIGITAL_OUT] = self._pending[DIGITAL_OUT] = (out & ~mode) | (value & mode)

    # -- PDOs --------------------------------------------------------------------------------------
    def _on_rpdo(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if self.node.nmt._state != NMT_OPERATIONAL:
            return
        layout = self._rpdos[can_id]
        if len(data) != layout.size:
            self.counts["rpdo_bad_length"] += 1
            return
        self.counts["rpdo"] += 1
        self._last_rpdo = self._now()
        if self._rpdo_timed_out:
            self._rpdo_timed_out = False
            self._send(EMCY_BASE + self.node_id, EMCY_ERROR_RESET)
        for obj, value in zip(layout.objects, layout.codec.unpack(bytes(data))):
            self._pending[obj] = value

    def amplifier_currents(self) -> tuple[float, float]:
        """A driven by each ESCON for the applied outputs: zero unless enabled and ready."""
        out = self.outputs[DIGITAL_OUT]
        currents = [0.0, 0.0]
        for k, obj in enumerate((SET_VALUE_1, SET_VALUE_2)):
            amp = self.amps[k]
            enabled = amp.is_enabled(bool(out & ENABLE_BITS[k]))
            if enabled and self.faults.amp_not_ready != k + 1:
                currents[k] = amp.current(self.outputs[obj] >> ANALOG_CODE_SHIFT)
        return currents[0], currents[1]

    def _inputs(self) -> dict[tuple[int, int], int]:
        """Sample the plant's sensors as the I/O module's input objects."""
        plant = self.plant
        c1, c2 = self.encoders.raw_from_counts(*plant.encoder_counts())
        for i, c in ((0, c1), (1, c2)):
            if self.faults.stuck_encoder != i + 1:
                self._stuck_raw[i] = c
        full, half = 1 << self.counter_bits, 1 << (self.counter_bits - 1)
        c1, c2 = self._stuck_raw
        c1 = c1 - full if c1 >= half else c1           # the counter objects are signed integers
        c2 = c2 - full if c2 >= half else c2
        s1, s2 = self.strain.raw(*plant.strain_gauge_torques(), ADC_MIN, ADC_MAX)
        if self.faults.strain_gauge_rail == 1:
            s1 = ADC_MAX
        elif self.faults.strain_gauge_rail == 2:
            s2 = ADC_MAX
        ready = 0
        for i in (0, 1):
            if self.amps[i].ready_level(self.faults.amp_not_ready != i + 1):
                ready |= READY_BITS[i]
        return {COUNTER_1: c1, COUNTER_2: c2, STRAIN_1: s1, STRAIN_2: s2, DIGITAL_IN: ready}

    def _on_sync(self) -> None:
        """A SYNC is one control tick of physical time: the plant steps whatever the node's state
        (a hung node holds its outputs, a stopped one has its error values); only an operational,
        communicating node applies its RPDOs and answers with TPDOs."""
        self.counts["sync"] += 1
        talking = self.node.nmt._state == NMT_OPERATIONAL and not (self.faults.frozen or self.faults.bus_off)
        if talking:
            self.outputs.update(self._pending)
        if self._synced:
            self.plant.step(*self.amplifier_currents())
        self._synced = True
        t = self.plant.t                       # the time of this SYNC's sample
        for name, start, stop in self.schedule:
            self.faults.set(name, start <= t < stop)
        talking = self.node.nmt._state == NMT_OPERATIONAL and not (self.faults.frozen or self.faults.bus_off)
        if not talking:
            return
        inputs = self._inputs()
        for layout in self._tpdos:
            if self.faults.drop_tpdos > 0:
                self.faults.drop_tpdos -= 1
                self.counts["tpdo_dropped"] += 1
                continue
            self._send(layout.cob_id, layout.codec.pack(*(inputs[o] for o in layout.objects)))
            self.counts["tpdo_sent"] += 1

    # -- bus ---------------------------------------------------------------------------------------
    def _send(self, cob_id: int, data: bytes) -> None:
        """Send without waiting: a frame the transmit queue cannot take (no other node acknowledges:
        the daemon is gone) is counted and dropped, as the real node's controller would."""
        try:
            self.bus.send(can.Message(arbitration_id=cob_id, is_extended_id=False, data=data), timeout=0.0)
        except can.CanOperationError:
            self.counts["tx_dropped"] += 1

    def _now(self) -> float:
        """s: the monotonic clock standalone, the SYNC clock (plant time) in lockstep."""
        return time.monotonic() if self.realtime else self.plant.t

    def _watch_rpdo(self) -> None:
        """RPDO deadline monitoring: no set values for the event time -> error values and EMCY 0x8250."""
        if (self._rpdo_timeout_s > 0.0 and not self._rpdo_timed_out and self.node.nmt._state == NMT_OPERATIONAL
                and self._now() - self._last_rpdo > self._rpdo_timeout_s + 1e-9):
            self._rpdo_timed_out = True
            self.counts["rpdo_timeouts"] += 1
            self._safe_outputs()
            self._send(EMCY_BASE + self.node_id, EMCY_RPDO_TIMEOUT)

    def _heartbeat(self) -> None:
        """Send the heartbeat when it is due (0x1017; on the SYNC clock in lockstep)."""
        period_ms = self._heartbeat_ms
        if not period_ms:
            return
        now = self._now()
        if now >= self._next_heartbeat:
            self._send(HEARTBEAT_BASE + self.node_id, bytes((self.node.nmt._state,)))
            self.counts["heartbeats"] += 1
            # on the SYNC clock, half a tick early so that float rounding cannot skip a tick
            self._next_heartbeat = now + period_ms * 1e-3 - (0.5 * self.dt if not self.realtime else 0.0)

    def service(self) -> None:
        """Handle every frame waiting on the bus, then send a due heartbeat. Never blocks."""
        while True:
            msg = self.bus.recv(0.0)
            if msg is None:
                break
            self._handle(msg)
        self._idle()

    def _handle(self, msg: can.Message) -> None:
        if msg.is_error_frame or msg.is_remote_frame:
            return
        if msg.arbitration_id == SYNC_COB_ID:
            self._on_sync()
        elif not (self.faults.frozen or self.faults.bus_off):
            # NMT commands are 2 bytes and SDO requests 8 (CiA 301); the canopen library's handlers
            # unpack them without a length check, so a short frame is dropped (and counted) here
            need = NMT_FRAME_BYTES if msg.arbitration_id == 0 else (
                SDO_FRAME_BYTES if msg.arbitration_id == SDO_RX_BASE + self.node_id else 0)
            if len(msg.data) < need:
                self.counts["bad_frames"] += 1
                return
            self.network.notify(msg.arbitration_id, msg.data, msg.timestamp)

    def _idle(self) -> None:
        f = self.faults
        if f.bus_off:
            if not self._bus_off_sent:   # what the master's controller reports, then silence
                self.bus.send(can.Message(arbitration_id=CAN_ERR_BUSOFF, is_error_frame=True, dlc=8))
                self._bus_off_sent = True
                self.node.nmt._state = NMT_PRE_OPERATIONAL      # 0x1029: communication error -> pre-op
                self._safe_outputs()
            return
        self._bus_off_sent = False
        if not f.frozen:
            self._watch_rpdo()
            self._heartbeat()

    def close(self) -> None:
        """Release the emulator's bus."""
        self.bus.shutdown()

    def serve(self, duration_s: float | None = None, poll_s: float = 0.001) -> None:
        """Standalone: block on the bus and serve until ``duration_s`` has passed (forever if None);
        says when a master starts and stops sending SYNCs."""
        presence = Presence("SYNCs")
        end = None if duration_s is None else time.monotonic() + duration_s
        while (now := time.monotonic()) < (end or math.inf):
            msg = self.bus.recv(poll_s)
            if msg is not None:
                self._handle(msg)
            self._idle()
            presence.update(self.counts["sync"], now)


class LockstepBus(can.BusABC):
    """The backend's side of an in-process virtual bus: every ``send`` lets the emulator handle the
    frame (and answer) before it returns, so backend and emulator share one thread in lockstep."""

    def __init__(self, channel: str, emulator: "CanopenEmulator | None" = None, **kwargs):
        self._inner = can.Bus(interface="virtual", channel=channel)
        self.emulator = emulator
        super().__init__(channel=channel, **kwargs)
        self.channel_info = f"lockstep {self._inner.channel_info}"

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._inner.send(msg, timeout)
        if self.emulator is not None:
            self.emulator.service()

    def _recv_internal(self, timeout: float | None):
        return self._inner._recv_internal(timeout)

    def shutdown(self) -> None:
        self._inner.shutdown()
        super().shutdown()


def lockstep_pair(cfg: Config, eds: str, channel: str) -> tuple[LockstepBus, CanopenEmulator]:
    """An emulator on virtual ``channel`` and the lockstep bus a backend uses to reach it."""
    link = LockstepBus(channel)
    emulator = CanopenEmulator(cfg, can.Bus(interface="virtual", channel=channel), eds)
    link.emulator = emulator
    return link, emulator


# -- ankle-rt emulate --transport canopen ---------------------------------------------------------

def run_standalone(cfg: Config, args: argparse.Namespace) -> int:
    """Serve the I/O node on a real CAN interface until Ctrl-C or ``--duration`` (the bench's second
    computer). The plant steps on each SYNC of the master; heartbeats run on the monotonic clock."""
    from hardware.canopen_backend import configured_bus_load
    from hardware.canopen_pdo import eds_path

    co = cfg["canopen"]
    interface = args.interface or co["interface"]
    channel = args.channel or co["channel"]
    if interface == "virtual":
        print("ankle-rt emulate: python-can's virtual bus exists only inside one process; for a one-process "
              "bench run the daemon with config/bench-canopen.yaml (canopen.emulator: lockstep), or give "
              "--interface socketcan --channel can0|vcan0", file=sys.stderr)
        return 2
    try:
        schedule = [parse_schedule(spec, FAULTS) for spec in args.inject]
    except ValueError as exc:
        print(f"ankle-rt emulate: {exc}", file=sys.stderr)
        return 2
    print(configured_bus_load(cfg).table(), flush=True)
    try:
        bus = can.Bus(interface=interface, channel=channel, bitrate=co["bitrate"])
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        print(f"ankle-rt emulate: cannot open {interface}:{channel}: {describe_open_error(exc, interface, channel)}",
              file=sys.stderr)
        return 1
    emulator = CanopenEmulator(cfg, bus, str(eds_path(cfg)), realtime=True)
    emulator.schedule = schedule
    print(f"emulator: CANopen I/O node {emulator.node_id} on {interface}:{channel} ({until_text(args.duration)})",
          flush=True)
    try:
        emulator.serve(args.duration or None)
    except KeyboardInterrupt:
        pass
    finally:
        emulator.close()
    c = emulator.counts
    print(f"emulator: {emulator.plant.ticks} ticks, {c['sync']} SYNC, {c['rpdo']} RPDO, {c['tpdo_sent']} TPDO sent, "
          f"{c['tpdo_dropped']} dropped, {c['heartbeats']} heartbeats, {c['tx_dropped']} frames not sent "
          f"(nobody acknowledging)", flush=True)
    return 0
