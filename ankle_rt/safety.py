"""The safety layer: the daemon's states, the fault checks of every cycle, current limiting.

States, in the spirit of ros2_control::

    CONFIGURED --activate--> ACTIVE --fault--> FAULT --reset--> SAFE --activate--> ACTIVE
                               |                                  ^
                               +------------deactivate------------+

CONFIGURED is the start-up state (sensors read and logged, strain gauges tared, amplifiers off).
Set values reach the amplifiers only in ACTIVE. In the cycle a fault is detected the daemon zeroes
the set values, calls ``backend.deactivate()`` (enables off) and records the reason; FAULT then
latches (amplifiers off) until an explicit reset, which leads to SAFE: amplifiers off, no fault
pending, ready to be activated again. Sensors are checked in every state but FAULT, so a broken
sensor also blocks a later activation. Faults are small integer codes (:class:`Fault`), so the hot
path records a reason without formatting a string.

No value can switch a check off: :class:`Safety` checks its own limits when it is configured (a
NaN limit compares false against everything, so a NaN peak current would disable the clamp) and
refuses non-finite or out-of-range ones with a ConfigError naming the key. In the cycle a non-finite
reference or controller output is a fault before anything reaches the amplifiers.
"""

from __future__ import annotations

import enum
import math
from typing import Any, Mapping, Sequence

import numpy as np

from ankle_rt.backend import BackendFault, SensorFrame
from ankle_rt.config_schema import SCHEMA
from ankle_rt.elementwise import Value, any_true, clip, positive_part, select, stack
from ankle_rt.estimation import Estimate
from ankle_rt.gauge_check import GaugeCrossCheck
from ankle_rt.joint_check import JointCrossCheck
from ankle_rt.kinematics import ankle_stiffness, motor_ratio
from ankle_rt.loop_setup import has_joint_encoders, reads_joint_encoders
from ankle_rt.oscillation import OscillationDetector
from ankle_rt.params import TransmissionParams
from ankle_rt.schema import ConfigError


class State(enum.IntEnum):
    CONFIGURED = 0   # start-up: sensors read and logged, amplifiers disabled (strain gauges tared here)
    ACTIVE = 1       # controller output reaches the amplifiers
    FAULT = 2        # latched from the cycle a fault was detected: amplifiers disabled until a reset
    SAFE = 3         # after a reset or deactivation: amplifiers disabled, may be activated again


class Fault(enum.IntEnum):
    NONE = 0
    ANKLE_RANGE = 1          # estimated or measured ankle angle beyond +/- limits.ankle_range_deg
    OVERCURRENT = 2          # I^2 t estimate spent the ESCON's peak-current budget
    SENSOR_STALE = 3         # the sample sequence did not advance for safety.stale_cycles cycles
    MOTOR_JUMP = 4           # encoder angle jumped more than safety.max_motor_speed_rad_s allows
    SG_JUMP = 5              # strain-gauge torque jumped more than safety.max_sg_step_nm in one sample
    SG_RAIL = 6              # strain-gauge torque at its rail (safety.sg_rail_nm) or reported so
    SENSOR_INVALID = 7       # a sensor value is NaN/inf
    AMP_NOT_READY = 8        # an ESCON ready output is low while active
    MISSED_DEADLINES = 9     # loop.max_consecutive_overruns overruns in a row, or one stall > loop.max_stall_s
    COMMAND_LOST = 10        # no command on the socket for service.command_timeout_s while active
    LINK_LOST = 11           # backend: no sample within its detection time
    BUS_OFF = 12             # backend: CAN bus-off
    DEVICE_FAULT = 13        # backend: the bridge / I/O module reported a fault
    ENCODER_FAULT = 14       # backend: encoder stuck or implausible
    OUTPUT_INVALID = 15      # the controller produced a NaN/inf torque
    REFERENCE_INVALID = 16   # the ankle reference is NaN/inf
    LOG_FAILED = 17          # a run log write failed (disk full) and logging.fault_on_error is set
    OSCILLATION = 18         # a set value oscillated above 20 Hz beyond safety.oscillation_rms_a for oscillation_hold_s
    SG_MISMATCH = 19         # strain-gauge torque disagrees with the torque the motors deliver (ankle_rt.gauge_check)
    JOINT_INVALID = 20       # a joint-encoder angle is NaN/inf (the serial bridge's invalid bit) on a device with them
    JOINT_MISMATCH = 21      # joint-encoder angle disagrees with the motors and gauges (ankle_rt.joint_check)

    @property
    def description(self) -> str:
        return _DESCRIPTIONS[self]


# A set value may not drive a motor that already turns faster than this share of
# safety.max_motor_speed_rad_s faster still (Safety.limit_currents, safety9): beyond the limit
# MOTOR_JUMP leaves the motors unpowered at speed and the foot coasts far past the ankle range (a
# configured 34 / 17 deg step under the PD: 118 deg). The walking scenario's fastest motor is at 20 rad/s.
GOVERNOR_SHARE = 0.8

_DESCRIPTIONS = {
    Fault.NONE: "no fault",
    Fault.ANKLE_RANGE: "ankle angle beyond the software limit",
    Fault.OVERCURRENT: "current above the amplifier limits (I^2 t budget spent)",
    Fault.SENSOR_STALE: "sensor samples stopped advancing",
    Fault.MOTOR_JUMP: "motor encoder jumped further than physics allows",
    Fault.SG_JUMP: "strain-gauge torque jumped further than physics allows",
    Fault.SG_RAIL: "strain gauge at its rail",
    Fault.SENSOR_INVALID: "sensor value not finite",
    Fault.AMP_NOT_READY: "amplifier not ready",
    Fault.MISSED_DEADLINES: "too many consecutive missed deadlines",
    Fault.COMMAND_LOST: "command channel lost",
    Fault.LINK_LOST: "backend link lost",
    Fault.BUS_OFF: "CAN bus-off",
    Fault.DEVICE_FAULT: "device reported a fault",
    Fault.ENCODER_FAULT: "encoder fault reported by the backend",
    Fault.OUTPUT_INVALID: "controller output not finite",
    Fault.REFERENCE_INVALID: "ankle reference not finite",
    Fault.LOG_FAILED: "run log write failed (logging.fault_on_error)",
    Fault.OSCILLATION: "sustained current oscillation above 20 Hz (an unstable loop)",
    Fault.SG_MISMATCH: "strain-gauge torque disagrees with the motors (stuck, drifting, sign-flipped or stepped gauge)",
    Fault.JOINT_INVALID: "joint encoder reading not finite (invalid sample)",
    Fault.JOINT_MISMATCH: "joint encoder disagrees with the motors and strain gauges (sign-flipped, mis-scaled or stuck)",
}

# BackendFault bits that stop the device, in priority order. CRC errors and sequence gaps are
# tolerated one by one (they are counted by the backend); if samples stop, SENSOR_STALE trips.
_BACKEND_FAULTS = (
    (BackendFault.LINK_LOST, Fault.LINK_LOST),
    (BackendFault.BUS_OFF, Fault.BUS_OFF),
    (BackendFault.DEVICE_FAULT, Fault.DEVICE_FAULT),
    (BackendFault.AMP_NOT_READY, Fault.AMP_NOT_READY),
    (BackendFault.ENCODER_FAULT, Fault.ENCODER_FAULT),
    (BackendFault.STRAIN_GAUGE_RAIL, Fault.SG_RAIL),
    (BackendFault.STALE_SAMPLE, Fault.SENSOR_STALE),
)
_FATAL_BACKEND_BITS = 0
for _bit, _ in _BACKEND_FAULTS:
    _FATAL_BACKEND_BITS |= int(_bit)

# Plain ints for the per-cycle code (an enum attribute lookup costs more than the check itself).
_ACTIVE, _FAULT = int(State.ACTIVE), int(State.FAULT)
_AMP_NOT_READY, _SENSOR_INVALID, _SG_RAIL = int(Fault.AMP_NOT_READY), int(Fault.SENSOR_INVALID), int(Fault.SG_RAIL)
_SENSOR_STALE, _MOTOR_JUMP, _SG_JUMP = int(Fault.SENSOR_STALE), int(Fault.MOTOR_JUMP), int(Fault.SG_JUMP)
_ANKLE_RANGE, _OVERCURRENT, _OUTPUT_INVALID = int(Fault.ANKLE_RANGE), int(Fault.OVERCURRENT), int(Fault.OUTPUT_INVALID)
_REFERENCE_INVALID, _OSCILLATION, _SG_MISMATCH = int(Fault.REFERENCE_INVALID), int(Fault.OSCILLATION), int(Fault.SG_MISMATCH)
_JOINT_INVALID, _JOINT_MISMATCH = int(Fault.JOINT_INVALID), int(Fault.JOINT_MISMATCH)


def _limit(value: Any, key: str, low: float, high: float | None, low_open: bool = True) -> float:
    """``value`` as a float if finite and within (low, high] ([low, high] when not ``low_open``; no
    upper bound for None); else ConfigError naming ``key``: a limit the safety layer relies on must
    be a real number."""
    high = math.inf if high is None else high
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if ok:
        ok = (value > low if low_open else value >= low) and value <= high
    if not ok:
        bound = f"{'(' if low_open else '['}{low:g}, {high:g}]"
        raise ConfigError(f"the safety layer refuses {value!r}: expected a finite number in {bound}", "safety", key)
    return float(value)


def _configured(cfg: Mapping[str, Any], key: str, low: float | None = None) -> float:
    """The config's value at the dotted ``key``, checked again (a config built in code may have
    skipped validation) against the bounds the schema gives it, the one place they are written;
    ``low`` (closed) replaces the schema's lower bound where another setting sets it."""
    section, name = key.split(".")
    spec = SCHEMA.fields[section].fields[name]
    if low is None:
        return _limit(cfg[section][name], key, spec.low, spec.high, spec.low_open)
    return _limit(cfg[section][name], key, low, spec.high, low_open=False)


class Safety:
    """Sensor plausibility checks, current limits and the state machine (see the module docstring)."""

    def __init__(self, cfg: Mapping[str, Any], dt: float):
        self.dt = _limit(dt, "dt", 0.0, 1.0)
        self.ankle_limit = math.radians(_configured(cfg, "limits.ankle_range_deg"))
        # With the motors detached from the cables (sim.cables: false, the actuator experiments) the
        # ankle angle estimated from the motors means nothing; only joint encoders are checked then.
        self.check_estimated_ankle = bool(cfg["sim"]["cables"])
        self.max_motor_speed = _configured(cfg, "safety.max_motor_speed_rad_s")
        self.governor_speed = GOVERNOR_SHARE * self.max_motor_speed
        self.max_sg_step = _configured(cfg, "safety.max_sg_step_nm")
        self.sg_rail = _configured(cfg, "safety.sg_rail_nm")
        self.stale_cycles = int(_configured(cfg, "safety.stale_cycles"))
        i_cont = _configured(cfg, "amplifier.current_limit_continuous")
        self.i_peak = _configured(cfg, "amplifier.current_limit_peak", low=i_cont)
        self.i_cont2 = i_cont ** 2
        peak_s = _configured(cfg, "safety.i2t_peak_duration_s")
        self.i2t_budget = (self.i_peak ** 2 - self.i_cont2) * peak_s  # A^2 s
        self.oscillation = OscillationDetector(self.dt, _configured(cfg, "safety.oscillation_rms_a"),
                                               _configured(cfg, "safety.oscillation_hold_s"))
        # The gauges are cross-checked where there are gauges and cables between motors and ankle.
        a = cfg["actuator"]
        self.kt = float(a["torque_constant"])
        self.gauges = self.joints = None
        # a device with joint encoders: a non-finite angle is a fault (NaN means none); where the controller acts
        # on them and there are gauges, they are cross-checked against the motors and gauges too
        self.joint_encoders = has_joint_encoders(cfg)
        if self.check_estimated_ankle and (cfg["backend"] == "sim" or cfg["strain_gauges"]["matrix"] is not None):
            R = motor_ratio(TransmissionParams(**cfg["transmission"]))
            self.gauges = GaugeCrossCheck(self.dt, R.tolist(), a["inertia"], a["damping"], a["coulomb"],
                                          cfg["estimation"]["velocity_cutoff_hz"],
                                          max_delay_s=_configured(cfg, "safety.max_actuation_delay_s"))
            if self.joint_encoders:
                k_dp, k_ie = ankle_stiffness(TransmissionParams(**cfg["transmission"]))
                self.joints = JointCrossCheck(self.dt, k_dp, k_ie, _configured(cfg, "safety.joint_mismatch_rad"),
                                              reads_joint_encoders(cfg))
        self.state = State.CONFIGURED
        self.fault = Fault.NONE
        self.fault_time = math.nan
        self.i2t = [0.0, 0.0]          # A^2 s spent above the continuous limit, per amplifier
        self.saturated = 0             # cycles in which a set value was clamped to the peak current
        self.current = [0.0, 0.0]      # A, the limited set values of this cycle
        self._seq = -1
        self._stale = 0
        self._have_last = False
        self._p1 = self._p2 = self._s0 = self._s1 = self._t = 0.0
        self._v1 = self._v2 = 0.0      # rad/s, each motor's speed over the last sample (as MOTOR_JUMP sees it)
        self._governed = False         # some motor beyond governor_speed at the last sample: _v1, _v2 are set

    # -- state machine (commands; not per cycle) ---------------------------------------------------
    def trip(self, fault: Value, t: float) -> None:
        """Enter FAULT with ``fault`` as the reason where it is not 0 (the first reason is kept).
        Element-wise: on a :meth:`stack`, ``fault`` is a code per device."""
        tripping = (self.state != _FAULT) & (fault != 0)
        self.state = select(tripping, State.FAULT, self.state)
        self.fault = select(tripping, fault, self.fault)
        self.fault_time = select(tripping, t, self.fault_time)

    def reset(self) -> None:
        """FAULT -> SAFE (the explicit operator action). Raises RuntimeError in any other state."""
        if self.state != State.FAULT:
            raise RuntimeError(f"nothing to reset: state is {State(self.state).name}, not FAULT")
        self.state = State.SAFE
        self.fault = Fault.NONE
        self.fault_time = math.nan
        self._have_last = False
        self._stale = 0
        self.oscillation.reset()

    def activated(self, est: Estimate, where: bool | np.ndarray = True) -> None:
        """CONFIGURED/SAFE -> ACTIVE (the daemon's activate; for a batch, where ``where`` holds): set
        values restart from zero, and with them the oscillation detector and the gauge cross-check."""
        cur = self.current
        cur[0] = select(where, 0.0, cur[0])
        cur[1] = select(where, 0.0, cur[1])
        self.oscillation.reset(where)
        if self.gauges is not None:
            self.gauges.reset(est.mv1, est.mv2, where)
        if self.joints is not None:
            self.joints.activated(where)
        self.state = select(where, State.ACTIVE, self.state)

    def check_gauges(self, est: Estimate) -> Value:
        """SG_MISMATCH once the strain-gauge torques have disagreed with the torques the motors deliver
        (this cycle's set values, :mod:`ankle_rt.gauge_check`), OSCILLATION instead when the set values
        oscillate at that moment; 0 otherwise or without gauges. Element-wise (a code per device on a
        :meth:`stack`; the caller keeps the codes of the devices it drives this cycle)."""
        g = self.gauges
        if g is None:
            return 0
        kt, cur = self.kt, self.current
        off = g.update(kt * cur[0], kt * cur[1], est.mv1, est.mv2, est.sg_dp, est.sg_ie)
        if not any_true(off):
            return 0 * off
        # while the set values oscillate the cable modes part gauge and motors: the loop is the cause
        return select(off, select(self.oscillation.band_above(), _OSCILLATION, _SG_MISMATCH), 0)

    # -- per cycle -------------------------------------------------------------------------------
    def check_sensors(self, frame: SensorFrame, est: Estimate) -> int:
        """Return the first fault the sample shows (0 if none). Plain-float checks, no allocation."""
        bits = frame.faults
        if bits and bits & _FATAL_BACKEND_BITS:
            for bit, code in _BACKEND_FAULTS:
                if bits & bit:
                    return code
        if self.state == _ACTIVE and not (frame.amp_ready[0] and frame.amp_ready[1]):
            return _AMP_NOT_READY
        v = frame.values
        code = self.check_values(frame.t, v[0], v[1], v[2], v[3], est)
        if code:
            return code
        seq = frame.seq
        if seq == self._seq:
            self._stale += 1
            if self._stale >= self.stale_cycles:
                return _SENSOR_STALE
        else:
            self._stale = 0
            self._seq = seq
        return 0

    def check_values(self, t: float, p1: Value, p2: Value, s0: Value, s1: Value, est: Estimate) -> Value:
        """The first fault the sensor values show (0 if none): not finite (a joint encoder's named), strain
        gauge at its rail, motor or strain-gauge jump since the last sample, ankle (estimated or joint encoder)
        beyond the range, joint encoders against the motors and gauges while active. ``t`` s (one for a batch),
        motor angles rad, raw strain-gauge torques N m; the ankle from ``est``. Element-wise: a code per device
        on a :meth:`stack`."""
        rail, lim = self.sg_rail, self.ankle_limit
        a0, a1, j0, j1 = est.dp, est.ie, est.joint_dp, est.joint_ie
        invalid = (p1 + p2 + s0 + s1 + t) * 0.0 != 0.0     # NaN or inf anywhere
        joint_invalid = self.joint_encoders & ((j0 + j1) * 0.0 != 0.0)
        joints, mismatch = self.joints, False
        railed = (abs(s0) >= rail) | (abs(s1) >= rail)
        ranged = (self.check_estimated_ankle & ((abs(a0) > lim) | (abs(a1) > lim))) \
            | (abs(j0) > lim) | (abs(j1) > lim)           # NaN (no joint encoders) compares False
        if self._have_last:
            h = t - self._t
            h = h if h > self.dt else self.dt
            d1, d2 = p1 - self._p1, p2 - self._p2
            governed = self.governor_speed * h
            # a jump is beyond the governor's speed too: the common cycle compares once per motor
            self._governed = any_true((abs(d1) > governed) | (abs(d2) > governed))
            if self._governed:
                allowed = self.max_motor_speed * h
                motor_jump = (abs(d1) > allowed) | (abs(d2) > allowed)
                self._v1, self._v2 = d1 / h, d2 / h
            else:
                motor_jump = False
            step = self.max_sg_step
            sg_jump = (abs(s0 - self._s0) > step) | (abs(s1 - self._s1) > step)
            if joints is not None:
                mismatch = joints.update(a0, a1, j0, j1, est.sg_dp, est.sg_ie, self.state == _ACTIVE)
        else:
            motor_jump = sg_jump = self._governed = False
            if joints is not None:
                joints.start(a0, a1, j0, j1, est.sg_dp, est.sg_ie)
        self._have_last = True
        self._p1, self._p2, self._s0, self._s1, self._t = p1, p2, s0, s1, t
        if not any_true(invalid | joint_invalid | railed | motor_jump | sg_jump | ranged | mismatch):
            return 0 * invalid
        return select(invalid, _SENSOR_INVALID, select(joint_invalid, _JOINT_INVALID, select(railed, _SG_RAIL, select(
            motor_jump, _MOTOR_JUMP, select(sg_jump, _SG_JUMP, select(ranged, _ANKLE_RANGE, select(
                mismatch, _JOINT_MISMATCH, 0)))))))

    def check_reference(self, dp: Value, ie: Value) -> Value:
        """REFERENCE_INVALID when the ankle reference (rad) is NaN or inf. (Commands that would take it
        beyond the ankle range are refused before they start; the ankle itself is checked against
        the range every cycle.) Element-wise."""
        return select((dp + ie) * 0.0 == 0.0, 0, _REFERENCE_INVALID)

    def limit_currents(self, i1: Value, i2: Value, where: bool | np.ndarray = True) -> Value:
        """Clamp set values (A) to the peak current into ``self.current`` and update the I^2 t
        estimate; return OVERCURRENT once the peak budget is spent, OUTPUT_INVALID for NaN,
        OSCILLATION once the clamped set values have oscillated (:mod:`ankle_rt.oscillation`).
        A set value that would drive a motor turning faster than ``governor_speed`` (GOVERNOR_SHARE
        of safety.max_motor_speed_rad_s, its speed over the last sample) faster still is zero.
        Element-wise; on a :meth:`stack` only the devices ``where`` holds count (saturation, I^2 t,
        faults): the others are not driven this cycle."""
        cur, pk = self.current, self.i_peak
        valid = (i1 + i2) * 0.0 == 0.0          # False for NaN or inf
        counted = valid & where
        self.saturated = self.saturated + (counted & ((abs(i1) > pk) | (abs(i2) > pk)))
        i1 = clip(i1, -pk, pk)
        i2 = clip(i2, -pk, pk)
        if self._governed:
            g, v1, v2 = self.governor_speed, self._v1, self._v2
            i1 = select(((v1 > g) & (i1 > 0.0)) | ((v1 < -g) & (i1 < 0.0)), 0.0, i1)
            i2 = select(((v2 > g) & (i2 > 0.0)) | ((v2 < -g) & (i2 < 0.0)), 0.0, i2)
        cur[0] = select(valid, i1, 0.0)
        cur[1] = select(valid, i2, 0.0)
        dt, ic2, q = self.dt, self.i_cont2, self.i2t
        q0 = q[0] + (i1 * i1 - ic2) * dt
        q1 = q[1] + (i2 * i2 - ic2) * dt
        q[0] = select(counted, positive_part(q0), q[0])
        q[1] = select(counted, positive_part(q1), q[1])
        over = counted & ((q0 > self.i2t_budget) | (q1 > self.i2t_budget))
        # the detector's state matters only while driven: it restarts at every activation (activated)
        oscillating = counted & self.oscillation.update(cur[0], cur[1])
        invalid = where & (valid ^ True)         # driven and not finite
        if not any_true(over | oscillating | invalid):
            return 0 * over
        return select(over, _OVERCURRENT, select(invalid, _OUTPUT_INVALID, select(oscillating, _OSCILLATION, 0)))

    @classmethod
    def stack(cls, layers: Sequence["Safety"]) -> "Safety":
        """One safety layer standing for ``layers`` (one per device of a batch): limits, state,
        fault and I^2 t as arrays over the batch, for the element-wise checks and limits (the period
        and the last sample time are the batch's, one for all)."""
        return stack(layers, shared=("dt", "_t"), columns=("i2t", "current"))
