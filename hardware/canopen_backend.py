"""The CANopen backend: the ESCON amplifiers and the sensors behind a CiA 401 I/O node.

One I/O node (``hardware/ankle_io.eds``) carries everything: the two analog set values (0x6411), the
enables (0x6200), the ESCON ready lines (0x6000), the strain-gauge bridges (0x6401) and the encoder
counters (0x2100). Per cycle (docs/canopen.md):

    read():  send SYNC (and, while inactive, the safe RPDO) -> poll the bus without blocking (bounded
             frame count; on a real clock spin at most ``canopen.tpdo_wait_us`` for this cycle's
             TPDOs) -> decode with preallocated structs -> heartbeat consumer, bus-off, EMCY, ready
             and sensor checks -> SensorFrame
    write(): pack the set values and enables into the preallocated RPDO and send it; the node applies
             it at the next SYNC

A lost TPDO keeps the previous sample and its ``seq`` (counted; the daemon's stale-sample rule
decides); the heartbeat consumer reports LINK_LOST, a node outside OPERATIONAL or an EMCY
DEVICE_FAULT, a bus-off error frame or a refused send BUS_OFF until frames flow again.

There is no python-can Notifier thread while the loop runs: canopen's ``Network.connect()`` would
start one that runs Python callbacks for every frame and competes with the loop for the GIL. A
Notifier runs only during configuration, where canopen's SDO client needs it.

Start-up (configure): NMT pre-operational -> SDO: identity check, cycle period, heartbeat producer
time, safe-on-error values, the EDS's PDO mapping (transmission type 1) -> NMT operational with set
values zero and enables off, so the sensors flow (the daemon tares) before the amplifiers are enabled.
Shutdown (close): set values zero, enables off, NMT pre-operational.
"""

from __future__ import annotations

import time

import can
import canopen

from ankle_rt.backend import Backend, BackendError, BackendFault, SensorFrame, load_by_name
from ankle_rt.clock import Clock
from ankle_rt.config import Config, ConfigError
from hardware.can_hints import describe_open_error
from hardware.canbus_load import BusLoad, check_bus_load, loop_bus_load
from hardware.canopen_pdo import (COUNTER_1, COUNTER_2, DIGITAL_IN, DIGITAL_OUT, ENABLE_BITS,
                                  HEARTBEAT_BASE, READY_BITS, SET_VALUE_1, SET_VALUE_2, STRAIN_1, STRAIN_2,
                                  SYNC_COB_ID, ANALOG_CODE_SHIFT, EdsError, NodeLayout, analog_codec,
                                  counter_bits, eds_path, load_node)
from hardware.escon import enable_outputs, escon_amplifiers
from hardware.sensors import MotorEncoders, StrainGauges, StuckEncoderDetector

# canopen.emulator: lockstep: the bench's in-process node, named here and imported only then (the
# driver never imports the emulators).
LOCKSTEP_EMULATOR = "hardware.emulators.canopen_emulator:lockstep_pair"
MAX_FRAMES_PER_READ = 64         # frames handled per read(); the rest wait for the next cycle
STATE_BOOT_UP, STATE_OPERATIONAL, STATE_PRE_OPERATIONAL = 0x00, 0x05, 0x7F   # heartbeat states
CMD_START, CMD_ENTER_PRE_OPERATIONAL = 0x01, 0x80                               # NMT commands
CAN_ERR_BUSOFF = 0x40            # error-frame class bit (linux/can/error.h), as python-can reports it
EMCY_BASE = 0x80
NOTIFIER_POLL_S = 0.01           # configuration-time Notifier: how quickly it can be stopped
INPUT_SLOTS = (COUNTER_1, COUNTER_2, STRAIN_1, STRAIN_2, DIGITAL_IN)  # order of self._raw


def node_layout(cfg: Config, network: canopen.Network | None = None) -> tuple[canopen.RemoteNode, NodeLayout]:
    """The I/O node and its PDO layout from the config's EDS (ConfigError naming ``canopen.eds``)."""
    try:
        return load_node(eds_path(cfg), cfg["canopen"]["io_node_id"], network)
    except EdsError as exc:
        raise ConfigError(str(exc), getattr(cfg, "source", None), "canopen.eds") from None


def configured_bus_load(cfg: Config, layout: NodeLayout | None = None) -> BusLoad:
    """The bus load of the config's rate, bit rate, PDO mapping and heartbeat (not yet checked).
    ``layout``: the node's PDO layout when already loaded (default: from the config's EDS)."""
    co = cfg["canopen"]
    if layout is None:
        _, layout = node_layout(cfg)
    return loop_bus_load(layout, cfg["controller"]["rate_hz"], co["bitrate"], co["heartbeat_producer_ms"])


class CanopenBackend(Backend):
    name = "canopen"

    @property
    def simulated_plant(self) -> bool:
        """True only with the in-process lockstep emulator this backend started itself."""
        return self.emulator is not None

    def __init__(self, cfg: Config, clock: Clock, *, bus: can.BusABC | None = None):
        """Configure: check the bus load, open the bus (or use ``bus``), set the node up, go operational."""
        super().__init__(cfg, clock)
        co = cfg["canopen"]
        source = getattr(cfg, "source", None)
        if co["heartbeat_consumer_ms"] <= co["heartbeat_producer_ms"]:
            raise ConfigError(f"must be longer than canopen.heartbeat_producer_ms "
                              f"({co['heartbeat_producer_ms']} ms)", source, "canopen.heartbeat_consumer_ms")
        self.period_ns = round(1e9 / cfg["controller"]["rate_hz"])
        self.network = canopen.Network()
        self.node, self.layout = node_layout(cfg, self.network)
        self.bus_load = configured_bus_load(cfg, self.layout)
        print(f"canopen: bus load at {cfg['controller']['rate_hz']} Hz\n{self.bus_load.table()}")
        check_bus_load(self.bus_load, source)
        self.amps = escon_amplifiers(cfg, analog_codec())
        self._enabled = enable_outputs(self.amps, ENABLE_BITS, True)
        self._disabled = enable_outputs(self.amps, ENABLE_BITS, False)
        self.encoders = MotorEncoders.from_config(cfg, counter_bits(self.node.object_dictionary))
        self.strain = StrainGauges.from_config(cfg)
        self.stuck = StuckEncoderDetector.from_config(cfg, self.period_ns * 1e-9)
        self.node_id = co["io_node_id"]
        self.consumer_ns = co["heartbeat_consumer_ms"] * 1_000_000
        self.tpdo_wait_ns = 0 if clock.simulated else co["tpdo_wait_us"] * 1000
        self.bus = None
        self.emulator = None             # the in-process device emulator (canopen.emulator: lockstep)
        if bus is None and co["emulator"] == "lockstep":
            if co["interface"] != "virtual":
                raise ConfigError("a lockstep emulator runs on the in-process virtual bus: set canopen.interface "
                                  "to virtual", source, "canopen.emulator")
            bus, self.emulator = load_by_name(LOCKSTEP_EMULATOR)(cfg, str(eds_path(cfg)), co["channel"])
        elif bus is None:
            bus = self._open_bus(co)
        self.bus = bus
        self.network.bus = bus
        self._prepare_frames()
        self.active = False
        self.counts = {"sync_sent": 0, "tpdo_received": 0, "tpdo_missed": 0, "heartbeats": 0,
                       "heartbeat_timeouts": 0, "emcy": 0, "error_frames": 0, "bus_off": 0,
                       "send_errors": 0, "unknown_frames": 0, "bad_length": 0, "frames_deferred": 0}
        self.start_ns = clock.now_ns()
        try:
            self._configure_node(co)
        except BaseException:
            self._release_bus()
            raise

    # -- configuration -------------------------------------------------------------------------
    def _open_bus(self, co: dict) -> can.BusABC:
        try:
            return can.Bus(interface=co["interface"], channel=co["channel"], bitrate=co["bitrate"])
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            raise BackendError(f"canopen: cannot open interface {co['interface']!r} channel {co['channel']!r}: "
                               f"{describe_open_error(exc, co['interface'], co['channel'])}") from None

    def _prepare_frames(self) -> None:
        """Preallocate every frame the loop sends and the decode tables for what it receives."""
        lay = self.layout
        self._sync = can.Message(arbitration_id=SYNC_COB_ID, is_extended_id=False, data=b"")
        self._rpdos = [can.Message(arbitration_id=p.cob_id, is_extended_id=False, data=bytearray(p.size))
                       for p in lay.rpdos]
        self._rpdo_values = [[0] * len(p.objects) for p in lay.rpdos]
        self._out_slots = {}
        for obj in (SET_VALUE_1, SET_VALUE_2, DIGITAL_OUT):
            pdo, pos = lay.slot(obj)
            self._out_slots[obj] = (lay.rpdos.index(pdo), pos)
        self._raw = [0] * len(INPUT_SLOTS)
        self._tpdo_by_cob = {}
        for i, p in enumerate(lay.tpdos):
            dest = tuple((pos, INPUT_SLOTS.index(o)) for pos, o in enumerate(p.objects) if o in INPUT_SLOTS)
            self._tpdo_by_cob[p.cob_id] = (i, p.codec, p.size, dest)
        self._all_tpdos = (1 << len(lay.tpdos)) - 1
        self._hb_cob = HEARTBEAT_BASE + self.node_id
        self._emcy_cob = EMCY_BASE + self.node_id

    def _configure_node(self, co: dict) -> None:
        """NMT pre-operational, SDO set-up, NMT operational (a Notifier runs only in here)."""
        node = self.node
        node.sdo.RESPONSE_TIMEOUT = co["sdo_timeout_s"]
        notifier = can.Notifier(self.bus, self.network.listeners, timeout=NOTIFIER_POLL_S)
        try:
            node.nmt.send_command(CMD_ENTER_PRE_OPERATIONAL)
            od = node.object_dictionary
            product = node.sdo[0x1018][2].raw
            if product != od[0x1018][2].default:
                raise BackendError(f"canopen: node {self.node_id} reports product code 0x{product:08X}, "
                                   f"the EDS describes 0x{od[0x1018][2].default:08X}")
            node.sdo[0x1006].raw = self.period_ns // 1000                  # communication cycle period, µs
            node.sdo[0x1017].raw = co["heartbeat_producer_ms"]
            node.sdo[0x1029][1].raw = 0                                   # communication error -> pre-operational
            node.sdo[0x6206][1].raw = ENABLE_BITS[0] | ENABLE_BITS[1]    # enables take the error value ...
            node.sdo[0x6207][1].raw = 0                                   # ... off
            for sub in (1, 2):
                node.sdo[0x6443][sub].raw = 1                             # set values take the error value ...
                node.sdo[0x6444][sub].raw = self.amps[sub - 1].zero_code << ANALOG_CODE_SHIFT  # ... zero current
                node.sdo[0x6411][sub].raw = self.amps[sub - 1].zero_code << ANALOG_CODE_SHIFT
            node.sdo[0x6200][1].raw = 0
            node.rpdo.save()
            node.tpdo.save()
            for m in node.rpdo.map.values():                              # deadline monitoring of the set values
                if m.enabled and m.map:
                    m.com_record[5].raw = co["rpdo_timeout_ms"]
            node.nmt.send_command(CMD_START)
        except (canopen.SdoCommunicationError, canopen.SdoAbortedError) as exc:
            raise BackendError(f"canopen: node {self.node_id} on {co['interface']}:{co['channel']} did not "
                               f"accept its configuration: {exc}") from None
        finally:
            notifier.stop(timeout=1.0)
        self._node_state = STATE_OPERATIONAL
        self._last_heartbeat_ns = self.clock.now_ns()
        self._bus_off = self._bus_off_now = False
        self._link_lost = False
        self._emcy_pending = False
        self._fresh = 0
        self._seq = 0
        self._acting = [0.0, 0.0]       # A, the set values that act until the next SYNC
        self.write(0.0, 0.0)

    # -- the cycle -----------------------------------------------------------------------------
    def _send(self, msg: can.Message) -> None:
        """Send one frame; a refused send (controller bus-off, tx queue full) becomes BUS_OFF."""
        try:
            self.bus.send(msg)
        except can.CanError:
            self.counts["send_errors"] += 1
            self._bus_off = True

    def _receive(self, deadline_ns: int) -> None:
        """Handle waiting frames without blocking; spin until ``deadline_ns`` (monotonic) for the
        cycle's TPDOs when it lies in the future. At most MAX_FRAMES_PER_READ frames."""
        bus = self.bus
        by_cob = self._tpdo_by_cob
        raw = self._raw
        counts = self.counts
        for _ in range(MAX_FRAMES_PER_READ):
            msg = bus.recv(0.0)
            if msg is None:
                if self._fresh == self._all_tpdos or time.monotonic_ns() >= deadline_ns:
                    return
                continue
            cob = msg.arbitration_id
            if msg.is_error_frame:
                counts["error_frames"] += 1
                if cob & CAN_ERR_BUSOFF:
                    counts["bus_off"] += 1
                    self._bus_off = self._bus_off_now = True
                continue
            entry = by_cob.get(cob)
            if entry is not None:
                i, codec, size, dest = entry
                if msg.dlc != size or len(msg.data) != size:     # the DLC field can lie about the payload
                    counts["bad_length"] += 1
                    continue
                values = codec.unpack_from(msg.data)
                for pos, slot in dest:
                    raw[slot] = values[pos]
                self._fresh |= 1 << i
                counts["tpdo_received"] += 1
            elif cob == self._hb_cob:
                counts["heartbeats"] += 1
                self._last_heartbeat_ns = self.clock.now_ns()
                self._link_lost = False
                self._node_state = state = msg.data[0] & 0x7F if len(msg.data) else STATE_BOOT_UP
                if state == STATE_PRE_OPERATIONAL and not self.active:
                    self._restart_node()        # e.g. after a bus-off: its configuration is intact
            elif cob == self._emcy_cob:
                counts["emcy"] += 1
                self._emcy_pending = len(msg.data) >= 2 and bool(msg.data[0] or msg.data[1])  # 0000: error reset
            else:
                counts["unknown_frames"] += 1
        counts["frames_deferred"] += 1

    def read(self, frame: SensorFrame) -> None:
        now = self.clock.now_ns()
        self._fresh = 0
        self._bus_off_now = False
        self._send(self._sync)
        self.counts["sync_sent"] += 1
        if not self.active:        # keep a node that was away (hung, bus-off) on safe outputs
            self.write(0.0, 0.0)
        self._receive(time.monotonic_ns() + self.tpdo_wait_ns)
        faults = BackendFault.NONE
        raw = self._raw
        if self._fresh == self._all_tpdos:      # a complete new sample: convert it, advance seq
            self._seq += 1
            if not self._bus_off_now:           # frames flow again: the controller recovered
                self._bus_off = False
            self.encoders.convert(raw[0], raw[1], frame.motor_pos)
            if self.strain.convert(raw[2], raw[3], frame.sg_torque):
                faults |= BackendFault.STRAIN_GAUGE_RAIL
            if self.stuck.update(self.encoders.moved, self._acting[0], self._acting[1],
                                 float(frame.sg_torque[0]), float(frame.sg_torque[1])):
                faults |= BackendFault.ENCODER_FAULT
        else:                                   # a lost TPDO: the frame keeps the last sample and seq;
            self.counts["tpdo_missed"] += 1     # the daemon's stale-sample rule decides
        if now - self._last_heartbeat_ns > self.consumer_ns:
            if not self._link_lost:
                self.counts["heartbeat_timeouts"] += 1
            self._link_lost = True
            faults |= BackendFault.LINK_LOST
        elif self._node_state != STATE_OPERATIONAL:
            faults |= BackendFault.DEVICE_FAULT
        if self._emcy_pending:
            faults |= BackendFault.DEVICE_FAULT
        if self._bus_off:
            faults |= BackendFault.BUS_OFF
        digital = raw[4]
        for k in (0, 1):
            ready = self.amps[k].is_ready(bool(digital & READY_BITS[k]))
            frame.amp_ready[k] = ready
            if self.active and not ready:
                faults |= BackendFault.AMP_NOT_READY
        frame.t = (now - self.start_ns) * 1e-9
        frame.seq = self._seq
        frame.faults = faults

    def write(self, current_1: float, current_2: float) -> None:
        amps = self.amps
        if self.active:
            code_1, code_2 = amps[0].code(current_1), amps[1].code(current_2)
            self._acting[0] = amps[0].current(code_1)
            self._acting[1] = amps[1].current(code_2)
            enables = self._enabled
        else:
            code_1, code_2 = amps[0].zero_code, amps[1].zero_code
            self._acting[0] = self._acting[1] = 0.0
            enables = self._disabled
        slots = self._out_slots
        values = self._rpdo_values
        p, k = slots[SET_VALUE_1]
        values[p][k] = code_1 << ANALOG_CODE_SHIFT
        p, k = slots[SET_VALUE_2]
        values[p][k] = code_2 << ANALOG_CODE_SHIFT
        p, k = slots[DIGITAL_OUT]
        values[p][k] = enables
        for layout, msg, vals in zip(self.layout.rpdos, self._rpdos, values):
            layout.codec.pack_into(msg.data, 0, *vals)
            self._send(msg)

    def activate(self) -> None:
        """Enable the amplifiers (from the next write on); NMT start first, in case the node fell
        back to pre-operational."""
        self._restart_node()
        self.active = True

    def _restart_node(self) -> None:
        """NMT start (one unconfirmed frame; a no-op for an operational node). Outputs stay as the
        last RPDO set them, so with the amplifiers inactive they stay zero and disabled."""
        try:
            self.node.nmt.send_command(CMD_START)
        except can.CanError:
            self.counts["send_errors"] += 1
            return
        self._node_state = STATE_OPERATIONAL    # the next heartbeat confirms it

    def deactivate(self) -> None:
        """Set values zero, enables off, sent at once (the node applies them at the next SYNC)."""
        self.active = False
        if self.bus is not None:
            self.write(0.0, 0.0)

    def close(self) -> None:
        """Zero set values and enables off, NMT pre-operational (outputs take their error values), bus released."""
        if self.bus is None:
            return
        self.deactivate()
        try:
            self.node.nmt.send_command(CMD_ENTER_PRE_OPERATIONAL)
        except can.CanError:
            self.counts["send_errors"] += 1
        self._release_bus()

    def _release_bus(self) -> None:
        self.bus.shutdown()
        self.bus = None
        if self.emulator is not None:
            self.emulator.close()

    def counters(self) -> dict[str, int]:
        return dict(self.counts)
