"""The Lab Streaming Layer output with a real inlet on this machine: a real-time daemon with
``lsl.enabled`` publishes every cycle record (labelled channels, stamped on the loop clock) and its
state changes as markers. Skipped without pylsl (the ``lab`` extra). Timeouts are guards only."""

from __future__ import annotations

import subprocess
import sys
import time
import uuid

import numpy as np
import pytest

from ankle_rt.client import AnkleClient
from ankle_rt.config import ConfigError, load_config
from ankle_rt.log.lsl import CHANNELS, EVENTS_NAME, STREAM_NAME
from ankle_rt.log.reader import read_log
from ankle_rt.log.record import UNITS
from ankle_rt.safety import State
from tests.service_helpers import SIM_CONFIG

pylsl = pytest.importorskip("pylsl", reason="pylsl is not installed (pip install 'ankle-rt[lab]')")

LSL_CONFIG = """\
include: [{sim}]
controller: {{rate_hz: 500}}
safety: {{auto_activate: false}}
reference: {{profile: hold}}
sim: {{disturbances: []}}
loop: {{max_consecutive_overruns: 1000000, realtime: {{spin_us: 0}}}}   # a busy CI machine must not fault it
lsl: {{enabled: true, source_id: {source_id}}}
"""


def _resolve(source_id: str):
    found = pylsl.resolve_byprop("source_id", source_id, minimum=1, timeout=30.0)
    assert found, f"no LSL stream with source_id {source_id}"
    return pylsl.StreamInlet(found[0], max_buflen=60)


def _channel_labels(info) -> list[tuple[str, str]]:
    channel = info.desc().child("channels").child("channel")
    out = []
    while not channel.empty():
        out.append((channel.child_value("label"), channel.child_value("unit")))
        channel = channel.next_sibling()
    return out


def test_a_real_inlet_receives_the_cycles_and_the_markers(tmp_path):
    source_id = f"ankle-rt-test-{uuid.uuid4().hex[:8]}"   # never another run's streams
    cfg = tmp_path / "lsl.yaml"
    cfg.write_text(LSL_CONFIG.format(sim=SIM_CONFIG, source_id=source_id))
    log = tmp_path / "run.arlog"
    sock = tmp_path / "ctl.sock"
    proc = subprocess.Popen([sys.executable, "-m", "ankle_rt.cli", "run", "--config", str(cfg), "--socket", str(sock),
                             "--log", str(log), "--duration", "600", "--no-plot"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        data = _resolve(source_id)
        events = _resolve(source_id + "-events")
        info = data.info(timeout=30.0)
        assert (info.name(), info.type(), info.channel_count(), info.nominal_srate()) == (
            STREAM_NAME, "ankle-rt", len(CHANNELS), 500.0)
        assert _channel_labels(info) == [(name, UNITS[name]) for name in CHANNELS]
        assert events.info(timeout=30.0).name() == EVENTS_NAME and events.info().type() == "Markers"
        data.open_stream(timeout=30.0)
        events.open_stream(timeout=30.0)
        samples, stamps, markers = [], [], []

        def pull(until: float) -> None:
            while time.monotonic() < until:
                chunk, ts = data.pull_chunk(timeout=0.2, max_samples=100000)
                samples.extend(chunk)
                stamps.extend(ts)
                got, mts = events.pull_chunk(timeout=0.0)
                markers.extend(m[0] for m in got)

        pull(time.monotonic() + 0.5)
        with AnkleClient.connect(socket_path=sock, timeout_s=30.0, deactivate_on_exit=False) as ankle:
            ankle.activate(tare_timeout_s=60.0)
            pull(time.monotonic() + 3.0)
            ankle.deactivate()
            pull(time.monotonic() + 0.5)
            ankle.stop()
        proc.communicate(timeout=120)
        pull(time.monotonic() + 1.0)                            # what was still in flight
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0
    got = np.array(samples)
    col = {name: got[:, i] for i, name in enumerate(CHANNELS)}
    logged = read_log(log).records
    window = logged["loop_time"] >= col["loop_time"][0]          # the log's cycles since the inlet connected
    assert logged["loop_time"][window][-1] - col["loop_time"][0] > 3.5
    assert len(got) >= 0.9 * np.count_nonzero(window)
    received = np.isin(logged["loop_time"][window], col["loop_time"])
    assert received.mean() >= 0.9
    row = np.searchsorted(logged["loop_time"], col["loop_time"][len(got) // 2])   # a sample is its log record
    for name in CHANNELS:
        assert col[name][len(got) // 2] == pytest.approx(float(logged[name][row]), nan_ok=True, rel=0, abs=0)
    offset = np.array(stamps) - col["loop_time"]                 # stamped at the cycle start on the loop clock
    assert np.ptp(offset) < 1e-6
    assert abs(offset[-1] + col["loop_time"][-1] - pylsl.local_clock()) < 60.0
    assert "state:active" in markers and "state:safe" in markers
    assert markers.index("state:active") < markers.index("state:safe")
    active = logged["state"] == int(State.ACTIVE)                # ... and the currents only while active
    assert np.any(col["current_cmd_1"] != 0.0) and np.all(logged["current_cmd_1"][~active] == 0.0)


def test_lsl_needs_the_run_log(tmp_path):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(f"include: [{SIM_CONFIG}]\nlsl: {{enabled: true}}\nlogging: {{enabled: false}}\n")
    with pytest.raises(ConfigError, match="lsl.enabled: needs logging.enabled: true"):
        load_config(cfg)
