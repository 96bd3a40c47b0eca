"""Calibration through the Backend interface: strain-gauge tare and sign checks.

Runs on any backend (simulator, serial bridge, CANopen, their emulators); it only reads frames and
writes currents, on the clock it is given.

1. Tare: amplifiers off, foot unloaded, ``tare_s`` of samples. The mean strain-gauge torque is what
   the current ``strain_gauges.tare`` leaves over, so the new tare is the old one plus the mean.
2. Sign check, per motor: enable, a current pulse of ``+current`` on that motor alone for
   ``pulse_s``, coast for ``settle_s``, then the same pulse negative to bring it back. The positive
   pulse must turn that motor forward (a flipped amplifier or encoder sign turns a PD loop into
   positive feedback), clearly more than the other motor (swapped outputs or channels), and, with
   joint encoders, move the ankle the way the kinematics say: theta = R^-1 theta_m.

Every check that fails is reported with the config key to look at. The backend is left deactivated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ankle_rt.backend import Backend, BackendFault, SensorFrame
from ankle_rt.clock import Clock
from ankle_rt.kinematics import Kinematics
from ankle_rt.params import TransmissionParams

# Faults that stop a calibration at once (CRC errors and sequence gaps are only counted).
STOP_FAULTS = (BackendFault.LINK_LOST | BackendFault.AMP_NOT_READY | BackendFault.STRAIN_GAUGE_RAIL
               | BackendFault.BUS_OFF | BackendFault.DEVICE_FAULT | BackendFault.ENCODER_FAULT
               | BackendFault.STALE_SAMPLE)
MIN_MOTION_RAD = 0.2 * math.pi / 180      # a pulse must turn its motor at least this far (0.2 deg)
MAX_MOTION_RAD = 20.0 * math.pi / 180     # and never further than this: abort
CROSSTALK = 0.5                           # the other motor may move at most this share of the pulsed one
ANKLE_AGREEMENT = 0.9                     # cosine between measured and kinematic ankle motion


class CalibrationAborted(RuntimeError):
    """The device reported a fault or moved too far; the backend was deactivated."""


@dataclass
class MotorCheck:
    motor: int                                # 1 or 2
    current: float                            # A of the positive pulse
    motor_motion: tuple[float, float]         # rad, both motors, from the positive pulse
    ankle_motion: tuple[float, float] | None  # rad [DP, IE] from joint encoders, None without
    expected_ankle: tuple[float, float]       # rad, R^-1 times the motor motion
    problems: list[str] = field(default_factory=list)


@dataclass
class CalibrationReport:
    tare: tuple[float, float]                 # N m [DP, IE], the new strain_gauges.tare
    tare_mean: tuple[float, float]            # N m, what the old tare left over
    tare_noise: tuple[float, float]           # N m rms during the tare
    tare_samples: int
    motors: list[MotorCheck]
    backend_counters: dict[str, int]

    @property
    def problems(self) -> list[str]:
        return [p for m in self.motors for p in m.problems]

    @property
    def ok(self) -> bool:
        return not self.problems

    def yaml(self) -> str:
        """The calibration values to put into the hardware config."""
        return ("strain_gauges:\n"
                f"  tare: [{self.tare[0]:.6g}, {self.tare[1]:.6g}]   # N m [DP, IE], ankle-rt calibrate, "
                f"noise {self.tare_noise[0]:.3g} / {self.tare_noise[1]:.3g} N m rms\n")


class _Runner:
    """Reads, writes and sleeps one period at a time; stops on a fault or too large a motion."""

    def __init__(self, backend: Backend, clock: Clock, rate_hz: int):
        self.backend = backend
        self.clock = clock
        self.period_ns = round(1e9 / rate_hz)
        self.frame = SensorFrame()
        self.deadline = clock.now_ns()
        self.origin: np.ndarray | None = None

    def cycles(self, n: int, current_1: float = 0.0, current_2: float = 0.0) -> list[SensorFrame]:
        """``n`` cycles with these set values; the frames with a new sample (copies)."""
        out = []
        backend, frame = self.backend, self.frame
        last_seq = None
        for _ in range(n):
            self.clock.sleep_until(self.deadline)
            self.deadline += self.period_ns
            backend.read(frame)
            if frame.faults & STOP_FAULTS:
                raise CalibrationAborted(f"the device reported {BackendFault(frame.faults & STOP_FAULTS)!r}")
            if self.origin is not None and np.max(np.abs(frame.motor_pos - self.origin)) > MAX_MOTION_RAD:
                raise CalibrationAborted(f"a motor moved more than {math.degrees(MAX_MOTION_RAD):g} deg")
            backend.write(current_1, current_2)
            if frame.seq != last_seq:
                last_seq = frame.seq
                snap = SensorFrame()
                snap.t, snap.seq = frame.t, frame.seq
                snap.motor_pos[:] = frame.motor_pos
                snap.sg_torque[:] = frame.sg_torque
                snap.ankle_pos[:] = frame.ankle_pos
                out.append(snap)
        return out


def calibrate(cfg: dict, backend: Backend, clock: Clock, *, tare_s: float = 0.5, current: float = 0.5,
              pulse_s: float = 0.05, settle_s: float = 0.3) -> CalibrationReport:
    """Tare the strain gauges and check the signs (see the module docstring). Raises
    :class:`CalibrationAborted` on a device fault or runaway motion (after deactivating)."""
    rate = cfg["controller"]["rate_hz"]
    kin = Kinematics.from_params(TransmissionParams(**cfg["transmission"]))
    run = _Runner(backend, clock, rate)
    n = lambda s: max(1, round(s * rate))   # noqa: E731  (cycles in s seconds)
    old_tare = (cfg.get("strain_gauges") or {}).get("tare") or [0.0, 0.0]
    try:
        backend.deactivate()
        run.cycles(n(0.05))                               # let the first samples settle
        samples = run.cycles(n(tare_s))
        sg = np.array([f.sg_torque for f in samples])
        mean, noise = sg.mean(axis=0), sg.std(axis=0)
        backend.activate()
        checks = [_check_motor(run, kin, m, current, n(pulse_s), n(settle_s)) for m in (0, 1)]
    finally:
        backend.deactivate()
    return CalibrationReport(
        tare=(old_tare[0] + float(mean[0]), old_tare[1] + float(mean[1])),
        tare_mean=(float(mean[0]), float(mean[1])), tare_noise=(float(noise[0]), float(noise[1])),
        tare_samples=len(samples), motors=checks, backend_counters=backend.counters())


def _position(frames: list[SensorFrame], attr: str) -> np.ndarray:
    """Mean of the last few samples' ``attr`` (motor_pos or ankle_pos)."""
    return np.mean([getattr(f, attr) for f in frames[-5:]], axis=0)


def _check_motor(run: _Runner, kin: Kinematics, m: int, current: float, pulse: int, settle: int) -> MotorCheck:
    o = 1 - m
    rest = run.cycles(5)
    run.origin = _position(rest, "motor_pos")
    start_m, start_a = run.origin, _position(rest, "ankle_pos")
    pulse_currents = (current, 0.0) if m == 0 else (0.0, current)
    run.cycles(pulse, *pulse_currents)
    after = run.cycles(settle)
    moved = _position(after, "motor_pos") - start_m
    ankle = _position(after, "ankle_pos") - start_a
    run.cycles(pulse, -pulse_currents[0], -pulse_currents[1])       # and back
    run.cycles(settle)
    run.origin = None
    expected = kin.R_inv @ moved
    check = MotorCheck(m + 1, current, (float(moved[0]), float(moved[1])),
                       None if np.any(np.isnan(ankle)) else (float(ankle[0]), float(ankle[1])),
                       (float(expected[0]), float(expected[1])))
    deg = math.degrees
    p = check.problems
    if abs(moved[o]) >= MIN_MOTION_RAD and abs(moved[o]) > CROSSTALK * abs(moved[m]):
        p.append(f"a pulse on amplifier {m + 1} turned motor {o + 1} by {deg(moved[o]):+.3f} deg and motor {m + 1} "
                 f"by {deg(moved[m]):+.3f} deg: set-value outputs or encoder channels are swapped")
        return check
    if abs(moved[m]) < MIN_MOTION_RAD:
        p.append(f"motor {m + 1} did not move ({deg(moved[m]):+.3f} deg) for a {current:+g} A pulse: amplifier "
                 f"{m + 1} not enabled or powered, the motor blocked, or the pulse too small for the friction "
                 f"(try --current); check {motor_key('escon.amplifiers', m, '.enable_active_high')} "
                 "and the enable wiring")
        return check
    if moved[m] < 0:
        culprit = _flipped_sign(check, kin, m)
        p.append(f"motor {m + 1} turned {deg(moved[m]):+.3f} deg for a {current:+g} A pulse: {culprit}")
    elif check.ankle_motion is not None:
        a = np.array(check.ankle_motion)
        cos = float(a @ expected / (np.linalg.norm(a) * np.linalg.norm(expected) + 1e-300))
        if cos < ANKLE_AGREEMENT:
            p.append(f"motor {m + 1} moved the ankle by ({deg(a[0]):+.3f}, {deg(a[1]):+.3f}) deg [DP, IE] but the "
                     f"kinematics predict ({deg(expected[0]):+.3f}, {deg(expected[1]):+.3f}) deg: check "
                     f"joint_encoders.sign and transmission.lever_dp / lever_ie / pulley_radius")
    return check


def motor_key(list_key: str, m: int, rest: str = "") -> str:
    """A per-motor config key for 0-based motor index ``m``: the key as config errors print it (list
    index from 0) and the motor it belongs to (numbered from 1, as every message numbers motors)."""
    return f"{list_key}.{m}{rest} (list item {m} = motor {m + 1})"


def _flipped_sign(check: MotorCheck, kin: Kinematics, m: int) -> str:
    """Which sign to fix for a motor that turned backwards; joint encoders tell amplifier from encoder."""
    both = f"the sign of amplifier {m + 1} or of encoder {m + 1} is flipped: check " \
           f"{motor_key('escon.amplifiers', m, '.sign')} and {motor_key('encoders.sign', m)}"
    if check.ankle_motion is None:
        return both
    a = np.array(check.ankle_motion)
    along = float(a @ kin.R_inv[:, m])   # > 0: the ankle went the way a forward turn of motor m takes it
    if abs(along) < 1e-9:
        return both
    if along > 0:
        return f"the motor turned forward but encoder {m + 1} counts backwards: flip {motor_key('encoders.sign', m)}"
    return (f"the motor turned backwards: flip {motor_key('escon.amplifiers', m, '.sign')} "
            "(wiring or ESCON Studio direction)")
