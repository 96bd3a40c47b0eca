"""Serial transport end to end: the daemon's serial backend against the bridge emulator on a pty pair,
in lockstep. The section 7 experiment against the direct simulated backend, fault injection through
the daemon's safety (detection time, reason, safe outputs, resume after reset), the bridge watchdog,
link budget and configuration errors."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ankle_rt.backend import BackendError, BackendFault, SensorFrame, open_backend
from ankle_rt.clock import SimClock
from ankle_rt.config import Config, ConfigError
from ankle_rt.daemon import run_lockstep
from ankle_rt.safety import Fault, State
from hardware.serial_backend import SerialBackend
from hardware.emulators.serial_emulator import CORES, BridgeEmulator, LockstepLink, open_lockstep
from hardware.serial_protocol import PAYLOADS, MsgType
from tests.conftest import ROOT
from tests.hw_helpers import Bench, QuantisedSimBackend, bench_config, config_copy, sim_copy

BENCH = ROOT / "config" / "bench-serial.yaml"


@pytest.fixture
def bench_cfg() -> Config:
    """A private copy of config/bench-serial.yaml."""
    return bench_config(BENCH)


@pytest.fixture(params=CORES)
def core(request) -> str:
    """The bridge firmware core behind the emulated board: the Python reference, or the firmware's
    C core compiled natively (firmware in the loop). Every test taking it runs against both."""
    return request.param


def open_bench(cfg: Config, clock: SimClock, core: str) -> SerialBackend:
    """The serial backend against the lockstep emulator with firmware ``core``."""
    return SerialBackend(cfg, clock, port=open_lockstep(cfg, core))


def test_section7_through_the_serial_bridge_matches_the_direct_simulation(bench_cfg):
    """Tolerance. The only difference the transport may add is the 12-bit set value: +/-15 A over
    4096 codes is 7.32 mA (12 mN m of motor torque) per code, so a set value is off by at most
    3.7 mA. Under kp = 90 N m/rad that is a static motor offset of 6e-3 / 90 = 7e-5 rad, 1.3 encoder
    counts (5.4e-5 rad each); encoder quantisation and stick-slip in the friction band turn it into
    a few counts, so motors within 5 counts (2.7e-4 rad) and ankles (R^-1: x0.11 DP, x0.2 IE, plus
    the bench's 12 µrad joint-encoder count) within 1e-4 rad = 0.006 deg on the 10 deg / 5 deg step.
    With the same quantisation applied to the direct backend, motors and set values agree to
    floating-point rounding: nothing else differs."""
    duration = 3.5
    direct = run_lockstep(sim_copy(bench_cfg), duration)
    backend = SerialBackend(bench_cfg, SimClock())
    via = run_lockstep(bench_cfg, duration, backend=backend)
    counters = backend.counters()
    backend.close()
    assert direct.summary["fault"] == via.summary["fault"] == "NONE"
    assert len(via) == len(direct) and np.allclose(direct["t"], via["t"], rtol=0, atol=1e-12)
    count = 2 * math.pi / bench_cfg["actuator"]["encoder_counts_per_rev"]
    for k in ("motor_pos_1", "motor_pos_2"):
        assert np.max(np.abs(direct[k] - via[k])) <= 5 * count, k
    for k in ("ankle_dp", "ankle_ie", "est_ankle_dp", "est_ankle_ie"):   # joint encoders / estimate
        assert np.max(np.abs(direct[k] - via[k])) < 1e-4, k
    assert abs(via["ankle_dp"][-1] - math.radians(10)) < math.radians(0.5)    # the step was tracked
    assert abs(via["ankle_ie"][-1] - math.radians(5)) < math.radians(0.5)
    assert counters["samples"] == len(via) and counters["crc_errors"] == counters["frames_lost"] == 0

    quantised = run_lockstep(sim_copy(bench_cfg), duration,
                             backend=QuantisedSimBackend(sim_copy(bench_cfg), SimClock(), backend.amps))
    for k in ("motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2"):
        assert np.max(np.abs(quantised[k] - via[k])) < 1e-9, k


def test_section7_through_the_firmware_c_core_is_the_python_emulator_run(bench_cfg):
    """Firmware in the loop: the same run with the bridge firmware's C core (compiled natively) in place
    of the Python one, the plant side unchanged. Both send the same codes, so nothing is left to
    quantisation: every logged value is equal, bit for bit (loop timing is simulated too)."""
    runs, counters = [], []
    for core in CORES:
        backend = open_bench(config_copy(bench_cfg), SimClock(), core)
        runs.append(run_lockstep(bench_cfg, 3.5, backend=backend))
        counters.append(backend.counters())
        backend.close()
    python, c = runs
    assert c.summary["fault"] == "NONE" and counters[0] == counters[1]
    for k in python.records.dtype.names:
        assert np.array_equal(python[k], c[k], equal_nan=True), k
    assert abs(c["ankle_dp"][-1] - math.radians(10)) < math.radians(0.5)


# -- fault injection through the daemon's safety ---------------------------------------------------

# (fault, expected reason, stated detection time in cycles: 1 = safe in the cycle whose sample shows
# the fault). Lockstep: the bridge takes the sample a cycle reads when it gets the previous cycle's
# command, so the sample in flight when a fault is injected predates it: the test allows that cycle.
FAULTS = [
    ("stuck_encoder_1", Fault.ENCODER_FAULT, 10),   # encoders.stuck_time = 10 ms out of balance
    ("sg_rail_2", Fault.SG_RAIL, 1),
    ("not_ready_1", Fault.AMP_NOT_READY, 1),
    ("stale", Fault.SENSOR_STALE, 1),                # the bridge's time stopped: STALE_SAMPLE
    ("frozen", Fault.LINK_LOST, 3),                  # serial.link_timeout_s = 3 ms
    ("drop", Fault.LINK_LOST, 3),
    ("corrupt", Fault.LINK_LOST, 3),
]


@pytest.mark.parametrize("name, expected, within", FAULTS, ids=[f[0] for f in FAULTS])
def test_injected_fault_goes_safe_in_time_and_resumes_after_reset(core, bench_cfg, name, expected, within):
    bench = Bench(bench_cfg, lambda cfg, clock: open_bench(cfg, clock, core))
    emu = bench.emu
    try:
        bench.run_into_the_step()                            # the motors work when the fault comes
        emu.inject(name)
        took = bench.cycles_until_safe(within + 10)
        assert took <= 1 + within
        assert bench.daemon.safety.fault == expected
        bench.cycles(1)
        if name == "frozen":       # a hung bridge applies nothing: its (hardware) watchdog makes it safe
            bench.cycles(round(bench_cfg["serial"]["watchdog_s"] * bench_cfg["controller"]["rate_hz"]))
        assert emu.codes == [a.zero_code for a in emu.amps] and emu.amplifier_currents() == (0.0, 0.0)
        bench.assert_latched(expected)
        emu.inject(name, on=False)
        bench.cycles(10)
        bench.reset_and_resume()                             # the amplifiers drive what the daemon sends
        assert emu.outputs_enabled() and emu.amplifier_currents() == tuple(bench.backend.sent)
    finally:
        bench.close()


def run_frames(backend, n, frame=None):
    """``n`` cycles of read + zero write on the backend's SimClock: [(seq, faults)]."""
    frame = frame or SensorFrame()
    out = []
    for _ in range(n):
        backend.read(frame)
        out.append((frame.seq, frame.faults))
        backend.write(0.0, 0.0)
        backend.clock.advance(backend.period_ns)
    return out


def test_single_lost_or_corrupted_samples_are_counted_and_tolerated(core, bench_cfg):
    """One sample dropped, the next one corrupted: the frame holds the last sample (the daemon's
    safety.stale_cycles bounds how long), the CRC error and the gap are reported once and counted."""
    backend = open_bench(bench_cfg, SimClock(), core)
    emu = backend.emulator
    frame = SensorFrame()
    seq = run_frames(backend, 5, frame)[-1][0]
    emu.inject("drop")
    seen = run_frames(backend, 1, frame)          # this cycle's command makes the bridge drop a sample
    emu.inject("drop", on=False)
    emu.inject("corrupt")
    seen += run_frames(backend, 1, frame)         # ... and this one's a corrupted sample
    emu.inject("corrupt", on=False)
    seen += run_frames(backend, 3, frame)
    assert seen == [(seq + 1, BackendFault.NONE),          # a normal sample
                    (seq + 1, BackendFault.NONE),          # nothing arrived: the sample is held
                    (seq + 1, BackendFault.CRC_ERROR),     # the corrupted one was dropped
                    (seq + 4, BackendFault.SEQUENCE_GAP),  # the next good one shows the two lost
                    (seq + 5, BackendFault.NONE)]
    c = backend.counters()
    assert c["crc_errors"] == 1 and c["frames_lost"] == 2 and c["cycles_without_sample"] == 2
    assert c["link_lost"] == 0
    backend.close()


def test_bridge_watchdog_zeroes_outputs_when_commands_stop(core, bench_cfg):
    """Free-running bridge ticks without commands: after serial.watchdog_s the set values are zero,
    the enables off, and the host sees the bridge's watchdog status as a device fault."""
    backend = open_bench(bench_cfg, SimClock(), core)
    emu = backend.emulator
    backend.activate()
    frame = SensorFrame()
    backend.read(frame)
    backend.write(3.0, -3.0)
    assert emu.amplifier_currents()[0] == pytest.approx(3.0, abs=emu.amps[0].current_lsb)
    watchdog_ticks = round(bench_cfg["serial"]["watchdog_s"] * bench_cfg["controller"]["rate_hz"])
    currents = []
    for _ in range(watchdog_ticks + 2):          # the bridge's own clock; the host stays silent
        emu.tick()
        currents.append(emu.amplifier_currents()[0])
    assert currents[watchdog_ticks - 2] > 2.9 and currents[watchdog_ticks] == 0.0
    backend.read(frame)
    assert frame.faults & BackendFault.DEVICE_FAULT and backend.counters()["watchdog_trips"] == 1
    backend.close()


def test_link_lost_when_the_port_fails(core, bench_cfg):
    backend = open_bench(bench_cfg, SimClock(), core)
    run_frames(backend, 3)
    backend.port.port.close()                    # the device vanished
    frame = SensorFrame()
    backend.read(frame)
    assert frame.faults & BackendFault.LINK_LOST and backend.counters()["port_errors"] >= 1
    backend.port.close()


def test_configuration_errors_name_the_key(bench_cfg, tmp_path):
    cfg = config_copy(bench_cfg)
    cfg.source = "bench.yaml"
    cfg["serial"]["baudrate"] = 460800
    with pytest.raises(ConfigError, match=r"bench.yaml: serial.baudrate: 460800 bit/s is too slow.*102%"):
        open_backend(cfg, SimClock())
    cfg["serial"]["baudrate"] = 2_000_000
    cfg["serial"]["link_timeout_s"] = 0.0015
    with pytest.raises(ConfigError, match=r"serial.link_timeout_s: must be at least two periods \(0.002 s\)"):
        open_backend(cfg, SimClock())
    cfg["serial"]["link_timeout_s"] = 0.003
    cfg["escon"]["amplifiers"] = None
    with pytest.raises(ConfigError, match=r"escon.amplifiers: missing"):
        open_backend(cfg, SimClock())


def test_a_bridge_that_cannot_do_the_configuration_is_refused(core, bench_cfg):
    device = config_copy(bench_cfg)
    device["encoders"]["counter_bits"] = 32            # the bridge has 32-bit counters, the host says 16
    link = LockstepLink(BridgeEmulator(device, core=core))
    with pytest.raises(BackendError, match=r"refused its configuration.*encoders.counter_bits"):
        SerialBackend(bench_cfg, SimClock(), port=link)
    link.close()


def test_no_bridge_on_the_port(bench_cfg):
    master, slave = os.openpty()                 # a serial line with nobody at the other end
    try:
        bench_cfg["serial"].update(emulator="none", port=os.ttyname(slave), open_timeout_s=0.05)
        with pytest.raises(BackendError, match=r"did not acknowledge its configuration within 0.05 s"):
            open_backend(bench_cfg, SimClock())
        bench_cfg["serial"]["port"] = "/nonexistent/tty"
        with pytest.raises(BackendError, match=r"cannot open /nonexistent/tty"):
            open_backend(bench_cfg, SimClock())
    finally:
        os.close(master)
        os.close(slave)


def test_16_bit_counters_unwrap_end_to_end_and_a_negative_start_reads_negative(core, bench_cfg):
    assert bench_cfg["encoders"]["counter_bits"] == 16
    emu = BridgeEmulator(bench_cfg, core=core)
    emu.plant.model.set_rest_at((0.0, 0.1))                  # motor 2 starts at -0.25 rad: counter near 2^16
    backend = SerialBackend(bench_cfg, SimClock(), port=LockstepLink(emu))
    rad = 2 * math.pi / bench_cfg["actuator"]["encoder_counts_per_rev"]
    frame = SensorFrame()
    backend.activate()
    travelled = [0, 0]
    last = emu.plant.encoder_counts()
    for k in range(400):
        backend.read(frame)
        truth = emu.plant.encoder_counts()                   # the plant has not stepped since the sample
        assert (frame.motor_pos[0], frame.motor_pos[1]) == (truth[0] * rad, truth[1] * rad), k
        travelled = [t + abs(c - p) for t, c, p in zip(travelled, truth, last)]
        last = truth
        backend.write(15.0 if k < 200 else -15.0, -15.0 if k < 200 else 15.0)
        backend.clock.advance(backend.period_ns)
    assert min(travelled) > 3 * 2**16                        # each counter wrapped several times
    assert frame.faults == BackendFault.NONE
    backend.close()


def test_pwm_set_values_reach_the_amplifiers(core, bench_cfg):
    for amp in bench_cfg["escon"]["amplifiers"]:
        amp.update(mode="pwm", current_at_min=-15.0, current_at_max=15.0)
    backend = open_bench(bench_cfg, SimClock(), core)
    emu = backend.emulator
    assert emu.modes == 0b11 and backend.zero_codes == (5000, 5000)
    frame = SensorFrame()
    backend.read(frame)
    backend.activate()
    for i1, i2 in ((2.0, -1.0), (-14.9, 14.9), (40.0, -40.0)):
        backend.write(i1, i2)
        lsb = emu.amps[0].current_lsb
        assert emu.amplifier_currents() == pytest.approx((max(-15, min(15, i1)), max(-15, min(15, i2))), abs=lsb / 2)
        backend.read(frame)
    backend.deactivate()
    assert emu.codes == [5000, 5000] and emu.amplifier_currents() == (0.0, 0.0)
    backend.close()


def test_a_new_configuration_restarts_the_sample_time(core, bench_cfg):
    clock = SimClock()
    first = open_bench(bench_cfg, clock, core)
    run_frames(first, 50)
    second = SerialBackend(bench_cfg, clock, port=first.port)   # the daemon restarts on the same link
    frame = SensorFrame()
    second.read(frame)
    assert frame.t == 0.0 and first.emulator.plant.ticks == 50
    second.close()


def test_emulate_standalone_on_a_pty_serves_a_daemon_in_another_process(core, bench_cfg, tmp_path):
    """`ankle-rt emulate --transport serial --port pty --core ...` in a subprocess, the backend in this
    one. No timing is asserted: only that every command stepped the emulator once and samples came back."""
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "ankle_rt.cli", "emulate", "--transport", "serial",
                             "--config", str(BENCH), "--port", "pty", "--duration", "20", "--core", core],
                            stdout=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line.startswith("emulator: serial bridge on /dev/pts/"), line
        bench_cfg["serial"].update(emulator="none", port=line.split(" on ")[1].split(" ")[0], open_timeout_s=10.0)
        backend = open_backend(bench_cfg, SimClock())
        seen = run_frames(backend, 300)
        counters = backend.counters()
        backend.close()
        assert counters["crc_errors"] == counters["frames_lost"] == 0
        assert counters["samples"] > 0 and seen[-1][0] > seen[0][0]
    finally:
        proc.terminate()
        out, _ = proc.communicate(timeout=10)
    ticks, commands = (int(w) for w in out.rsplit("emulator: ", 1)[1].split()[::2][:2])   # the last line
    # One tick per command that followed a sample; the last commands may still be in the pty when
    # the emulator is stopped, so only bounds: every sample received was a tick, no tick without one.
    assert counters["samples"] - 1 <= ticks <= commands <= 301


def test_emulate_free_running_like_the_real_bridge(core, bench_cfg):
    """`--free-run`: the emulator owns the clock; a real-time host loop reads whatever arrived. Only
    what does not depend on timing is asserted: samples arrive intact and the sample time advances."""
    import subprocess
    import sys

    from ankle_rt.clock import MonotonicClock

    proc = subprocess.Popen([sys.executable, "-m", "ankle_rt.cli", "emulate", "--transport", "serial",
                             "--config", str(BENCH), "--port", "pty", "--free-run", "--duration", "20",
                             "--core", core], stdout=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert f"free-running, {core} core (stops after 20 s" in line, line
        bench_cfg["serial"].update(emulator="none", port=line.split(" on ")[1].split(" ")[0], open_timeout_s=10.0)
        clock = MonotonicClock()
        backend = open_backend(bench_cfg, clock)
        frame = SensorFrame()
        times = []
        deadline = clock.now_ns()
        for _ in range(300):
            deadline += backend.period_ns
            clock.sleep_until(deadline)
            backend.read(frame)
            times.append(frame.t)
            backend.write(0.0, 0.0)
        counters = backend.counters()
        backend.close()
    finally:
        proc.terminate()
        proc.communicate(timeout=10)
    assert counters["crc_errors"] == 0 and counters["samples"] > 0
    assert times[-1] > times[0] and all(b >= a for a, b in zip(times, times[1:]))


def test_a_free_running_emulator_whose_host_left_does_not_hang(bench_cfg):
    """The daemon configures the bridge and leaves; the bridge keeps sampling into a pty nobody reads.
    What the pty cannot take is dropped and the emulator still ends at --duration."""
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "ankle_rt.cli", "emulate", "--transport", "serial",
                             "--config", str(BENCH), "--port", "pty", "--free-run", "--duration", "4"],
                            stdout=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        bench_cfg["serial"].update(emulator="none", port=line.split(" on ")[1].split(" ")[0], open_timeout_s=10.0)
        backend = open_backend(bench_cfg, SimClock())
        run_frames(backend, 10)
        backend.close()
        out, _ = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0 and int(out.rsplit("emulator: ", 1)[1].split()[0]) > 0   # ended, having ticked
    assert "bytes not sent (nobody reading)" in out


def test_emulate_refuses_a_bad_injection(capsys):
    from ankle_rt.cli import main

    assert main(["emulate", "--transport", "serial", "--config", str(BENCH), "--port", "pty",
                 "--inject", "melt@1"]) == 2
    assert "unknown fault 'melt'" in capsys.readouterr().err


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_line_noise_never_crashes_the_backend_nor_yields_a_sample_that_was_not_sent(seed):
    """Random bytes between the frames and random bit flips, through the real pty: every sample the
    backend hands out is bit for bit one the bridge sent, and every intact sample arrives. Both
    firmware cores (the seed picks one)."""
    cfg = bench_config(BENCH)
    cfg["sim"]["seed"] = seed % 2**31
    emu = BridgeEmulator(cfg, core=CORES[seed % 2])
    sent = {}
    send = emu._send_sample

    def recording_send(frame: bytes) -> None:
        fields = PAYLOADS[MsgType.SAMPLE].unpack_from(frame, 7)
        sent[fields[0]] = fields                                        # before the line noise
        send(frame)
    emu._send_sample = recording_send
    emu.inject("noise")
    backend = SerialBackend(cfg, SimClock(), port=LockstepLink(emu))
    frame = SensorFrame()
    backend.activate()
    for k in range(300):
        backend.read(frame)
        if backend.latest is not None:
            assert backend.latest == sent[backend.latest[0]]            # time_us identifies the sample
        backend.write(0.4 * math.sin(k / 20), -0.3)
        backend.clock.advance(backend.period_ns)
    c = backend.counters()
    corrupted = emu.samples_corrupted                    # before close(): its command would tick again
    backend.close()
    assert corrupted > 0 and c["bytes_discarded"] > 0
    assert c["crc_errors"] <= corrupted                  # a flip in the header is garbage, not a CRC error
    assert c["samples"] + c["cycles_without_sample"] == 300
    lost = 300 - c["samples"]                            # only the corrupted ones (the 301st is unread)
    assert corrupted - 1 <= lost <= corrupted


def test_a_scheduled_fault_is_in_the_run_log_with_its_reason(core, bench_cfg, tmp_path):
    """The whole run through run_lockstep: the strain gauge goes to its rail at 1.0 s of plant time.
    The log records the reason and the backend's fault bits from that cycle on, the set values are
    zero and the run ends normally."""
    backend = open_bench(bench_cfg, SimClock(), core)
    backend.emulator.add_schedule("sg_rail_1@1.0")
    res = run_lockstep(bench_cfg, 1.5, backend=backend, log_path=tmp_path / "run.arlog")
    backend.close()
    first = int(np.argmax(res["fault"] != 0))
    assert res["t"][first] == pytest.approx(1.0, abs=1.5e-3) and res["fault"][first] == Fault.SG_RAIL
    assert res["backend_faults"][first] & BackendFault.STRAIN_GAUGE_RAIL
    assert set(res["state"][first:]) <= {State.FAULT, State.SAFE} and not res["current_cmd_1"][first:].any()
    assert res.summary["fault"] == "SG_RAIL" and (tmp_path / "run.arlog").stat().st_size > 0


def test_a_frozen_bridge_holds_its_outputs_until_its_watchdog_and_resumes(core, bench_cfg):
    """Scheduled in plant time: hung from 10 ms to 20 ms. The plant goes on with the outputs as they
    were until the watchdog (5 ms) zeroes them; the host sees no samples (LINK_LOST after 3 ms);
    afterwards samples resume with the plant's time, the first one reporting the watchdog trip."""
    backend = open_bench(bench_cfg, SimClock(), core)
    emu = backend.emulator
    emu.add_schedule("frozen@0.010:0.020")
    backend.activate()
    frame = SensorFrame()
    log = []
    for _ in range(30):
        backend.read(frame)
        log.append((round(frame.t * 1000), frame.faults, emu.amplifier_currents()[0]))
        backend.write(2.0, 2.0)
        backend.clock.advance(backend.period_ns)
    times = [t for t, _, _ in log]
    assert times[:11] == list(range(11)) and times[11:21] == [10] * 10     # nothing new while hung
    assert [f for _, f, _ in log[11:21]] == [BackendFault.NONE] * 2 + [BackendFault.LINK_LOST] * 8
    held = [i for _, _, i in log[11:21]]
    assert held[:5] == pytest.approx([2.0] * 5, abs=0.01) and held[5:] == [0.0] * 5   # watchdog: 5 ms
    assert times[21:] == list(range(21, 30))                                 # resumed in plant time
    assert log[21][1] == BackendFault.DEVICE_FAULT and log[22][1] == BackendFault.NONE
    assert emu.watchdog_resets == 1                                          # the hardware watchdog, once
    assert log[22][2] == pytest.approx(2.0, abs=0.01)
    backend.close()


def test_bridge_numbering_that_jumps_back_is_taken_up_again(bench_cfg):
    """After a restart of the bridge (or more than half the 16-bit sequence lost) the numbering goes
    back: the backend reports it once and follows the new numbering instead of ignoring it forever."""
    backend = open_backend(bench_cfg, SimClock())
    frame = SensorFrame()
    run_frames(backend, 5, frame)
    backend.emulator.core.writer.seq = (backend.last_frame_seq + 40000) % 65536     # Python core
    seen = run_frames(backend, 4, frame)
    assert [f for _, f in seen] == [BackendFault.NONE, BackendFault.SEQUENCE_GAP, BackendFault.NONE,
                                    BackendFault.NONE]
    assert [s for s, _ in seen] == [6, 7, 8, 9] and backend.counters()["seq_resyncs"] == 1
    backend.close()


def test_a_slow_enable_input_is_why_the_set_value_is_zeroed_too(core, bench_cfg):
    """An ESCON may take 8 ms to follow its enable input. Dropping only the enable would leave the
    current on for 8 ticks; deactivate() zeroes the set value as well, so it is off at the next tick."""
    def currents_after(deactivate: bool) -> list[float]:
        emu = BridgeEmulator(bench_cfg, enable_delay_s=0.008, core=core)
        backend = SerialBackend(bench_cfg, SimClock(), port=LockstepLink(emu))
        frame = SensorFrame()
        backend.activate()
        on = []
        for _ in range(15):                                   # enabled after the 8 ms, then driving 3 A
            backend.read(frame)
            backend.write(3.0, 3.0)
            on.append(emu.plant.current[0])
        assert on[:7] == [0.0] * 7 and on[8:] == pytest.approx([3.0] * 7, abs=0.01)
        if deactivate:
            backend.deactivate()
        out = []
        for _ in range(10):
            backend.read(frame)
            if deactivate:
                backend.write(3.0, 3.0)                       # ignored: zero sent while not active
            else:                                             # what a bridge dropping only the enables does
                backend._command(emu.amps[0].code(3.0), emu.amps[1].code(3.0), backend.disabled)
            out.append(emu.plant.current[0])
        backend.close()
        return out

    assert currents_after(deactivate=True) == [0.0] * 10
    only_enable = currents_after(deactivate=False)
    assert only_enable[:7] == pytest.approx([3.0] * 7, abs=0.01) and only_enable[8:] == [0.0, 0.0]
