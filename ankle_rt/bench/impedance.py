"""The rendered-impedance experiment behind ``ankle-rt bench impedance``: what stiffness, damping and
friction hysteresis the wearer feels for a commanded ankle impedance, measured on the simulator.

One lockstep run per commanded impedance (simulated clock, the real daemon, controller and safety
layer) with the reference held at 0 and external torques on the foot, one ankle axis at a time:

- static pulses of several sizes and both signs, ``pulse_s`` each with ``rest_s`` between: rendered
  (secant) stiffness = applied torque / true ankle angle averaged over the pulse's last 50 ms;
- sinusoidal torques of each amplitude at each frequency for ``sine_cycles`` cycles; the last
  ``analysed_cycles`` give the first-harmonic impedance Z = T / Theta: dynamic stiffness Re Z, damping
  Im Z / w, the apparent inertia (K - Re Z) / w^2 (at the highest frequency, where it dominates), and
  the hysteresis: energy dissipated per cycle (the torque-angle loop's area, J) beyond what the
  commanded damping dissipates (pi B w theta_amp^2), and the joint-torque tracking error
  (desired minus strain-gauge torque, RMS). The ankle is passive when every cycle's loop area is
  >= 0 (the external torque puts energy in, the ankle never gives net energy back to the foot);
- (a separate run per ground) the torque step: the foot held at 0 by a ground spring (rigid or soft),
  the reference stepped so the impedance law asks ``step_nm`` [DP, IE] at once; overshoot of the
  strain-gauge torque over its final value.

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
DYNAMIC_MAX_HZ = 2.0      # dynamic stiffness and damping are judged on the sines up to this frequency
# the torque step's grounds: ((K_dp, K_ie) N m/rad, B N m s/rad) holding the foot at 0. "rigid" is as
# stiff as the explicit (held over a tick) ground stays stable on the 4 g m^2 foot (3000 is not)
GROUNDS = {"rigid": ((1000.0, 500.0), 1.0), "soft": ((300.0, 150.0), 1.0)}
FINAL_WINDOW_S = 0.2      # the step's final value: mean over the run's last this long
QUIET_WINDOW_S = 0.4      # the current noise at rest: the set values' spread over the settle's last this long


@dataclass(frozen=True)
class Experiment:
    """The torque programme, per axis (N m, s, Hz)."""

    pulses_nm: tuple[tuple[float, ...], tuple[float, ...]] = ((1.0, -1.0, 3.0, -3.0, 6.0, -6.0, 12.0, -12.0),
                                                              (1.0, -1.0, 3.0, -3.0, 6.0, -6.0))   # [DP, IE]
    pulse_s: float = 1.5
    rest_s: float = 1.0
    sine_hz: tuple[float, ...] = (0.5, 1.0, 2.0, 5.0)
    sine_nm: tuple[tuple[float, ...], tuple[float, ...]] = ((6.0, 15.0), (3.0, 7.5))   # amplitudes [DP, IE]
    sine_cycles: int = 4
    analysed_cycles: int = 2
    axes: tuple[str, ...] = AXES
    step_nm: tuple[float, float] = (6.0, 3.0)     # torque step [DP, IE]; (0, 0): no step runs
    step_s: float = 0.8                           # the step run lasts this long after the step


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
        for amp in exp.sine_nm[axis]:
            for f in exp.sine_hz:
                dur = exp.sine_cycles / f
                segs.append(Segment(axis, t, t + dur, "sine", amp, f))
                t += dur + exp.rest_s
    return segs, t


def simulated_s(exp: Experiment) -> float:
    """Simulated time (s) one commanded impedance costs: the programme's run and, when the
    experiment has a torque step, one step run per ground."""
    steps = len(GROUNDS) * (SETTLE_S + exp.step_s) if any(exp.step_nm) else 0.0
    return schedule(exp)[1] + steps


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
    steps: list[dict[str, Any]] = field(default_factory=list)
    fault: str = "NONE"
    final_offset_rad: float = math.nan   # max |ankle angle| over the last 0.1 s (back at the equilibrium?)
    current_noise_a: float = math.nan    # A: the larger motor's set-value RMS about its mean, at rest
    loops: list[dict[str, np.ndarray]] = field(default_factory=list)   # torque-angle loops for the plot

    def stiffness_error_max_pct(self, min_torque: float = 1.0) -> float:
        errs = [abs(p["error_pct"]) for p in self.pulses if abs(p["torque_nm"]) >= min_torque]
        return max(errs) if errs else math.nan

    def _dynamic(self, key: str) -> float:
        errs = [abs(s[key]) for s in self.sines if s["freq_hz"] <= DYNAMIC_MAX_HZ and not math.isnan(s[key])]
        return max(errs, default=math.nan)

    def dynamic_stiffness_error_max_pct(self) -> float:
        """Worst |Re Z / K - 1| over the sines up to DYNAMIC_MAX_HZ, all amplitudes, %."""
        return self._dynamic("dynamic_stiffness_error_pct")

    def damping_error_max_pct(self) -> float:
        """Worst |B rendered / B commanded - 1| over the sines up to DYNAMIC_MAX_HZ, %."""
        return self._dynamic("damping_error_pct")

    def apparent_inertia_kg_m2(self) -> float:
        """The largest (K - Re Z) / w^2 over the axes at the highest sine frequency and the smallest
        amplitude (the linear figure: a larger push also meets the correction clamp): the inertia
        the wearer moves."""
        if not self.sines:
            return math.nan
        f1 = max(s["freq_hz"] for s in self.sines)
        at = [s for s in self.sines if s["freq_hz"] == f1]
        return max(s["apparent_inertia_kg_m2"] for s in at
                   if s["amplitude_nm"] == min(t["amplitude_nm"] for t in at if t["axis"] == s["axis"]))

    def passive(self) -> bool:
        """No sine cycle gives net energy back to the foot (every loop area >= 0)."""
        return all(s["loop_energy_j"] >= 0.0 for s in self.sines)

    def torque_step_overshoot_pct(self) -> float:
        return max((s["overshoot_pct"] for s in self.steps), default=math.nan)

    def torque_step_ideal_overshoot_pct(self) -> float:
        """What an ideal renderer of the commanded impedance would show (:func:`run_torque_step`)."""
        return max((s["ideal_overshoot_pct"] for s in self.steps), default=math.nan)

    def torque_step_excess_pct(self) -> float:
        """The measured peak beyond the ideal renderer's (:func:`run_torque_step`), %."""
        return max((s["excess_pct"] for s in self.steps), default=math.nan)

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
                "steps": self.steps,
                "stiffness_error_max_pct": self.stiffness_error_max_pct(),
                "dynamic_stiffness_error_max_pct": self.dynamic_stiffness_error_max_pct(),
                "damping_error_max_pct": self.damping_error_max_pct(),
                "torque_step_overshoot_pct": self.torque_step_overshoot_pct(),
                "torque_step_ideal_overshoot_pct": self.torque_step_ideal_overshoot_pct(),
                "torque_step_excess_pct": self.torque_step_excess_pct(),
                "apparent_inertia_kg_m2": self.apparent_inertia_kg_m2(),
                "passive": self.passive(),
                "hysteresis_j_per_cycle": self.hysteresis_j_per_cycle(),
                "torque_tracking_rms_nm": self.torque_tracking_rms_nm(), "current_noise_a": self.current_noise_a}


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


# the Coulomb-like friction parameters of the simulator's friction effects (the viscous ones the gain
# margin already spans x0.5-x2)
COULOMB_LIKE = {"stribeck": ("static_excess",), "asymmetric_friction": ("coulomb_asymmetry", "coulomb_asymmetry_2"),
                "load_dependent_friction": ("coefficient",)}


def with_plant_friction(cfg: Config, scale: float) -> Config:
    """``cfg`` with its plant's Coulomb-like friction (``actuator.coulomb`` and the friction effects'
    static terms) times ``scale``: a device with less (or more) friction than its config states, for
    ``run_impedance(..., plant_cfg=...)`` while the controller keeps the stated model."""
    c = cfg.deep_copy()
    c["actuator"]["coulomb"] = scale * c["actuator"]["coulomb"]
    c["sim"]["effects"] = [{**e, **{k: scale * e[k] for k in COULOMB_LIKE.get(e.get("type"), ()) if k in e}}
                           for e in c["sim"]["effects"]]
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
    # what the loop makes of the gauges' noise and the encoders' counts with nothing to do: the set values'
    # spread at rest, before the first push (the loop amplifies noise in its rate term; the motor heats with it)
    quiet = (t >= SETTLE_S - QUIET_WINDOW_S) & (t < SETTLE_S)
    res.current_noise_a = float(max(np.std(run[f"current_cmd_{m}"][quiet]) for m in (1, 2)))
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
                          "dynamic_stiffness": float(Z.real),
                          "dynamic_stiffness_error_pct": 100.0 * (Z.real / K[s.axis] - 1.0),
                          "apparent_inertia_kg_m2": float((K[s.axis] - Z.real) / w ** 2),
                          "damping": float(Z.imag / w),
                          "damping_error_pct": 100.0 * (Z.imag / w / B[s.axis] - 1.0) if B[s.axis] > 0 else math.nan,
                          "loop_energy_j": area, "hysteresis_j": area - commanded_loss,
                          "torque_error_rms_nm": float(np.sqrt(np.mean(err ** 2)))})
        if keep_loops:
            res.loops.append({"axis": name, "freq_hz": s.freq, "amplitude_nm": s.size, "angle": th.copy(),
                              "torque": tau})
    if any(exp.step_nm):
        res.steps = [run_torque_step(cfg, exp, ground, plant_cfg=plant_cfg) for ground in GROUNDS]
    return res


def run_torque_step(cfg: Config, exp: Experiment, ground: str, *, plant_cfg: Config | None = None) -> dict[str, Any]:
    """The torque step on ``ground`` (a key of GROUNDS): the reference steps at SETTLE_S by step_nm / K per
    axis while the ground holds the foot; overshoot of the strain-gauge torque over its final value
    (worst axis, %) and the final torques (N m).

    The commanded impedance itself overshoots by this measure: an ideal renderer (no actuator
    dynamics) of the spring K pushes the foot with K ref = step_nm the instant the reference steps
    (the foot has not moved yet) and with step_nm g / (K + g) once the foot has settled into the
    ground g, an overshoot of 100 K / g % (``ideal_overshoot_pct``: 67 % for K 200 on the soft
    ground). ``excess_pct``: the measured peak beyond that ideal peak step_nm, in % of it: what the
    actuator adds (the apparent inertia ringing on the ground)."""
    from ankle_rt.backend import open_backend
    from ankle_rt.clock import SimClock
    from ankle_rt.daemon import run_lockstep

    (k0, k1), b = GROUNDS[ground]
    imp = cfg["controller"]["impedance"]
    c = cfg.deep_copy()
    c["reference"]["profile"] = "step"
    c["reference"]["step"] = {"dp": exp.step_nm[0] / imp["stiffness_dp"], "ie": exp.step_nm[1] / imp["stiffness_ie"],
                              "start_s": SETTLE_S}
    inner = open_backend(c if plant_cfg is None else plant_cfg, SimClock())
    backend = TorqueProgramBackend(inner, lambda t, x: (-k0 * x[0] - b * x[4], -k1 * x[1] - b * x[5]))
    try:
        run = run_lockstep(c, SETTLE_S + exp.step_s, backend=backend)
    finally:
        backend.close()
    t = run["t"]
    after, final = t >= SETTLE_S, t >= SETTLE_S + exp.step_s - FINAL_WINDOW_S
    out: dict[str, Any] = {"ground": ground, "fault": run.summary["fault"]}
    worst = worst_ideal = worst_excess = 0.0
    for axis, name in enumerate(AXES):
        tau = run[f"sg_torque_{name}"]
        end = float(np.mean(tau[final]))
        peak = float(np.max(tau[after] * math.copysign(1.0, end)))
        over = 100.0 * max(0.0, peak / abs(end) - 1.0) if end != 0.0 else math.inf
        ideal = 100.0 * imp[f"stiffness_{name}"] / (k0, k1)[axis]
        excess = 100.0 * max(0.0, peak / abs(exp.step_nm[axis]) - 1.0) if exp.step_nm[axis] else 0.0
        out[f"final_{name}_nm"], out[f"overshoot_{name}_pct"] = end, over
        out[f"ideal_overshoot_{name}_pct"], out[f"excess_{name}_pct"] = ideal, excess
        worst, worst_ideal, worst_excess = max(worst, over), max(worst_ideal, ideal), max(worst_excess, excess)
    out["overshoot_pct"], out["ideal_overshoot_pct"], out["excess_pct"] = worst, worst_ideal, worst_excess
    return out


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
