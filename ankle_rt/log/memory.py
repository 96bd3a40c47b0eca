"""An in-memory record sink for lockstep runs: the same records as the run log, kept in one
preallocated buffer instead of going to disk (tests and tools read them as a numpy array)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ankle_rt.log.record import RECORD_DTYPE, RECORD_STRUCT
from ankle_rt.log.writer import encode_header


class MemoryRecorder:
    """Holds up to ``capacity`` records; later ones are counted in ``dropped``, never reallocated."""

    def __init__(self, capacity: int):
        self.size = RECORD_STRUCT.size
        self.capacity = capacity
        self.buffer = bytearray(capacity * self.size)
        self.pack_into = RECORD_STRUCT.pack_into
        self.written = 0
        self.dropped = 0

    def append(self, *values: Any) -> None:
        n = self.written
        if n < self.capacity:
            self.pack_into(self.buffer, n * self.size, *values)
            self.written = n + 1
        else:
            self.dropped += 1

    @property
    def records(self) -> np.ndarray:
        """The recorded cycles as a structured array (a view of the buffer)."""
        return np.frombuffer(self.buffer, dtype=RECORD_DTYPE, count=self.written)

    def save(self, path: str | Path, meta: dict[str, Any]) -> None:
        """Write the records as a run log file (the format of :mod:`ankle_rt.log.writer`)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("wb") as handle:
            handle.write(encode_header(meta))
            handle.write(memoryview(self.buffer)[: self.written * self.size])

    def close(self) -> None:
        """Nothing to flush (the sink interface of LogWriter)."""
