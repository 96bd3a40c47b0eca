"""The log writer's tap (what the Lab Streaming Layer publisher hangs on): it sees every record once,
in order, across the ring's wrap; a tap that fails is dropped with its reason and the log goes on;
and the LSL publisher turns state changes, faults and gait-phase changes into markers (with a real
inlet)."""

from __future__ import annotations

import uuid

import numpy as np
import pytest

from ankle_rt.log.lsl import CHANNELS
from ankle_rt.log.reader import read_log
from ankle_rt.log.record import RECORD_SIZE
from ankle_rt.log.writer import LogWriter
from ankle_rt.safety import Fault, State



def record(k: int, state: int = State.ACTIVE, fault: int = Fault.NONE, gait_phase: int = 0) -> tuple:
    return (k * 1e-3, *[float(k)] * (len(CHANNELS) - 2), k * 1e-3, k, 1000.0, 50.0, 0, state, fault, 0, gait_phase)


class Collecting:
    """A tap that keeps the loop_time of every record it is handed; fails on call ``fail_at``."""

    def __init__(self, fail_at: int = -1):
        self.error = ""
        self.opened = self.closed = 0
        self.loop_times: list[float] = []
        self.calls = 0
        self.fail_at = fail_at

    def open(self):
        self.opened += 1

    def publish(self, chunk):
        self.calls += 1
        if self.calls == self.fail_at:
            raise RuntimeError("the lab network is gone")
        values = np.ndarray((len(chunk) // RECORD_SIZE, len(CHANNELS)), "<f8", chunk, 0, (RECORD_SIZE, 8))
        self.loop_times.extend(values[:, CHANNELS.index("loop_time")])

    def close(self):
        self.closed += 1


def test_the_tap_sees_every_record_once_in_order_across_the_wrap(tmp_path):
    tap = Collecting()
    writer = LogWriter(tmp_path / "a.arlog", {}, capacity=256, flush_interval_s=3600.0, tap=tap)
    for k in range(1000):     # about four times round the ring; flushed here (as the thread does) and by close()
        writer.append(*record(k))
        if k % 100 == 99:
            writer._flush()   # as the thread would: the ring must not overflow in this test
    writer.close()
    assert tap.opened == 1 and tap.closed == 1 and not tap.error
    assert tap.loop_times == [k * 1e-3 for k in range(1000)]
    assert len(read_log(tmp_path / "a.arlog").records) == 1000


def test_a_failing_tap_is_dropped_and_the_log_goes_on(tmp_path):
    tap = Collecting(fail_at=2)
    writer = LogWriter(tmp_path / "b.arlog", {}, capacity=256, flush_interval_s=3600.0, tap=tap)
    for k in range(300):
        writer.append(*record(k))
        if k % 100 == 99:
            writer._flush()
    writer.close()
    assert tap.error == "RuntimeError: the lab network is gone" and tap.closed == 1 and tap.calls == 2
    assert len(tap.loop_times) == 100 and writer.tap is None
    log = read_log(tmp_path / "b.arlog").records
    assert len(log) == 300 and writer.status()["state"] == "closed"


def test_state_changes_faults_and_gait_phases_become_markers(tmp_path):
    pylsl = pytest.importorskip("pylsl", reason="pylsl is not installed (pip install 'ankle-rt[lab]')")
    from ankle_rt.control.gait_phase import EARLY_STANCE, EARLY_SWING, PHASE_NAMES, SAFE
    from ankle_rt.log.lsl import LslPublisher

    source_id = f"ankle-rt-test-{uuid.uuid4().hex[:8]}"
    publisher = LslPublisher(1000.0, source_id, lambda: 100.0, {s.name: int(s) for s in State},
                             {f.name: int(f) for f in Fault}, phases=PHASE_NAMES)
    publisher.open()
    try:
        found = pylsl.resolve_byprop("source_id", source_id + "-events", minimum=1, timeout=30.0)
        inlet = pylsl.StreamInlet(found[0])
        inlet.open_stream(timeout=30.0)
        writer = LogWriter(tmp_path / "c.arlog", {}, capacity=256, flush_interval_s=3600.0)   # its ring only
        states = [State.CONFIGURED] * 3 + [State.ACTIVE] * 5 + [State.FAULT] * 4 + [State.SAFE] * 3
        faults = [Fault.NONE] * 8 + [Fault.MISSED_DEADLINES] * 7
        phases = [0] * 3 + [1 + SAFE] * 2 + [1 + EARLY_STANCE] * 2 + [1 + EARLY_SWING] * 8   # the log's codes
        for k, (state, fault, phase) in enumerate(zip(states, faults, phases)):
            writer.append(*record(k, state, fault, phase))
        half = 6 * RECORD_SIZE
        publisher.publish(writer.ring.view[:half])        # two flushes: a change at the boundary counts too
        publisher.publish(writer.ring.view[half:len(states) * RECORD_SIZE])
        writer.close()
        markers, stamps = [], []
        for _ in range(100):
            got, ts = inlet.pull_chunk(timeout=0.2)
            markers += [m[0] for m in got]
            stamps += ts
            if len(markers) >= 8:
                break
    finally:
        publisher.close()
    assert markers == ["state:configured", "state:active", "gait_phase:safe", "gait_phase:early_stance",
                       "gait_phase:early_swing", "fault:missed_deadlines", "state:fault", "state:safe"]
    assert stamps == pytest.approx([100.0, 100.003, 100.003, 100.005, 100.007, 100.008, 100.008, 100.012])
    assert publisher.samples == len(states) and publisher.events == 8


def test_without_pylsl_the_daemon_refuses_to_start_naming_the_key(sim_cfg, tmp_path, monkeypatch):
    import ankle_rt.log.lsl as lsl
    from ankle_rt.clock import MonotonicClock
    from ankle_rt.config import ConfigError
    from ankle_rt.daemon import Daemon

    monkeypatch.setattr(lsl, "pylsl_available", lambda: False)
    sim_cfg["lsl"]["enabled"] = True
    daemon = Daemon(sim_cfg, MonotonicClock())
    try:
        with pytest.raises(ConfigError, match=r"lsl.enabled: lsl.enabled needs pylsl: pip install 'ankle-rt\[lab\]'"):
            daemon.open_log(tmp_path / "x.arlog")
        assert daemon.recorder is None and not (tmp_path / "x.arlog").exists()
    finally:
        daemon.close()


def test_config_check_says_the_streams_and_whether_pylsl_is_there(tmp_path, capsys, monkeypatch):
    import ankle_rt.log.lsl as lsl
    from ankle_rt.cli import main
    from tests.conftest import SIM_CONFIG

    cfg = tmp_path / "lab.yaml"
    cfg.write_text(f"include: [{SIM_CONFIG}]\nlsl: {{enabled: true, source_id: left-ankle}}\n")
    monkeypatch.setattr(lsl, "pylsl_available", lambda: True)
    assert main(["config", "check", str(cfg)]) == 0
    assert "lsl:         streams ankle-rt and ankle-rt-events (source_id left-ankle) in real time\n" \
        in capsys.readouterr().out
    monkeypatch.setattr(lsl, "pylsl_available", lambda: False)
    assert main(["config", "check", str(cfg)]) == 0
    assert "pylsl is NOT installed here: pip install 'ankle-rt[lab]'" in capsys.readouterr().out
    assert main(["config", "check", str(SIM_CONFIG)]) == 0
    assert "lsl:" not in capsys.readouterr().out
