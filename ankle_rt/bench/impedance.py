"""The rendered-impedance experiment behind ``ankle-rt bench impedance``: what stiffness, damping and
friction hysteresis the wearer feels for a commanded ankle impedance, measured on the simulator.

One lockstep run per commanded impedance (simulated clock, the real daemon, controller and safety
layer) with the reference held at 0 and external torques on the foot, one ankle axis at a time:

- static pulses of several sizes and both signs, ``pulse_s`` each with ``rest_s`` between: rendered
  (secant) stiffness = applied torque / true ankle angle averaged over the pulse's last 50 ms;
- sinusoidal torques at each frequency for ``sine_cycles`` cycles; the last ``analysed_cycles``
  give the first-harmonic impedance Z = T / Theta: dynamic stiffness Re Z, damping Im Z / w, and the
  hysteresis: energy dissipated per cycle (the torque-angle loop's area, J) beyond what the
  commanded damping dissipates (pi B w theta_amp^2), and the joint-torque tracking error
  (desired minus strain-gauge torque, RMS).

The torques enter through the simulated plant's ``extra_disturbance`` (the sim backend only);
the true ankle angle is the simulator's (a bench's joint encoders). Numpy only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from ankle_rt.backend import Backend, ForwardingBackend, SensorFrame
from ankle_rt.config import Config

AXES = ("dp", "ie")
SETTLE_S = 1.0            # activation (tare 0.1 s, soft start 0.2 s) and rest before the first pulse
END_WINDOW_S = 0.05       # the pulse's end: angle averaged over this window


@dataclass(frozen=True)
class Experiment:
    """The torque programme, per axis (N m, s, Hz)."""

    pulses_nm: tuple[tuple[float, ...], tuple[float, ...]] = ((3.0, -3.0, 6.0, -6.0, 12.0, -12.0),
                                                              (1.5, -1.5, 3.0, -3.0, 6.0, -6.0))   # [DP, IE]
    pulse_s: float = 1.5
    rest_s: float = 1.0
    sine_hz: tuple[float, ...] = (0.5, 1.0, 2.0, 5.0)
    sine_nm: tuple[float, float] = (6.0, 3.0)     # amplitude [DP, IE]
    sine_cycles: int = 4
    analysed_cycles: int = 2
    axes: tuple[str, ...] = AXES


@dataclass
class Segment:
    axis: int
    start: float
    stop: float
    kind: str                 # "pulse" | "sine"
    size: float               # N m (pulse torque or sine amplitude)
    freq: float = 0.0


def schedule(exp: Experiment) -> tuple[list[Segment], float]:
    """The segments of the programme and its total duration (s)."""
    segs, t = [], SETTLE_S
    for axis_name in exp.axes:
        axis = AXES.index(axis_name)
        for size in exp.pulses_nm[axis]:
            segs.append(Segment(axis, t, t + exp.pulse_s, "pulse", size))
            t += exp.pulse_s + exp.rest_s
        for f in exp.sine_hz:
            dur = exp.sine_cycles / f
            segs.append(Segment(axis, t, t + dur, "sine", exp.sine_nm[axis], f))
            t += dur + exp.rest_s
    return segs, t


def torque_at(segs: Sequence[Segment], t: float) -> tuple[float, float]:
    """N m [DP, IE] the programme applies at time ``t``."""
    out = [0.0, 0.0]
    for s in segs:
        if s.start <= t < s.stop:
            out[s.axis] += s.size if s.kind == "pulse" else s.size * math.sin(2.0 * math.pi * s.freq * (t - s.start))
    return out[0], out[1]


class TorqueProgramBackend(ForwardingBackend):
    """Wraps the simulated backend and sets its plant's ankle disturbance before each tick from
    ``torque(t, x)``: t the tick's mid-point (so the held torque has no half-tick lag), x the plant
    state [theta (2), theta_m (2), rates (4)] (an environment may depend on it)."""

    name = "sim+torque-programme"

    def __init__(self, inner: Backend, torque: Callable[[float, np.ndarray], tuple[float, float]]):
        super().__init__(inner)
        self.torque = torque
        self.plant = inner.plant
        self.half_dt = 0.5 * self.plant.dt

    def read(self, frame: SensorFrame) -> None:
        plant = self.plant
        plant.extra_disturbance[0], plant.extra_disturbance[1] = self.torque(plant.t + self.half_dt, plant.model.x)
        self.inner.read(frame)


@dataclass
class ImpedanceResult:
    """Measured figures of one run (one commanded impedance, one controller)."""

    commanded: dict[str, float]
    pulses: list[dict[str, Any]] = field(default_factory=list)
    sines: list[dict[str, Any]] = field(default_factory=list)
    fault: str = "NONE"
    final_offset_rad: float = math.nan   # max |ankle angle| over the last 0.1 s (back at the equilibrium?)
    loops: list[dict[str, np.ndarray]] = field(default_factory=list)   # torque-angle loops for the plot

    def stiffness_error_max_pct(self, min_torque: float = 3.0) -> float:
        errs = [abs(p["error_pct"]) for p in self.pulses if abs(p["torque_nm"]) >= min_torque]
        return max(errs) if errs else math.nan

    def damping_error_max_pct(self) -> float:
        errs = [abs(s["damping_error_pct"]) for s in self.sines if not math.isnan(s["damping_error_pct"])]
        return max(errs, default=math.nan)

    def hysteresis_j_per_cycle(self) -> float:
        """Worst excess dissipation per cycle at the lowest sine frequency (quasi-static hysteresis)."""
        if not self.sines:
            return math.nan
        f0 = min(s["freq_hz"] for s in self.sines)
        return max(abs(s["hysteresis_j"]) for s in self.sines if s["freq_hz"] == f0)

    def torque_tracking_rms_nm(self) -> float:
        return max((s["torque_error_rms_nm"] for s in self.sines), default=math.nan)

    def to_json(self) -> dict[str, Any]:
        return {"commanded": self.commanded, "fault": self.fault, "pulses": self.pulses, "sines": self.sines,
                "stiffness_error_max_pct": self.stiffness_error_max_pct(),
                "damping_error_max_pct": self.damping_error_max_pct(),
                "hysteresis_j_per_cycle": self.hysteresis_j_per_cycle(),
                "torque_tracking_rms_nm": self.torque_tracking_rms_nm()}


def bench_config(cfg: Config, *, stiffness: tuple[float, float], damping: tuple[float, float],
                 torque_feedback: str, friction_ff: str | None, effects: list[dict]) -> Config:
    """The impedance experiment's config from ``cfg``: simulator, impedance controller with the
    commanded gains, hold at 0, no configured disturbances, no log file. ``friction_ff``: None (off),
    'coulomb_viscous' or 'identified' (from the plant's own effects: the model is exact)."""
    c = cfg.deep_copy()
    c["backend"] = "sim"
    c["sim"]["effects"] = list(c["sim"]["effects"]) + list(effects)
    c["sim"]["disturbances"] = []
    ctl = c["controller"]
    ctl["type"] = "impedance"
    ctl["impedance"].update(stiffness_dp=stiffness[0], stiffness_ie=stiffness[1], damping_dp=damping[0],
                            damping_ie=damping[1], torque_feedback=torque_feedback)
    ff = ctl["friction_ff"]
    ff["enabled"] = friction_ff is not None
    ff["model"] = friction_ff or "coulomb_viscous"
    ff["model_file"] = ""
    c["reference"]["profile"] = "hold"
    c["reference"]["hold"] = {"dp": 0.0, "ie": 0.0}
    c["safety"]["auto_activate"] = True
    c["logging"]["enabled"] = False
    return c


def run_impedance(cfg: Config, exp: Experiment, *, plant_cfg: Config | None = None,
                  keep_loops: bool = False) -> ImpedanceResult:
    """Run the programme on the simulator in lockstep with the config's impedance controller;
    ``plant_cfg``: a different config for the simulated plant (a plant the controller's model
    does not match), default ``cfg``."""
    from ankle_rt.backend import open_backend
    from ankle_rt.clock import SimClock
    from ankle_rt.daemon import run_lockstep

    segs, duration = schedule(exp)
    inner = open_backend(cfg if plant_cfg is None else plant_cfg, SimClock())
    if not hasattr(inner, "plant"):
        raise ValueError("the impedance bench needs the simulated backend (backend: sim)")
    backend = TorqueProgramBackend(inner, lambda t, x: torque_at(segs, t))
    try:
        run = run_lockstep(cfg, duration, backend=backend)
    finally:
        backend.close()
    imp = cfg["controller"]["impedance"]
    K = (imp["stiffness_dp"], imp["stiffness_ie"])
    B = (imp["damping_dp"], imp["damping_ie"])
    res = ImpedanceResult(commanded={"stiffness_dp": K[0], "stiffness_ie": K[1], "damping_dp": B[0],
                                     "damping_ie": B[1]}, fault=run.summary["fault"])
    t = run["t"]
    angle = (run["ankle_dp"], run["ankle_ie"])
    res.final_offset_rad = float(max(np.max(np.abs(a[t >= duration - 0.1])) for a in angle))
    desired = _desired_torque(cfg, run)
    measured = (run["sg_torque_dp"], run["sg_torque_ie"])
    for s in segs:
        name = AXES[s.axis]
        if s.kind == "pulse":
            sel = (t >= s.stop - END_WINDOW_S) & (t < s.stop)
            theta = float(np.mean(angle[s.axis][sel]))
            k = s.size / theta if theta != 0.0 else math.inf
            res.pulses.append({"axis": name, "torque_nm": s.size, "angle_rad": theta, "stiffness": k,
                               "error_pct": 100.0 * (k / K[s.axis] - 1.0)})
            continue
        period = 1.0 / s.freq
        a0 = s.stop - exp.analysed_cycles * period
        sel = (t >= a0) & (t < s.stop)
        tt, th = t[sel], angle[s.axis][sel]
        w = 2.0 * math.pi * s.freq
        tau = s.size * np.sin(w * (tt - s.start))
        Z = _harmonic(tau, tt, w) / _harmonic(th, tt, w)
        amp = abs(_harmonic(th, tt, w))
        # work the external torque does on the ankle per cycle: what the ankle dissipates (J)
        area = float(np.sum(0.5 * (tau[1:] + tau[:-1]) * np.diff(th))) / exp.analysed_cycles
        commanded_loss = math.pi * B[s.axis] * w * amp ** 2
        err = desired[s.axis][sel] - measured[s.axis][sel]
        res.sines.append({"axis": name, "freq_hz": s.freq, "amplitude_nm": s.size, "angle_amplitude_rad": amp,
                          "dynamic_stiffness": float(Z.real), "damping": float(Z.imag / w),
                          "damping_error_pct": 100.0 * (Z.imag / w / B[s.axis] - 1.0) if B[s.axis] > 0 else math.nan,
                          "loop_energy_j": area, "hysteresis_j": area - commanded_loss,
                          "torque_error_rms_nm": float(np.sqrt(np.mean(err ** 2)))})
        if keep_loops:
            res.loops.append({"axis": name, "freq_hz": s.freq, "angle": th.copy(), "torque": tau})
    return res


def _harmonic(x: np.ndarray, t: np.ndarray, w: float) -> complex:
    """First-harmonic phasor of ``x`` over whole periods (x ~ Re(X e^{jwt}))."""
    return complex(2.0 * np.mean(x * np.exp(-1j * w * t)))


def _desired_torque(cfg: Config, run: Any) -> tuple[np.ndarray, np.ndarray]:
    """The impedance law's joint torque per cycle, recomputed from the logged estimates."""
    from ankle_rt.kinematics import Kinematics
    from ankle_rt.params import TransmissionParams

    Ri = Kinematics.from_params(TransmissionParams(**cfg["transmission"])).R_inv
    imp = cfg["controller"]["impedance"]
    v = Ri @ np.vstack([run["motor_vel_1"], run["motor_vel_2"]])
    return (imp["stiffness_dp"] * (run["ref_dp"] - run["est_ankle_dp"]) - imp["damping_dp"] * v[0],
            imp["stiffness_ie"] * (run["ref_ie"] - run["est_ankle_ie"]) - imp["damping_ie"] * v[1])
