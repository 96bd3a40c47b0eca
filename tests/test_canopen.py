"""CANopen transport: EDS and PDO mapping, bus load, the section 7 experiment through the backend and
the emulator in lockstep, fault injection through the daemon's safety, start-up and shutdown."""

from __future__ import annotations

import itertools
import math

import can
import canopen
import numpy as np
import pytest

from ankle_rt.backend import BackendError, BackendFault, SensorFrame, open_backend
from ankle_rt.clock import SimClock
from ankle_rt.config import Config, ConfigError
from ankle_rt.daemon import run_lockstep
from ankle_rt.safety import Fault
from hardware.canbus_load import MAX_BUS_LOAD, frame_bits
from hardware.canopen_backend import CanopenBackend, configured_bus_load
from hardware.emulators.canopen_emulator import FAULTS as NODE_FAULTS, lockstep_pair
from hardware.canopen_pdo import (COUNTER_1, COUNTER_2, DEFAULT_EDS, DIGITAL_IN, DIGITAL_OUT, SET_VALUE_1,
                                  SET_VALUE_2, STRAIN_1, STRAIN_2, EdsError, load_node)
from hardware.emulators.fault_schedule import parse_schedule
from tests.conftest import ROOT
from tests.hw_helpers import Bench, QuantisedSimBackend, bench_config, read_cycles, sim_copy

BENCH = ROOT / "config" / "bench-canopen.yaml"
_channels = itertools.count()


@pytest.fixture
def bench_cfg() -> Config:
    """A private copy of config/bench-canopen.yaml on a channel of its own."""
    cfg = bench_config(BENCH)
    cfg["canopen"]["channel"] = f"test-canopen-{next(_channels)}"
    return cfg


# -- EDS, PDO mapping, bus load ------------------------------------------------------------------

def test_eds_loads_with_canopen_and_maps_every_signal_sync_driven():
    od = canopen.import_od(str(DEFAULT_EDS), 5)
    assert od[0x1400][1].default == 0x205 and od[0x1800][1].default == 0x185 and od[0x1801][1].default == 0x285
    assert od[0x6443][1].default == 1 and od[0x6444][1].default == 0      # set value -> 0 on error
    assert od[0x6206][1].default == 0xFF and od[0x6207][1].default == 0   # enables -> off on error
    assert od[0x1017].writable
    _, layout = load_node(DEFAULT_EDS, 5)
    tx = {obj: p.name for p in layout.tpdos for obj in p.objects}
    rx = {obj: p.name for p in layout.rpdos for obj in p.objects}
    assert {COUNTER_1, COUNTER_2} <= tx.keys() and {STRAIN_1, STRAIN_2, DIGITAL_IN} <= tx.keys()
    assert {SET_VALUE_1, SET_VALUE_2, DIGITAL_OUT} <= rx.keys()
    for p in layout.tpdos + layout.rpdos:
        assert p.trans_type == 1 and p.size <= 8
        assert od[p.objects[0][0]][p.objects[0][1]].pdo_mappable
    assert [p.size for p in layout.tpdos] == [8, 5] and [p.size for p in layout.rpdos] == [5]


def test_eds_missing_a_needed_mapping_is_refused_naming_the_object(tmp_path):
    text = DEFAULT_EDS.read_text().replace("[1A01sub0]\nParameterName=Number of mapped objects\nObjectType=0x7\n"
                                           "DataType=0x0005\nAccessType=rw\nDefaultValue=3",
                                           "[1A01sub0]\nParameterName=Number of mapped objects\nObjectType=0x7\n"
                                           "DataType=0x0005\nAccessType=rw\nDefaultValue=2")
    eds = tmp_path / "short.eds"
    eds.write_text(text)
    with pytest.raises(EdsError, match="0x6000:01 is not mapped"):
        load_node(eds, 1)


def test_frame_bits_worst_case_stuffing():
    assert frame_bits(0) == 55 and frame_bits(8) == 135      # 47 + 8n + floor((34 + 8n - 1) / 4)
    with pytest.raises(ValueError):
        frame_bits(9)


def test_bus_load_at_1khz_and_refusal_names_the_key(bench_cfg):
    load = configured_bus_load(bench_cfg)
    per_cycle = sum(frame_bits(f.data_bytes) for f in load.frames if f.every_cycle)
    assert per_cycle == 55 + 105 + 135 + 105
    assert load.load == pytest.approx((per_cycle * 1000 + 65 * 100) / 1e6)
    assert load.load < MAX_BUS_LOAD and "40.6 %" in load.table()
    bench_cfg["canopen"]["bitrate"] = 500_000                 # the same traffic on half the bus: 81 %
    with pytest.raises(ConfigError, match="controller.rate_hz.*81.3 %"):
        open_backend(bench_cfg, SimClock())
    bench_cfg["canopen"]["bitrate"] = 1_000_000
    bench_cfg["controller"]["rate_hz"] = 2000
    with pytest.raises(ConfigError, match="controller.rate_hz"):
        open_backend(bench_cfg, SimClock())


def test_heartbeat_consumer_must_outlast_the_producer(bench_cfg):
    bench_cfg["canopen"]["heartbeat_consumer_ms"] = 10
    with pytest.raises(ConfigError, match="canopen.heartbeat_consumer_ms"):
        open_backend(bench_cfg, SimClock())


# -- start-up, cycle, shutdown -------------------------------------------------------------------

def test_startup_configures_the_node_over_sdo_and_shutdown_leaves_it_safe(bench_cfg):
    clock = SimClock()
    backend = open_backend(bench_cfg, clock)
    emu = backend.emulator
    assert emu.state == "OPERATIONAL"
    sdo = emu.node.sdo
    assert sdo[0x1017].raw == bench_cfg["canopen"]["heartbeat_producer_ms"]
    assert sdo[0x1006].raw == 1000                                      # µs, the control period
    frame = SensorFrame()
    backend.activate()
    for _ in range(20):
        backend.read(frame)
        backend.write(2.0, -1.0)
        clock.advance(backend.period_ns)
    assert emu.plant.current == pytest.approx([2.0, -1.0], abs=0.01)   # 12-bit set value, 7.3 mA LSB
    assert emu.outputs[DIGITAL_OUT] == 0b11
    assert frame.faults == BackendFault.NONE and frame.seq == 20
    backend.close()
    assert emu.state == "PRE-OPERATIONAL"
    assert emu.outputs[DIGITAL_OUT] == 0 and emu.amps[0].current(emu.outputs[SET_VALUE_1] >> 4) == 0.0


def test_a_missing_or_wrong_node_is_refused_naming_it(bench_cfg):
    bench_cfg["canopen"]["sdo_timeout_s"] = 0.05
    silent = can.Bus(interface="virtual", channel=bench_cfg["canopen"]["channel"] + "-empty")
    with pytest.raises(BackendError, match="node 1 on virtual:.* did not accept its configuration"):
        CanopenBackend(bench_cfg, SimClock(), bus=silent)
    link, emulator = lockstep_pair(bench_cfg, str(DEFAULT_EDS), bench_cfg["canopen"]["channel"])
    emulator.node.set_data(0x1018, 2, (0x1234).to_bytes(4, "little"))
    with pytest.raises(BackendError, match="product code 0x00001234"):
        CanopenBackend(bench_cfg, SimClock(), bus=link)
    emulator.close()


# -- the section 7 experiment: CANopen + emulator against the direct simulated backend ----------

def test_section7_through_canopen_matches_the_direct_simulation(bench_cfg):
    """Tolerance: the 12-bit set value (±15 A over 4096 codes: 7.3 mA, 12 mN m of motor torque per
    code) differs from the exact one by at most half a code; under kp = 90 N m/rad that moves a motor
    by ~7e-5 rad (~1.3 encoder counts), and the encoder quantisation and stick-slip turn it into a
    few counts. So motors within 5 counts (2.7e-4 rad) and ankles within 1e-4 rad (0.006 deg), on a
    10 deg / 5 deg step. With the same quantisation applied to the direct backend the motor
    trajectories and currents agree to floating-point rounding: the transport adds nothing else."""
    duration = 3.5
    direct = run_lockstep(sim_copy(bench_cfg), duration)
    clock = SimClock()
    backend = CanopenBackend(bench_cfg, clock)
    ankle = []
    plant = backend.emulator.plant
    step = plant.step

    def step_and_record(i1, i2):
        step(i1, i2)
        ankle.append(plant.ankle_positions())

    plant.step = step_and_record
    via_can = run_lockstep(bench_cfg, duration, backend=backend)
    backend.close()
    assert direct.summary["fault"] == via_can.summary["fault"] == "NONE"
    n = len(direct)
    assert len(via_can) == n and np.allclose(direct["t"], via_can["t"], rtol=0, atol=1e-12)
    assert np.nanmax(np.abs(direct["ref_dp"])) == pytest.approx(math.radians(10), rel=1e-3)
    count = 2 * math.pi / bench_cfg["actuator"]["encoder_counts_per_rev"]
    for k in ("motor_pos_1", "motor_pos_2"):
        assert np.max(np.abs(direct[k] - via_can[k])) <= 5 * count
    true_ankle = np.array(ankle)                         # after ticks 1..n-1 = rows 1..n-1
    assert np.max(np.abs(true_ankle[:, 0] - direct["ankle_dp"][1:])) < 1e-4
    assert np.max(np.abs(true_ankle[:, 1] - direct["ankle_ie"][1:])) < 1e-4
    for k in ("est_ankle_dp", "est_ankle_ie"):
        assert np.max(np.abs(direct[k] - via_can[k])) < 1e-4
    assert np.abs(true_ankle[-1, 0] - math.radians(10)) < math.radians(1)   # the step was tracked

    amps = backend.amps
    quantised = run_lockstep(sim_copy(bench_cfg), duration,
                             backend=QuantisedSimBackend(sim_copy(bench_cfg), SimClock(), amps))
    for k in ("motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2"):   # equal up to float rounding
        assert np.max(np.abs(quantised[k] - via_can[k])) < 1e-9, k


# -- fault injection through the daemon's safety ---------------------------------------------------

def _stuck(emu):
    emu.faults.stuck_encoder = 1


def _rail(emu):
    emu.faults.strain_gauge_rail = 2


def _not_ready(emu):
    emu.faults.amp_not_ready = 1


def _frozen(emu):
    emu.faults.frozen = True


def _bus_off(emu):
    emu.faults.bus_off = True


def _dropped(emu):
    emu.faults.drop_tpdos = 1000


# (injection, expected fault, cycles until the daemon is safe: 1 = in the cycle whose SYNC saw it)
FAULTS = [
    (_stuck, Fault.ENCODER_FAULT, 10),     # encoders.stuck_time: 10 ms of unbalanced torque without a count
    (_rail, Fault.SG_RAIL, 1),
    (_not_ready, Fault.AMP_NOT_READY, 1),
    (_bus_off, Fault.BUS_OFF, 1),
    (_frozen, Fault.SENSOR_STALE, 5),      # no TPDOs: the sample stops advancing (safety.stale_cycles)
    (_dropped, Fault.SENSOR_STALE, 5),
]


@pytest.mark.parametrize("inject, expected, within", FAULTS, ids=[f[0].__name__[1:] for f in FAULTS])
def test_injected_fault_goes_safe_in_time_and_resumes_after_reset(bench_cfg, inject, expected, within):
    bench = Bench(bench_cfg)
    emu = bench.emu
    try:
        bench.run_into_the_step()                            # the motors work when the fault comes
        inject(emu)
        took = bench.cycles_until_safe(within + 10)
        assert took <= within
        assert bench.daemon.safety.fault == expected
        bench.cycles(1)
        rpdo = bench.backend._rpdos[0].data                  # what the backend last sent: safe values
        assert rpdo[4] == 0 and int.from_bytes(rpdo[0:2], "little", signed=True) == 0
        if not emu.faults.frozen:                            # a hung node cannot apply anything
            assert emu.outputs[DIGITAL_OUT] == 0 and emu.amplifier_currents() == (0.0, 0.0)
        bench.assert_latched(expected)
        emu.faults.clear()
        bench.cycles(30)                                     # heartbeats and PDOs come back
        bench.reset_and_resume()
        assert emu.outputs[DIGITAL_OUT] == 0b11 and emu.state == "OPERATIONAL"
    finally:
        bench.close()


def test_heartbeat_consumer_reports_a_frozen_node_within_its_timeout(bench_cfg):
    clock = SimClock()
    backend = open_backend(bench_cfg, clock)
    frame = SensorFrame()
    read_cycles(backend, frame, 50)
    assert frame.faults == BackendFault.NONE
    backend.emulator.faults.frozen = True
    cycles = 0
    while not frame.faults & BackendFault.LINK_LOST:
        backend.read(frame)
        clock.advance(backend.period_ns)
        cycles += 1
        assert cycles <= 40
    consumer = bench_cfg["canopen"]["heartbeat_consumer_ms"]
    producer = bench_cfg["canopen"]["heartbeat_producer_ms"]
    assert consumer - producer <= cycles <= consumer + 1     # timed from the last heartbeat seen
    assert backend.counters()["heartbeat_timeouts"] == 1
    backend.close()


def test_a_single_lost_tpdo_holds_the_sample_and_is_counted(bench_cfg):
    clock = SimClock()
    backend = open_backend(bench_cfg, clock)
    frame = SensorFrame()
    read_cycles(backend, frame, 5)
    seq = frame.seq
    backend.emulator.faults.drop_tpdos = 1
    backend.read(frame)
    assert frame.seq == seq and frame.faults == BackendFault.NONE
    backend.read(frame)
    assert frame.seq == seq + 1
    assert backend.counters()["tpdo_missed"] == 1 and backend.emulator.counts["tpdo_dropped"] == 1
    backend.close()


# -- commands and scheduled injection --------------------------------------------------------------

def test_canbus_load_command_prints_the_table_and_refuses_too_fast_a_rate(capsys):
    from ankle_rt.cli import main

    assert main(["canbus-load", "--config", str(ROOT / "config" / "hw-canopen.yaml")]) == 0
    out = capsys.readouterr().out
    assert "TxPDO1_node1" in out and "bus load 40.6 %" in out
    assert main(["canbus-load", "--config", str(ROOT / "config" / "hw-canopen.yaml"), "--rate", "2000"]) == 2
    assert "controller.rate_hz" in capsys.readouterr().err


def test_emulate_refuses_the_in_process_virtual_bus_and_bad_schedules(capsys):
    from ankle_rt.cli import main

    assert main(["emulate", "--transport", "canopen", "--config", str(BENCH)]) == 2
    assert "virtual bus exists only inside one process" in capsys.readouterr().err
    assert main(["emulate", "--transport", "canopen", "--config", str(BENCH), "--interface", "socketcan",
                 "--inject", "melt@1"]) == 2
    assert "unknown fault 'melt'" in capsys.readouterr().err


def test_scheduled_injection_follows_plant_time(bench_cfg):
    clock = SimClock()
    backend = open_backend(bench_cfg, clock)
    backend.emulator.schedule = [parse_schedule("sg_rail_1@0.010:0.020", NODE_FAULTS)]
    frame = SensorFrame()
    rail = []
    for _ in range(30):
        backend.read(frame)
        rail.append(bool(frame.faults & BackendFault.STRAIN_GAUGE_RAIL))
        clock.advance(backend.period_ns)
    assert rail == [False] * 10 + [True] * 10 + [False] * 10
    backend.close()


def test_node_zeroes_its_outputs_when_set_values_stop_and_reports_it(bench_cfg):
    """RPDO deadline monitoring (0x1400 sub5 = canopen.rpdo_timeout_ms): a master that stops sending
    set values while the amplifiers are enabled gets safe outputs from the node and an EMCY."""
    clock = SimClock()
    backend = open_backend(bench_cfg, clock)
    emu = backend.emulator
    assert emu.node.sdo[0x1400][5].raw == bench_cfg["canopen"]["rpdo_timeout_ms"] == 5
    frame = SensorFrame()
    backend.activate()
    for _ in range(10):
        backend.read(frame)
        backend.write(2.0, 2.0)
        clock.advance(backend.period_ns)
    silent = 0
    while emu.amplifier_currents() != (0.0, 0.0):     # the loop hangs: SYNCs go on, no RPDO
        backend.read(frame)
        clock.advance(backend.period_ns)
        silent += 1
        assert silent <= 10
    assert silent == 6 and emu.counts["rpdo_timeouts"] == 1     # deadline 5 ms after the last RPDO
    assert emu.outputs[DIGITAL_OUT] == 0
    backend.read(frame)
    assert frame.faults & BackendFault.DEVICE_FAULT and backend.counters()["emcy"] == 1
    backend.deactivate()                                # the daemon goes safe; RPDOs flow again
    backend.read(frame)
    clock.advance(backend.period_ns)
    backend.read(frame)
    assert not frame.faults & BackendFault.DEVICE_FAULT and backend.counters()["emcy"] == 2   # error reset
    backend.close()


def test_a_node_that_reboots_loses_its_configuration_and_is_a_device_fault(bench_cfg):
    clock = SimClock()
    backend = open_backend(bench_cfg, clock)
    frame = SensorFrame()
    backend.read(frame)
    assert frame.faults == BackendFault.NONE
    backend.node.nmt.send_command(0x81)                 # reset node (a power glitch does the same)
    backend.read(frame)
    assert frame.faults & BackendFault.DEVICE_FAULT
    assert backend.emulator.node.sdo[0x1017].raw == 0   # back to the EDS defaults
    for _ in range(30):                                 # no heartbeat any more: the link is lost too
        clock.advance(backend.period_ns)
        backend.read(frame)
    assert frame.faults & BackendFault.LINK_LOST
    backend.close()


def test_standalone_emulator_serves_a_backend_on_the_real_clock(bench_cfg):
    """The bench's two-computer set-up in one process: the emulator serving in a thread of its own
    (real-time heartbeats), the backend on the monotonic clock configuring it over SDO with its
    Notifier. No timing is asserted: only that configuration works against an asynchronous node
    and that samples flow."""
    import threading
    import time

    from ankle_rt.clock import MonotonicClock
    from hardware.emulators.canopen_emulator import CanopenEmulator

    channel = bench_cfg["canopen"]["channel"]
    bench_cfg["canopen"]["tpdo_wait_us"] = 2000
    emulator = CanopenEmulator(bench_cfg, can.Bus(interface="virtual", channel=channel), str(DEFAULT_EDS),
                               realtime=True)
    serving = threading.Thread(target=emulator.serve, args=(3.0,), daemon=True)
    backend_bus = can.Bus(interface="virtual", channel=channel)
    def reaches(state: str) -> bool:          # the node handles frames in its own thread
        for _ in range(200):
            if emulator.state == state:
                return True
            time.sleep(0.01)
        return False

    serving.start()
    try:
        backend = CanopenBackend(bench_cfg, MonotonicClock(), bus=backend_bus)
        assert reaches("OPERATIONAL")
        frame = SensorFrame()
        for _ in range(50):
            backend.read(frame)
            time.sleep(0.002)                 # the loop sleeps until its next deadline
        assert frame.seq > 0 and backend.counters()["tpdo_received"] > 0
        backend.close()
        assert reaches("PRE-OPERATIONAL")
    finally:
        serving.join()
        emulator.close()
