"""The per-cycle log record: one table defines both the numpy dtype (for reading) and the struct
format (for packing in the loop), so the two cannot drift apart. Little-endian, no padding."""

from __future__ import annotations

import struct

import numpy as np

# (field name, struct code, meaning). Units: s, rad, rad/s, N m, A, µs.
FIELDS: tuple[tuple[str, str, str], ...] = (
    ("t", "d", "s, sample time of the sensor frame (backend clock)"),
    ("motor_pos_1", "d", "rad, encoder angle motor 1 (gearbox output)"),
    ("motor_pos_2", "d", "rad, encoder angle motor 2"),
    ("motor_vel_1", "d", "rad/s, filtered motor velocity 1"),
    ("motor_vel_2", "d", "rad/s, filtered motor velocity 2"),
    ("sg_torque_dp", "d", "N m, tared strain-gauge torque DP"),
    ("sg_torque_ie", "d", "N m, tared strain-gauge torque IE"),
    ("ankle_dp", "d", "rad, joint encoder DP (NaN without joint encoders)"),
    ("ankle_ie", "d", "rad, joint encoder IE"),
    ("est_ankle_dp", "d", "rad, estimated ankle DP = (R^-1 theta_m - K^-1 tau_j)_DP"),
    ("est_ankle_ie", "d", "rad, estimated ankle IE"),
    ("ref_dp", "d", "rad, ankle reference DP"),
    ("ref_ie", "d", "rad, ankle reference IE"),
    ("torque_cmd_1", "d", "N m, controller output motor 1 (before limits)"),
    ("torque_cmd_2", "d", "N m, controller output motor 2"),
    ("current_cmd_1", "d", "A, set value sent to amplifier 1 (0 unless active)"),
    ("current_cmd_2", "d", "A, set value sent to amplifier 2"),
    ("loop_time", "d", "s, cycle start on the loop clock, from the loop start"),
    ("seq", "q", "sample sequence number from the backend"),
    ("period_us", "f", "µs, start-to-start period of this cycle (0 for the first)"),
    ("latency_us", "f", "µs, cycle start to set values written"),
    ("overruns", "I", "overruns counted so far"),
    ("state", "B", "safety.State code"),
    ("fault", "B", "safety.Fault code (reason of the latest fault)"),
    ("backend_faults", "H", "BackendFault bits of the sample"),
)

_NUMPY = {"d": "<f8", "q": "<i8", "f": "<f4", "I": "<u4", "H": "<u2", "B": "u1"}

RECORD_STRUCT = struct.Struct("<" + "".join(code for _, code, _ in FIELDS))
RECORD_DTYPE = np.dtype([(name, _NUMPY[code]) for name, code, _ in FIELDS])
assert RECORD_DTYPE.itemsize == RECORD_STRUCT.size
