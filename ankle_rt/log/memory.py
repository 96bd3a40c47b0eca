"""An in-memory record sink for lockstep runs: the same records as the run log, kept in one
preallocated buffer instead of going to disk (tests and tools read them as a numpy array)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ankle_rt.log.header import encode_header
from ankle_rt.log.record import RECORD_DTYPE, RECORD_SIZE, RecordRing


class MemoryRecorder:
    """Holds up to ``capacity`` records; later ones are counted in ``dropped``, never reallocated."""

    def __init__(self, capacity: int):
        self.capacity = capacity
        self.ring = RecordRing(capacity)
        self.pack = self.ring.pack
        self.written = 0
        self.dropped = 0
        self.failed = False      # never: memory does not fill up (the sink interface of LogWriter)

    def append(self, *values: Any) -> None:
        n = self.written
        if n < self.capacity:
            self.pack(n, values)
            self.written = n + 1
        else:
            self.dropped += 1

    @property
    def records(self) -> np.ndarray:
        """The recorded cycles as a structured array (a view of the buffer)."""
        return np.frombuffer(self.ring.buffer, dtype=RECORD_DTYPE, count=self.written)

    def save(self, path: str | Path, meta: dict[str, Any]) -> None:
        """Write the records as a run log file (the format of :mod:`ankle_rt.log.writer`)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("wb") as handle:
            handle.write(encode_header({**meta, "part": 0, "first_record": 0, "first_part": path.name}))
            handle.write(self.ring.view[: self.written * RECORD_SIZE])

    def status(self) -> dict[str, Any]:
        """Like :meth:`LogWriter.status` (records kept in memory)."""
        return {"state": "memory", "error": "", "path": "", "part": 0, "records": self.written,
                "dropped": self.dropped, "deleted_files": 0}

    def close(self) -> None:
        """Nothing to flush (the sink interface of LogWriter)."""
