"""Issue 10 item 7: malformed CAN frames never raise out of the emulator or the backend."""

from __future__ import annotations

import itertools

import can
import pytest

from ankle_rt.backend import SensorFrame, open_backend
from ankle_rt.clock import SimClock
from tests.conftest import ROOT
from tests.hw_helpers import bench_config, read_cycles

_channels = itertools.count()


@pytest.fixture
def backend():
    cfg = bench_config(ROOT / "config" / "bench-canopen.yaml")
    cfg["canopen"]["channel"] = f"test-canopen-frames-{next(_channels)}"
    b = open_backend(cfg, SimClock())
    yield b
    b.close()


@pytest.mark.parametrize("cob, data", [(0x000, b""), (0x000, b"\x01"), ("sdo", b""), ("sdo", b"\x40")],
                         ids=["nmt-dlc0", "nmt-dlc1", "sdo-dlc0", "sdo-dlc1"])
def test_short_nmt_and_sdo_frames_are_dropped_and_counted(backend, cob, data):
    emu = backend.emulator
    cob = 0x600 + emu.node_id if cob == "sdo" else cob
    emu._handle(can.Message(arbitration_id=cob, data=data, is_extended_id=False))   # raised struct.error before
    assert emu.counts["bad_frames"] == 1
    frame = SensorFrame()
    read_cycles(backend, frame, 3)                   # the node still runs
    assert emu.state == "OPERATIONAL" and frame.faults == 0


def test_a_tpdo_whose_length_field_lies_is_counted_not_unpacked(backend):
    frame = SensorFrame()
    read_cycles(backend, frame, 2)
    cob = next(iter(backend._tpdo_by_cob))
    size = backend._tpdo_by_cob[cob][2]
    liar = can.Message(arbitration_id=cob, data=b"\x01\x02", dlc=size, is_extended_id=False, check=False)
    assert liar.dlc == size and len(liar.data) == 2
    backend.emulator.bus.send(liar)                  # the node's side of the virtual bus
    before = backend.counters()["bad_length"]
    backend.read(frame)                              # raised struct.error before
    assert backend.counters()["bad_length"] == before + 1
