"""The per-cycle log record: one table defines both the numpy dtype (for reading) and the struct
format (for packing in the loop), so the two cannot drift apart. Little-endian, no padding.

Each record ends in a CRC-32 of its data bytes (format 2), so a reader tells a damaged record from
an intact one and loses only the record a flipped bit hits. The CRC is part of the record's bytes
but not a named field of :data:`RECORD_DTYPE` (readers see the data fields only).
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

# (field name, struct code, unit, meaning). SI units (loop timing in µs); "count", "code" and "bits" for integers.
FIELDS: tuple[tuple[str, str, str, str], ...] = (
    ("t", "d", "s", "sample time of the sensor frame (backend clock)"),
    ("motor_pos_1", "d", "rad", "encoder angle motor 1 (gearbox output)"),
    ("motor_pos_2", "d", "rad", "encoder angle motor 2"),
    ("motor_vel_1", "d", "rad/s", "filtered motor velocity 1"),
    ("motor_vel_2", "d", "rad/s", "filtered motor velocity 2"),
    ("sg_torque_dp", "d", "N m", "tared strain-gauge torque DP"),
    ("sg_torque_ie", "d", "N m", "tared strain-gauge torque IE"),
    ("ankle_dp", "d", "rad", "joint encoder DP (NaN without joint encoders)"),
    ("ankle_ie", "d", "rad", "joint encoder IE"),
    ("est_ankle_dp", "d", "rad", "estimated ankle DP = (R^-1 theta_m - K^-1 tau_j)_DP"),
    ("est_ankle_ie", "d", "rad", "estimated ankle IE"),
    ("ref_dp", "d", "rad", "ankle reference DP"),
    ("ref_ie", "d", "rad", "ankle reference IE"),
    ("torque_cmd_1", "d", "N m", "controller output motor 1 (before limits)"),
    ("torque_cmd_2", "d", "N m", "controller output motor 2"),
    ("current_cmd_1", "d", "A", "set value sent to amplifier 1 (0 unless active)"),
    ("current_cmd_2", "d", "A", "set value sent to amplifier 2"),
    ("loop_time", "d", "s", "cycle start on the loop clock, from the loop start"),
    ("seq", "q", "count", "sample sequence number from the backend"),
    ("period_us", "f", "µs", "start-to-start period of this cycle (0 for the first)"),
    ("latency_us", "f", "µs", "cycle start to set values written"),
    ("overruns", "I", "count", "overruns counted so far"),
    ("state", "B", "code", "safety.State code"),
    ("fault", "B", "code", "safety.Fault code (reason of the latest fault)"),
    ("backend_faults", "H", "bits", "BackendFault bits of the sample"),
    ("gait_phase", "B", "code", "gait phase of the gait_phase controller: 1 + its index in "
                                "ankle_rt.control.gait_phase.PHASES; 0 = another controller (or a log from before the field)"),
)

_NUMPY = {"d": "<f8", "q": "<i8", "f": "<f4", "I": "<u4", "H": "<u2", "B": "u1"}


UNITS = {name: unit for name, _, unit, _ in FIELDS}


def field_doc(name: str) -> str:
    """"unit, meaning" of a field (the log header's and docs' description)."""
    _, _, unit, meaning = FIELDS[_DATA.names.index(name)]
    return meaning if unit in ("count", "code", "bits") else f"{unit}, {meaning}"


DATA_STRUCT = struct.Struct("<" + "".join(code for _, code, _, _ in FIELDS))   # the loop packs this
CRC_STRUCT = struct.Struct("<I")
_DATA_SIZE = DATA_STRUCT.size                                                 # 169 bytes of data ...
RECORD_SIZE = _DATA_SIZE + CRC_STRUCT.size                                    # ... + CRC: 173 bytes on disk
_SEALED = struct.Struct(f"<{_DATA_SIZE}sI")                                   # packed data + its CRC
# The data fields at their offsets; the trailing CRC is padding to numpy (itemsize RECORD_SIZE).
_DATA = np.dtype([(name, _NUMPY[code]) for name, code, _, _ in FIELDS])
RECORD_DTYPE = np.dtype({"names": list(_DATA.names), "formats": [_DATA[n] for n in _DATA.names],
                         "offsets": [_DATA.fields[n][1] for n in _DATA.names], "itemsize": RECORD_SIZE})
DATA_DTYPE = _DATA    # the fields packed, no CRC: for comparing data (format 1's record had no CRC)
assert _DATA.itemsize == DATA_STRUCT.size


class RecordRing:
    """A preallocated buffer of ``capacity`` record slots that the loop fills one record at a time.

    :meth:`pack` packs the data into a preallocated 169-byte scratch buffer, takes its CRC-32 and
    stores both in slot ``i`` with one more ``pack_into``: no allocation beyond the CRC's int, and no
    per-slot objects (a ring of any size costs its bytes only)."""

    def __init__(self, capacity: int):
        self.capacity = capacity
        self.buffer = bytearray(capacity * RECORD_SIZE)
        self.view = memoryview(self.buffer)
        self._scratch = bytearray(_DATA_SIZE)
        self._pack_data = DATA_STRUCT.pack_into
        self._pack_record = _SEALED.pack_into
        self._crc32 = zlib.crc32

    def pack(self, i: int, values: tuple) -> None:
        """Record ``values`` (FIELDS order) into slot ``i`` with its CRC-32."""
        scratch = self._scratch
        self._pack_data(scratch, 0, *values)
        self._pack_record(self.buffer, i * RECORD_SIZE, scratch, self._crc32(scratch))


def crc_ok(raw: np.ndarray) -> np.ndarray:
    """Per record of ``raw`` (an (n, record size) uint8 array, data then CRC): True where the stored
    CRC matches."""
    size = raw.shape[1] - CRC_STRUCT.size
    stored = raw[:, size:].copy().view("<u4").ravel() if len(raw) else np.zeros(0, dtype="<u4")
    crc32 = zlib.crc32
    computed = np.fromiter((crc32(row) for row in raw[:, :size]), dtype=np.uint32, count=len(raw))
    return computed == stored


def layout(n_fields: int, checksummed: bool) -> np.dtype:
    """The record dtype of a log written when the record had the first ``n_fields`` FIELDS (fields
    are only ever appended): packed data, plus the CRC's bytes as padding when ``checksummed``."""
    data = np.dtype([(name, _NUMPY[code]) for name, code, _, _ in FIELDS[:n_fields]])
    if not checksummed:
        return data
    return np.dtype({"names": list(data.names), "formats": [data[n] for n in data.names],
                     "offsets": [data.fields[n][1] for n in data.names], "itemsize": data.itemsize + CRC_STRUCT.size})


def upgrade(records: np.ndarray) -> np.ndarray:
    """Records of an older layout as RECORD_DTYPE; the fields it lacks are 0 (their "absent" value)."""
    if records.dtype == RECORD_DTYPE:
        return records
    out = np.zeros(len(records), dtype=RECORD_DTYPE)
    for name in records.dtype.names:
        out[name] = records[name]
    return out
