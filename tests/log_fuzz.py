"""A seeded fuzz of run logs, shared by tests/test_log_integrity.py (10^4 inputs) and
benchmarks/bench_log.py (10^5): mutate a clean log, read it, summarise it, build its CSV columns.
The only exception allowed is LogFormatError; a record read back must be an original one."""

from __future__ import annotations

import os
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ankle_rt.log.export import csv_columns
from ankle_rt.log.header import BLOCK_SIZE, HEADER_SIZE, LogFormatError
from ankle_rt.log.reader import read_log
from ankle_rt.log.record import RECORD_SIZE
from ankle_rt.log.summary import format_summary, summarize_log


def mutate(rng: np.random.Generator, data: bytes) -> tuple[bytearray, str]:
    """One random corruption of ``data`` and its kind."""
    out = bytearray(data)
    n = len(out)
    kind = ("flip", "flips", "bytes", "truncate", "extend", "insert", "delete", "zero_block",
            "header_json", "records_swap")[int(rng.integers(10))]
    if kind == "flip":
        pos = int(rng.integers(n))
        out[pos] ^= 1 << int(rng.integers(8))
    elif kind == "flips":
        for pos in rng.integers(n, size=int(rng.integers(2, 40))):
            out[int(pos)] ^= 1 << int(rng.integers(8))
    elif kind == "bytes":
        for pos in rng.integers(n, size=int(rng.integers(1, 20))):
            out[int(pos)] = int(rng.integers(256))
    elif kind == "truncate":
        del out[int(rng.integers(n)):]
    elif kind == "extend":
        out += rng.integers(256, size=int(rng.integers(1, 3 * RECORD_SIZE)), dtype=np.uint8).tobytes()
    elif kind == "insert":
        pos = int(rng.integers(n))
        out[pos:pos] = rng.integers(256, size=int(rng.integers(1, 9)), dtype=np.uint8).tobytes()
    elif kind == "delete":
        pos = int(rng.integers(n))
        del out[pos:pos + int(rng.integers(1, 9))]
    elif kind == "zero_block":
        pos = int(rng.integers(n))
        out[pos:pos + 512] = bytes(len(out[pos:pos + 512]))
    elif kind == "header_json":       # any byte of the first copy's JSON, magic included
        out[int(rng.integers(BLOCK_SIZE))] = int(rng.integers(256))
    else:                             # two whole records swapped: each still intact
        i, j = (int(v) for v in rng.integers((n - HEADER_SIZE) // RECORD_SIZE, size=2))
        a, b = HEADER_SIZE + i * RECORD_SIZE, HEADER_SIZE + j * RECORD_SIZE
        out[a:a + RECORD_SIZE], out[b:b + RECORD_SIZE] = data[b:b + RECORD_SIZE], data[a:a + RECORD_SIZE]
    return out, kind


@dataclass
class FuzzResult:
    inputs: int = 0
    refused: int = 0                                    # LogFormatError: not a readable log
    records_kept: int = 0
    damaged_counted: int = 0
    crashes: list[str] = field(default_factory=list)    # any other exception (the traceback's last line)
    violations: list[str] = field(default_factory=list)  # a damaged record read back, or a flip costing > 1


def fuzz_logs(data: bytes, n: int, seed: int, directory: Path, small_records: int = 40) -> FuzzResult:
    """``n`` mutations of ``data`` (a clean format-2 log; three in four cut to ``small_records``
    records, which keeps the summary cheap), each written to one file in ``directory`` and read."""
    base = np.frombuffer(data, dtype=np.uint8, offset=HEADER_SIZE).reshape(-1, RECORD_SIZE)
    originals = {bytes(row) for row in base}
    small = data[:HEADER_SIZE + small_records * RECORD_SIZE]
    rng = np.random.default_rng(seed)
    path = directory / f"ankle-rt-fuzz-{os.getpid()}.arlog"
    out = FuzzResult()
    try:
        for k in range(n):
            mutated, kind = mutate(rng, small if k % 4 else data)
            path.write_bytes(mutated)
            out.inputs += 1
            try:
                log = read_log(path)
                format_summary(summarize_log(log))
                csv_columns(log.records)
            except LogFormatError:
                out.refused += 1
                continue
            except Exception:       # noqa: BLE001 - counting every crash is the point
                out.crashes.append(f"input {k} ({kind}): {traceback.format_exc().strip().splitlines()[-1]}")
                continue
            rows = log.records.view(np.uint8).reshape(-1, RECORD_SIZE)
            if log.version != 2 or not all(bytes(row) in originals for row in rows):
                out.violations.append(f"input {k} ({kind}): a damaged record was read back")
            if kind == "flip" and (log.damaged > 1 or len(log) + log.damaged != log.total_records):
                out.violations.append(f"input {k}: one flipped bit cost {log.damaged} records")
            out.records_kept += len(log)
            out.damaged_counted += log.damaged
    finally:
        path.unlink(missing_ok=True)
    return out


def scratch_dir(fallback: Path) -> Path:
    """/dev/shm when writable (memory-backed: 10^5 small files stay cheap), else ``fallback``."""
    shm = Path("/dev/shm")
    return shm if shm.is_dir() and os.access(shm, os.W_OK) else fallback
