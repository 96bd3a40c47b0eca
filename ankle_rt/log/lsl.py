"""The daemon's cycle records and events on the Lab Streaming Layer (``lsl.enabled``, docs/lab.md).

Two outlets: ``ankle-rt`` (type ``ankle-rt``, one double channel per log record field, labels, units and
meanings in the stream's ``desc/channels``, the nominal rate = the loop's) and ``ankle-rt-events``
(type ``Markers``, one string channel: ``state:active``, ``fault:missed_deadlines``, ...). Each
sample is stamped with its cycle's start on the loop clock (CLOCK_MONOTONIC, which is LSL's
``local_clock()`` on Linux), so LabRecorder aligns it with motion capture, force plates and EMG.

The log writer's thread drives it (:class:`~ankle_rt.log.writer.LogWriter`'s ``tap``): the outlets are
made in that thread (liblsl's own threads then inherit its normal scheduling, never the loop's
SCHED_FIFO) and every flush pushes the new records as one chunk. Nothing here runs in the loop.
"""

from __future__ import annotations

import importlib.util
import socket
from typing import Any, Callable, Mapping

import numpy as np

from ankle_rt.log.record import FIELDS

STREAM_NAME = "ankle-rt"
EVENTS_NAME = "ankle-rt-events"
CHANNELS: tuple[str, ...] = tuple(name for name, *_ in FIELDS)
"""One channel per log record field, in the record's order (docs/design.md)."""


class LslUnavailable(RuntimeError):
    """``lsl.enabled`` but pylsl cannot be imported."""


def pylsl_available() -> bool:
    """True when pylsl is installed (its wheel bundles liblsl)."""
    return importlib.util.find_spec("pylsl") is not None


class LslPublisher:
    """The two outlets of one run. ``origin_s()``: the loop start on the loop clock (s), to which a
    record's ``loop_time`` is added; ``states`` and ``faults``: code names (the log header's)."""

    def __init__(self, rate_hz: float, source_id: str, origin_s: Callable[[], float],
                 states: Mapping[str, int], faults: Mapping[str, int], info: Mapping[str, str] | None = None):
        if not pylsl_available():
            raise LslUnavailable("lsl.enabled needs pylsl: pip install 'ankle-rt[lab]' (or pip install pylsl)")
        self.rate_hz = rate_hz
        self.source_id = source_id
        self.origin_s = origin_s
        self.state_names = {code: name.lower() for name, code in states.items()}
        self.fault_names = {code: name.lower() for name, code in faults.items()}
        self.info = dict(info or {})
        self.outlet: Any = None
        self.markers: Any = None
        self.samples = 0          # records pushed
        self.events = 0           # markers pushed
        self.error = ""           # why publishing stopped ("" while it works)
        self._state = -1          # the last record's state and fault codes (-1: none seen yet)
        self._fault = 0

    def open(self) -> None:
        """Make the outlets (in the log writer's thread, at its normal scheduling)."""
        import pylsl

        from ankle_rt.log.record import UNITS, field_doc

        info = pylsl.StreamInfo(STREAM_NAME, "ankle-rt", len(CHANNELS), self.rate_hz, pylsl.cf_double64,
                                self.source_id)
        desc = info.desc()
        desc.append_child_value("manufacturer", "ankle-rt")
        desc.append_child_value("hostname", socket.gethostname())
        for key, value in self.info.items():
            desc.append_child_value(key, value)
        channels = desc.append_child("channels")
        for name in CHANNELS:
            channel = channels.append_child("channel")
            channel.append_child_value("label", name)
            channel.append_child_value("unit", UNITS[name])
            channel.append_child_value("type", "ankle-rt")
            channel.append_child_value("description", field_doc(name))
        self.outlet = pylsl.StreamOutlet(info)
        events = pylsl.StreamInfo(EVENTS_NAME, "Markers", 1, pylsl.IRREGULAR_RATE, pylsl.cf_string,
                                  self.source_id + "-events")
        self.markers = pylsl.StreamOutlet(events)

    def publish(self, records: np.ndarray) -> None:
        """Push ``records`` (RECORD_DTYPE, oldest first) as one chunk, then the events they hold."""
        if self.outlet is None or len(records) == 0:
            return
        stamps = self.origin_s() + records["loop_time"]
        self.outlet.push_chunk(np.column_stack([records[name].astype(np.float64) for name in CHANNELS]),
                               stamps.tolist())
        self.samples += len(records)
        for stamp, marker in self._events(records["state"], records["fault"], stamps):
            self.markers.push_sample([marker], stamp)
            self.events += 1

    def _events(self, states: np.ndarray, faults: np.ndarray, stamps: np.ndarray) -> list[tuple[float, str]]:
        """(time, marker) of every state change and every new fault in these records."""
        state = np.concatenate(([self._state], states.astype(np.int64)))
        fault = np.concatenate(([self._fault], faults.astype(np.int64)))
        out = []
        for i in np.flatnonzero((state[1:] != state[:-1]) | ((fault[1:] != fault[:-1]) & (fault[1:] != 0))):
            if fault[i + 1] != fault[i] and fault[i + 1] != 0:
                out.append((float(stamps[i]), f"fault:{self.fault_names.get(int(fault[i + 1]), fault[i + 1])}"))
            if state[i + 1] != state[i]:
                out.append((float(stamps[i]), f"state:{self.state_names.get(int(state[i + 1]), state[i + 1])}"))
        self._state, self._fault = int(state[-1]), int(fault[-1])
        return out

    def status(self) -> dict[str, Any]:
        """For ``ctl status``: the streams, what went out, and why publishing stopped if it did."""
        return {"stream": STREAM_NAME, "events_stream": EVENTS_NAME, "samples": self.samples,
                "events": self.events, "error": self.error or None}

    def close(self) -> None:
        """Drop the outlets (inlets see the streams end)."""
        self.outlet = self.markers = None
