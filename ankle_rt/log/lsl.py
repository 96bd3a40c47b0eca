"""The daemon's cycle records and events on the Lab Streaming Layer (``lsl.enabled``, docs/lab.md).

Two outlets: ``ankle-rt`` (type ``ankle-rt``, one double channel per physical field of the log record,
:data:`CHANNELS`; labels, units and meanings in the stream's ``desc/channels``; the nominal rate =
the loop's) and ``ankle-rt-events``
(type ``Markers``, one string channel: ``state:active``, ``fault:missed_deadlines``, and with the
gait-phase controller every phase change, ``gait_phase:early_stance``, ...). Each
sample is stamped with its cycle's start on the loop clock (CLOCK_MONOTONIC, which is LSL's
``local_clock()`` on Linux), so LabRecorder aligns it with motion capture, force plates and EMG.

The log writer's thread drives it (:class:`~ankle_rt.log.writer.LogWriter`'s ``tap``): the outlets are
made in that thread (liblsl's own threads then inherit its normal scheduling, never the loop's
SCHED_FIFO) and every flush pushes the new records as one chunk. Nothing here runs in the loop.
"""

from __future__ import annotations

import importlib.util
import socket
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ankle_rt.log.record import RECORD_DTYPE, RECORD_SIZE, UNITS, field_doc

STREAM_NAME = "ankle-rt"
EVENTS_NAME = "ankle-rt-events"


def _leading_doubles() -> tuple[str, ...]:
    """The record's leading float64 fields (t ... loop_time): contiguous in every record, so a chunk
    of records is one strided (n, channels) view, pushed without Python work per value."""
    names = []
    for name in RECORD_DTYPE.names:
        dtype, offset = RECORD_DTYPE.fields[name][:2]
        if dtype != np.dtype("<f8") or offset != 8 * len(names):
            break
        names.append(name)
    return tuple(names)


CHANNELS: tuple[str, ...] = _leading_doubles()
"""The stream's channels: the physical record fields, in the record's order (docs/design.md). The
state and fault are the marker stream; loop timing and counters stay in the run log."""
_LOOP_TIME = CHANNELS.index("loop_time")
_STATE = RECORD_DTYPE.fields["state"][1]
_FAULT = RECORD_DTYPE.fields["fault"][1]
_PHASE = RECORD_DTYPE.fields["gait_phase"][1]


class LslUnavailable(RuntimeError):
    """``lsl.enabled`` but pylsl cannot be imported."""


def pylsl_available() -> bool:
    """True when pylsl is installed (its wheel bundles liblsl)."""
    return importlib.util.find_spec("pylsl") is not None


class LslPublisher:
    """The two outlets of one run. ``origin_s()``: the loop start on the loop clock (s), to which a
    record's ``loop_time`` is added; ``states`` and ``faults``: code names (the log header's);
    ``phases``: the record's ``gait_phase`` names by code (:data:`ankle_rt.control.gait_phase.PHASE_NAMES`)."""

    def __init__(self, rate_hz: float, source_id: str, origin_s: Callable[[], float],
                 states: Mapping[str, int], faults: Mapping[str, int], info: Mapping[str, str] | None = None,
                 phases: Sequence[str] = ()):
        if not pylsl_available():
            raise LslUnavailable("lsl.enabled needs pylsl: pip install 'ankle-rt[lab]' (or pip install pylsl)")
        self.rate_hz = rate_hz
        self.source_id = source_id
        self.origin_s = origin_s
        self.state_names = {code: name.lower() for name, code in states.items()}
        self.fault_names = {code: name.lower() for name, code in faults.items()}
        self.phase_names = dict(enumerate(phases))
        self.info = dict(info or {})
        self.outlet: Any = None
        self.markers: Any = None
        self.samples = 0          # records pushed
        self.events = 0           # markers pushed
        self.error = ""           # why publishing stopped ("" while it works)
        self._state = -1          # the last record's state and fault codes (-1: none seen yet)
        self._fault = 0
        self._phase = 0           # the last record's gait_phase code (0: not the gait-phase controller)

    def open(self) -> None:
        """Make the outlets (in the log writer's thread, at its normal scheduling)."""
        import pylsl

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

    def publish(self, chunk: memoryview) -> None:
        """Push the whole records in ``chunk`` (ring bytes, oldest first) as one LSL chunk, then
        the events they hold. A few numpy calls per flush: the writer thread holds the interpreter
        lock, which the loop may be waiting for, only briefly."""
        n = len(chunk) // RECORD_SIZE
        if self.outlet is None or n == 0:
            return
        values = np.ndarray((n, len(CHANNELS)), "<f8", chunk, 0, (RECORD_SIZE, 8))
        stamps = values[:, _LOOP_TIME] + self.origin_s()
        self.outlet.push_chunk(values, stamps.tolist())
        self.samples += n
        states = np.ndarray((n,), "u1", chunk, _STATE, (RECORD_SIZE,))
        faults = np.ndarray((n,), "u1", chunk, _FAULT, (RECORD_SIZE,))
        phases = np.ndarray((n,), "u1", chunk, _PHASE, (RECORD_SIZE,))
        if (states.min() == states.max() == self._state and faults.min() == faults.max() == self._fault
                and phases.min() == phases.max() == self._phase):
            return   # nothing happened (almost every flush while standing; a few times a stride walking)
        for stamp, marker in self._events(states, faults, phases, stamps):
            self.markers.push_sample([marker], stamp)
            self.events += 1

    def _events(self, states: np.ndarray, faults: np.ndarray, phases: np.ndarray,
                stamps: np.ndarray) -> list[tuple[float, str]]:
        """(time, marker) of every state change, every new fault and every gait-phase change in these
        records."""
        state = np.concatenate(([self._state], states.astype(np.int64)))
        fault = np.concatenate(([self._fault], faults.astype(np.int64)))
        phase = np.concatenate(([self._phase], phases.astype(np.int64)))
        out = []
        for i in np.flatnonzero((state[1:] != state[:-1]) | (fault[1:] != fault[:-1]) | (phase[1:] != phase[:-1])):
            if fault[i + 1] != fault[i] and fault[i + 1] != 0:
                out.append((float(stamps[i]), f"fault:{self.fault_names.get(int(fault[i + 1]), fault[i + 1])}"))
            if state[i + 1] != state[i]:
                out.append((float(stamps[i]), f"state:{self.state_names.get(int(state[i + 1]), state[i + 1])}"))
            if phase[i + 1] != phase[i]:
                out.append((float(stamps[i]), f"gait_phase:{self.phase_names.get(int(phase[i + 1]), phase[i + 1])}"))
        self._state, self._fault, self._phase = int(state[-1]), int(fault[-1]), int(phase[-1])
        return out

    def status(self) -> dict[str, Any]:
        """For ``ctl status``: the streams, what went out, and why publishing stopped if it did."""
        return {"stream": STREAM_NAME, "events_stream": EVENTS_NAME, "samples": self.samples,
                "events": self.events, "error": self.error or None}

    def close(self) -> None:
        """Drop the outlets (inlets see the streams end)."""
        self.outlet = self.markers = None
