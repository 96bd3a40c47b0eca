"""Random diagnosis cases: hidden effects (none, one, several, or one outside the vocabulary) in
simulated data, with or without sensor artefacts.

Shared by the diagnosis tests and benchmarks/bench_diagnose.py. A case draws, from its seed: the
effects and plausible magnitudes (rotor cogging through the gearbox on request), the plant's physical
parameters perturbed by +/-15 % around the nominal config, and two different trajectories
(identification and validation). All data come from the simulator (sim_backend) running the effects,
never from the diagnosis' own regressors. The data carry encoder quantisation, strain-gauge noise and
amplifier current noise, and on request sensor artefacts (:func:`corrupt`, :data:`ARTEFACTS`).
``--plant ankle`` cases run a motor PD loop tracking ankle references (multisine, gait-like or one
way: :func:`references`) against a multisine load on the foot; ``--plant actuator`` cases drive the
motors off the cables with open-loop multisine currents. :func:`draw_scenario` gives the benchmark's
mix.

The out-of-vocabulary effects ``kt_saturation`` (the torque constant dropping at high current),
``return_spring`` (a spring from each motor to the frame), ``position_friction`` (friction growing
along the travel) and ``friction_drift`` (Coulomb friction drifting with temperature) are test material, registered here rather
than in sim_backend: they are not product effects, and keeping them out of the simulator's library
keeps the library equal to the vocabulary the diagnosis can name.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ankle_rt.config import Config, Section, load_config, positive
from ankle_rt.interchange import Recording
from sim_backend.effects import EFFECTS, Effect, register_effect
from sim_backend.plant import SimulatedPlant

ROOT = Path(__file__).resolve().parent.parent
SIM_CONFIG = ROOT / "config" / "sim.yaml"
README_RUN_YAML = f"""\
include: [{SIM_CONFIG}]
reference:
  profile: chirp
  chirp: {{amplitude_dp: 0.09, amplitude_ie: 0.05, f0_hz: 0.2, f1_hz: 3.0, duration_s: 20.0, start_s: 0.3}}
loop:
  duration_s: 20.0
"""
"""The README's identification run (docs/diagnosis.md walkthrough): a 20 s chirp on the simulator."""
PERTURBATION = 0.15
RAMP_S = 0.5                # s, references and loads fade in over this
CURRENT_NOISE_A = 0.005     # A rms, amplifier current ripple (the set value is what gets recorded)


if "kt_saturation" not in EFFECTS:
    @register_effect("kt_saturation")
    class TorqueConstantSaturation(Effect):
        """OUT-OF-VOCABULARY TEST EFFECT: the torque constant falls at high current (magnetic saturation),
        applied torque = tau / sqrt(1 + (tau / saturation_torque)^2)."""

        PARAMS = Section({"saturation_torque": positive("N m at which the torque is 1/sqrt(2) of nominal")})
        cause = "unknown"

        def __init__(self, params, plant, dt):
            super().__init__(params, plant, dt)
            self.inv = 1.0 / params["saturation_torque"]

        def command(self, tau1, tau2):
            a, b = tau1 * self.inv, tau2 * self.inv
            return tau1 / math.sqrt(1.0 + a * a), tau2 / math.sqrt(1.0 + b * b)


if "return_spring" not in EFFECTS:
    @register_effect("return_spring")
    class ReturnSpring(Effect):
        """OUT-OF-VOCABULARY TEST EFFECT: a spring from each motor to the frame (a preloaded seal, a cable
        guide), resisting torque stiffness * theta_m."""

        PARAMS = Section({"stiffness": positive("N m/rad at the gearbox output")})
        cause = "unknown"

        def __init__(self, params, plant, dt):
            super().__init__(params, plant, dt)
            self.k = params["stiffness"]

        def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
            return self.k * th1, self.k * th2


if "position_friction" not in EFFECTS:
    @register_effect("position_friction")
    class PositionFriction(Effect):
        """OUT-OF-VOCABULARY TEST EFFECT: friction growing along the travel (a tight spot, a cable guide
        rubbing), extra Coulomb torque ``coefficient * theta_m^2 * tanh(w / v_eps)``."""

        PARAMS = Section({"coefficient": positive("N m/rad^2 at the gearbox output")})
        cause = "unknown"

        def __init__(self, params, plant, dt):
            super().__init__(params, plant, dt)
            self.c = params["coefficient"]
            self.inv_ve = 1.0 / plant.actuator.friction_smoothing_velocity

        def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
            c, ive = self.c, self.inv_ve
            return c * th1 * th1 * math.tanh(w1 * ive), c * th2 * th2 * math.tanh(w2 * ive)


if "friction_drift" not in EFFECTS:
    @register_effect("friction_drift")
    class FrictionDrift(Effect):
        """OUT-OF-VOCABULARY TEST EFFECT: the Coulomb friction drifting with temperature, by ``share`` of kc
        over a slow swing of ``period`` s: extra torque ``share kc sin(2 pi t / period) tanh(w / v_eps)``.
        Time is counted in control ticks (the command hook runs once per tick)."""

        PARAMS = Section({"share": positive("fraction of kc the friction drifts by"),
                          "period": positive("s, period of the slow swing")})
        cause = "unknown"

        def __init__(self, params, plant, dt):
            super().__init__(params, plant, dt)
            self.amp = params["share"] * plant.actuator.coulomb
            self.rate = 2 * math.pi * dt / params["period"]
            self.inv_ve = 1.0 / plant.actuator.friction_smoothing_velocity
            self.ticks = 0

        def reset(self) -> None:
            self.ticks = 0

        def command(self, tau1, tau2):
            self.ticks += 1
            return tau1, tau2

        def motor_torque(self, th1, th2, w1, w2, tc1, tc2):
            a, ive = self.amp * math.sin(self.rate * self.ticks), self.inv_ve
            return a * math.tanh(w1 * ive), a * math.tanh(w2 * ive)


# (effect, primary parameter, its range): the magnitude of a case is where its primary value lies
MAGNITUDES = {
    "stribeck": ("static_excess", (0.08, 0.3)),
    "asymmetric_friction": ("coulomb_asymmetry", (0.04, 0.12)),
    "load_dependent_friction": ("coefficient", (0.06, 0.3)),
    "cogging": ("amplitude", (0.04, 0.15)),
    "delay": ("delay", (0.002, 0.012)),
    "backlash": ("half_width", (5e-5, 4e-4)),
    "stiffness_nonlinear": ("hardening_stretch", (1.2e-3, 3e-4)),   # smaller stretch = stronger effect
    "torque_offset": ("torque_1", (0.1, 0.4)),
    "kt_saturation": ("saturation_torque", (6.0, 2.5)),            # smaller = stronger
    "return_spring": ("stiffness", (0.2, 1.0)),
    "position_friction": ("coefficient", (0.5, 1.5)),
    "friction_drift": ("share", (0.1, 0.2)),
}
OUT_OF_VOCABULARY = ("kt_saturation", "return_spring", "position_friction", "friction_drift")
MOTOR_EFFECTS = ("stribeck", "asymmetric_friction", "cogging", "delay", "torque_offset")
ANKLE_EFFECTS = MOTOR_EFFECTS + ("load_dependent_friction", "backlash", "stiffness_nonlinear")
#: rotor cogging periods per motor turn (pole/slot combinations of small BLDC motors)
ROTOR_COGGING_PERIODS = (4, 6, 8, 12, 14)
#: realistic rotor cogging: this share of the rated torque (kt x continuous current limit)
ROTOR_COGGING_SHARE = (0.01, 0.03)
#: Stribeck velocity (rad/s at the gearbox output), drawn log-uniformly ...
STRIBECK_VELOCITY = (0.03, 0.3)
#: ... but at least this in gait-like motion: the least walking data resolve. The gait reference
#: reverses the motors at up to ~75 rad/s^2 (output side), so |w| < vs lasts 2 vs / a per reversal:
#: 1 ms (one 1 kHz sample, 0.3 encoder counts of travel) for vs = 0.037, where the fit cannot tell the
#: Stribeck amplitude from its velocity and predicts the validation data worse (seed 1061); from
#: ~0.1 rad/s (>= 2.7 samples per reversal) it is named. docs/diagnosis.md, limits.
GAIT_MIN_STRIBECK_VELOCITY = 0.1
#: sensor and data artefacts a case can carry (not physics: flagged, never named)
ARTEFACTS = ("sg_clip", "sg_drift", "sg_hold", "current_limit", "dropouts")
#: further sensor faults, for the targeted tests (not drawn by the benchmark's scenarios): gauges clipped
#: before their noise is added (a rail that is not exactly flat), constant gauge zero offsets, motor
#: encoders scaled against the ankle encoders
SENSOR_FAULTS = ("sg_clip_noise", "sg_offset", "encoder_scale")
ENCODER_SCALE = 1.015           # the motor encoders read this x the true angle in the "encoder_scale" fault
SG_OFFSET_NM = (0.3, -0.25)     # N m on DP, IE of the "sg_offset" fault
MOTIONS = ("multisine", "gait", "one_way")


def draw_effect(name: str, rng: np.random.Generator, strength: float | None = None,
                cfg: Config | None = None, rotor: bool = False, motion: str = "multisine") -> tuple[dict, float]:
    """(sim.effects entry, magnitude in [0, 1]) with a plausible random size; ``strength`` < 1 instead
    makes it that fraction of the weakest plausible size (magnitude reported as 0). ``rotor``: cogging
    of the motor's rotor seen through the gearbox (periods per motor turn x gear ratio, 1-3 % of the
    rated torque; needs ``cfg``) instead of a gear-mesh ripple of 6-60 periods per output turn.
    ``motion``: the experiment's kind (in gait-like motion the Stribeck velocity is drawn from
    GAIT_MIN_STRIBECK_VELOCITY up)."""
    key, (lo, hi) = MAGNITUDES[name]
    mag = float(rng.uniform())
    value = lo + mag * (hi - lo)
    if strength is not None:
        mag = 0.0
        value = lo * strength if hi > lo else lo / strength
    entry: dict = {"type": name, key: value}
    if name == "stribeck":
        lo_v = GAIT_MIN_STRIBECK_VELOCITY if motion == "gait" else STRIBECK_VELOCITY[0]
        entry["stribeck_velocity"] = float(np.exp(rng.uniform(np.log(lo_v), np.log(STRIBECK_VELOCITY[1]))))
    elif name == "asymmetric_friction":
        sign = float(rng.choice([-1.0, 1.0]))
        entry[key] = sign * value
        entry["viscous_asymmetry"] = sign * float(rng.uniform(0.0, 0.015))
    elif name == "cogging" and rotor:
        rated = cfg["actuator"]["torque_constant"] * cfg["amplifier"]["current_limit_continuous"]
        share = ROTOR_COGGING_SHARE[0] + mag * (ROTOR_COGGING_SHARE[1] - ROTOR_COGGING_SHARE[0])
        entry[key] = share * rated
        entry["periods_per_rev"] = int(rng.choice(ROTOR_COGGING_PERIODS)) * int(cfg["actuator"]["gear_ratio"])
        entry["phase"] = float(rng.uniform(0.0, 2 * math.pi))
    elif name == "cogging":
        entry["periods_per_rev"] = int(rng.integers(6, 61))
        entry["phase"] = float(rng.uniform(0.0, 2 * math.pi))
    elif name == "friction_drift":
        entry["period"] = float(rng.uniform(20.0, 40.0))
    elif name == "torque_offset":
        entry[key] = float(rng.choice([-1.0, 1.0])) * value
        entry["torque_2"] = float(rng.choice([-1.0, 1.0])) * float(rng.uniform(lo, hi))
    return entry, mag


@dataclass
class Case:
    seed: int
    plant: str                 # "ankle" or "actuator"
    causes: tuple[str, ...]    # the vocabulary words expected, sorted ("none",) or (..., "unknown")
    effects: list[dict]        # the hidden sim.effects entries
    magnitude: float           # 0 (weakest of the plausible range) .. 1 (strongest), of the first effect
    truth_cfg: Config          # the perturbed plant that made the data
    nominal_cfg: Config        # what the diagnosis is given
    ident: Recording
    valid: Recording
    artefacts: tuple[str, ...] = ()
    motion: str = "multisine"

    @property
    def cause(self) -> str:
        """The one expected word of a single-effect case (the first of ``causes``)."""
        return self.causes[0]

    @property
    def effect(self) -> dict | None:
        return self.effects[0] if self.effects else None

    def describe(self) -> str:
        return (f"seed={self.seed} plant={self.plant} causes={list(self.causes)} effects={self.effects} "
                f"artefacts={list(self.artefacts)} motion={self.motion}")


def _nominal() -> Config:
    return load_config(SIM_CONFIG)


def perturbed(cfg: Config, rng: np.random.Generator) -> Config:
    out = cfg.deep_copy()
    for key in ("inertia", "damping", "coulomb"):
        out["actuator"][key] *= 1.0 + rng.uniform(-PERTURBATION, PERTURBATION)
    out["transmission"]["cable_stiffness"] *= 1.0 + rng.uniform(-PERTURBATION, PERTURBATION)
    return out


class Multisine:
    """Sum of sines with random phases; amplitudes fall as 1/f (smooth, rich)."""

    def __init__(self, rng: np.random.Generator, f_lo: float, f_hi: float, n: int, rms: float):
        self.f = np.exp(rng.uniform(np.log(f_lo), np.log(f_hi), n))
        self.p = rng.uniform(0, 2 * np.pi, n)
        a = 1.0 / self.f
        self.a = a * rms / math.sqrt(0.5 * float(a @ a))

    def samples(self, t: np.ndarray) -> np.ndarray:
        return (self.a[None, :] * np.sin(2 * np.pi * self.f[None, :] * t[:, None] + self.p[None, :])).sum(1)


def gait(rng: np.random.Generator, t: np.ndarray, amplitude: float) -> np.ndarray:
    """A walking-like periodic angle: a stride of ~1 s, a few harmonics with a push-off peak, the stride
    time varying a little from step to step."""
    stride = rng.uniform(0.9, 1.2)
    phase = 2 * np.pi * t / stride + 0.3 * np.sin(2 * np.pi * t / rng.uniform(5.0, 9.0))
    harm = rng.uniform(0.2, 1.0, 4) / np.arange(1, 5)
    off = rng.uniform(0, 2 * np.pi, 4)
    x = sum(h * np.sin(k * phase + o) for k, (h, o) in enumerate(zip(harm, off), start=1))
    return amplitude * x / max(float(np.std(x)), 1e-12) / math.sqrt(2.0)


def references(rng: np.random.Generator, t: np.ndarray, motion: str) -> np.ndarray:
    """Ankle reference angles [DP, IE] (rad) of one experiment."""
    if motion == "gait":
        return np.column_stack([gait(rng, t, 0.05), gait(rng, t, 0.02)])
    if motion == "one_way":
        # a slow sweep in one direction with a small ripple that never reverses it
        rate = rng.uniform(0.02, 0.04) * rng.choice([-1.0, 1.0])
        dp = rate * t + 0.2 * abs(rate) * np.sin(2 * np.pi * 0.7 * t) / (2 * np.pi * 0.7) * 0.8
        return np.column_stack([dp, 0.5 * dp])
    return np.column_stack([Multisine(rng, 0.1, 3.0, 7, 0.12).samples(t), Multisine(rng, 0.1, 3.0, 7, 0.06).samples(t)])


def simulate(cfg: Config, plant_kind: str, rng: np.random.Generator, duration_s: float,
             motion: str = "multisine", current_limit: float | None = None) -> Recording:
    """Run one experiment on a fresh SimulatedPlant and record it in interchange columns.
    ``current_limit`` (A): the amplifier saturates there (its current loop then delivers only 95 % of
    the limit while the recorded set value sits on the rail)."""
    plant = SimulatedPlant(cfg)
    dt = plant.dt
    n = int(round(duration_s / dt))
    t = np.arange(n) * dt
    kt = plant.kt
    noise = CURRENT_NOISE_A * rng.standard_normal((n, 2))
    cols = {name: np.empty(n) for name in ("t", "motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2",
                                           "sg_torque_dp", "sg_torque_ie", "ankle_dp", "ankle_ie")}
    if plant_kind == "actuator":
        i1 = Multisine(rng, 0.2, 6.0, 8, rng.uniform(0.5, 0.9)).samples(t)
        i2 = Multisine(rng, 0.2, 6.0, 8, rng.uniform(0.5, 0.9)).samples(t)
        ref = load = None
    else:
        R = np.array([[cfg["transmission"]["lever_dp"], cfg["transmission"]["lever_ie"]],
                      [cfg["transmission"]["lever_dp"], -cfg["transmission"]["lever_ie"]]]) \
            / cfg["transmission"]["pulley_radius"]
        ref = references(rng, t, motion) @ R.T
        load_rms = (4.0, 2.0) if motion != "one_way" else (1.0, 0.5)
        load = np.column_stack([Multisine(rng, 0.1, 4.0, 6, load_rms[0]).samples(t),
                                Multisine(rng, 0.1, 4.0, 6, load_rms[1]).samples(t)])
        fade_in = np.minimum(1.0, t / RAMP_S)[:, None]    # no start-up jump of the PD loop
        if motion != "one_way":
            ref *= fade_in
        load *= fade_in
        kp, kd = 60.0, 1.0
    x = plant.model.x
    limit = 0.9 * cfg["amplifier"]["current_limit_continuous"]
    rail = current_limit if current_limit is not None else math.inf
    for k in range(n):
        p1, p2 = plant.motor_positions()
        s1, s2 = plant.strain_gauge_torques()
        a1, a2 = plant.ankle_positions()
        if ref is None:
            c1, c2 = float(i1[k]), float(i2[k])
        else:
            c1 = (kp * (ref[k, 0] - p1) - kd * x[6]) / kt
            c2 = (kp * (ref[k, 1] - p2) - kd * x[7]) / kt
            c1 = max(-limit, min(limit, c1))
            c2 = max(-limit, min(limit, c2))
            plant.extra_disturbance[0] = float(load[k, 0])
            plant.extra_disturbance[1] = float(load[k, 1])
        c1, c2 = max(-rail, min(rail, c1)), max(-rail, min(rail, c2))
        row = (k * dt, p1, p2, c1, c2, s1, s2, a1, a2)
        for name, v in zip(cols, row):
            cols[name][k] = v
        u1 = 0.95 * c1 if abs(c1) >= rail else c1
        u2 = 0.95 * c2 if abs(c2) >= rail else c2
        plant.step(u1 + noise[k, 0], u2 + noise[k, 1])
    if plant_kind == "actuator":
        cols = {k: v for k, v in cols.items() if k in ("t", "motor_pos_1", "current_cmd_1")}
    return Recording(cols, f"simulated {plant_kind} run")


def corrupt(rec: Recording, artefact: str, rng: np.random.Generator) -> Recording:
    """The recording as a faulty sensor or link would deliver it (``current_limit`` acts in
    :func:`simulate`)."""
    cols = {k: v.copy() for k, v in rec.columns.items()}
    n = len(rec)
    if artefact == "sg_clip":           # gauges' amplifier saturating at 70 % of the peak torque
        for c in ("sg_torque_dp", "sg_torque_ie"):
            level = 0.7 * float(np.max(np.abs(cols[c])))
            cols[c] = np.clip(cols[c], -level, level)
    elif artefact == "sg_clip_noise":   # saturating before the noise is added: the rail is not flat
        for c in ("sg_torque_dp", "sg_torque_ie"):
            level = 0.7 * float(np.max(np.abs(cols[c])))
            cols[c] = np.clip(cols[c], -level, level) + 0.02 * rng.standard_normal(n)
    elif artefact == "sg_offset":       # zero offsets (tared under load, or a shifted bridge)
        for c, off in zip(("sg_torque_dp", "sg_torque_ie"), SG_OFFSET_NM):
            cols[c] += off
    elif artefact == "encoder_scale":
        for c in ("motor_pos_1", "motor_pos_2"):
            cols[c] *= ENCODER_SCALE
    elif artefact == "sg_drift":        # offsets wandering slowly (temperature)
        u = np.linspace(0.0, 1.0, n)
        for c in ("sg_torque_dp", "sg_torque_ie"):
            wander = u + 0.5 * np.sin(np.pi * u * rng.uniform(1, 2))
            cols[c] += rng.uniform(0.2, 0.5) * rng.choice([-1.0, 1.0]) * wander
    elif artefact == "sg_hold":         # bursts of repeated samples (stale values on the bus)
        for start in rng.integers(0, n - 200, max(4, n // 2000)):
            length = int(rng.integers(20, 150))
            for c in ("sg_torque_dp", "sg_torque_ie"):
                cols[c][start:start + length] = cols[c][start]
    elif artefact == "dropouts":        # lost frames: rows missing, time stamps jump
        keep = np.ones(n, dtype=bool)
        for start in rng.integers(100, n - 200, max(3, n // 3000)):
            keep[start:start + int(rng.integers(5, 60))] = False
        cols = {k: v[keep] for k, v in cols.items()}
    return Recording(cols, rec.source + f" ({artefact})")


def make_case(seed: int, plant: str = "ankle", cause: str | list[str] | None = None, ident_s: float = 12.0,
              valid_s: float = 6.0, p_none: float = 0.25, p_unknown: float = 0.1,
              strength: float | None = None, artefacts: tuple[str, ...] = (), motion: str = "multisine",
              rotor_cogging: bool = False, effects: list[dict] | None = None, kt_scale: float = 1.0) -> Case:
    """Draw a case from ``seed``. ``cause``: an effect name, a list of them (several at once), "none" or
    an out-of-vocabulary one; else random (``p_none`` effect-free, ``p_unknown`` out of vocabulary, the
    rest uniform over the vocabulary). ``strength``: see :func:`draw_effect`. ``artefacts``: sensor and
    data faults (:data:`ARTEFACTS`); ``motion``: the reference's kind (:data:`MOTIONS`);
    ``rotor_cogging``: cogging at the rotor's count through the gearbox (see :func:`draw_effect`);
    ``effects``: explicit sim.effects entries instead of drawn ones (``cause`` then gives the expected
    words); ``kt_scale``: the true torque constant is this x the configured one (a calibration error).
    With ``current_limit`` the config given to the diagnosis states that amplifier limit."""
    rng = np.random.default_rng(seed)
    pool = ANKLE_EFFECTS if plant == "ankle" else MOTOR_EFFECTS
    if cause is None:
        u = rng.uniform()
        if u < p_none:
            cause = "none"
        elif u < p_none + p_unknown:
            cause = str(rng.choice(OUT_OF_VOCABULARY))
        else:
            cause = str(rng.choice(pool))
    names = [cause] if isinstance(cause, str) else list(cause)
    names = [c for c in names if c != "none"]
    nominal = _nominal()
    truth = perturbed(nominal, rng)
    truth["sim"]["seed"] = int(seed)
    truth["sim"]["cables"] = plant == "ankle"
    truth["actuator"]["torque_constant"] *= kt_scale
    drawn = ([(e, 1.0) for e in effects] if effects is not None
             else [draw_effect(c, rng, strength, truth, rotor_cogging, motion) for c in names])
    effects = [e for e, _ in drawn]
    truth["sim"]["effects"] = effects
    limit = None
    if "current_limit" in artefacts:      # an amplifier limit the experiment reaches now and then
        probe = simulate(truth, plant, copy.deepcopy(rng), ident_s, motion)     # the same experiment
        limit = float(np.percentile(np.abs(probe.motor_input(1.0)), 99.5))
        nominal = nominal.deep_copy()
        nominal["amplifier"]["current_limit_peak"] = limit
        nominal["amplifier"]["current_limit_continuous"] = min(limit, nominal["amplifier"]["current_limit_continuous"])
    ident = simulate(truth, plant, rng, ident_s, motion, limit)
    valid = simulate(truth, plant, rng, valid_s, motion, limit)
    for a in artefacts:
        if a != "current_limit":
            ident, valid = corrupt(ident, a, rng), corrupt(valid, a, rng)
    words = sorted({"unknown" if c in OUT_OF_VOCABULARY else c for c in names}) or ["none"]
    return Case(seed, plant, tuple(words), effects, drawn[0][1] if drawn else 0.0, truth, nominal, ident, valid,
                tuple(artefacts), motion)


def primary_error(case: Case, parameters: dict, effect: str | None = None) -> float | None:
    """Relative error of an effect's primary parameter (the case's first effect unless ``effect`` names
    one; None when not applicable)."""
    entry = next((e for e in case.effects if e["type"] == (effect or case.effects[0]["type"])), None) \
        if case.effects else None
    if entry is None or entry["type"] in OUT_OF_VOCABULARY:
        return None
    key = MAGNITUDES[entry["type"]][0]
    if key not in parameters:
        return None
    true = entry[key]
    return abs(parameters[key]["value"] - true) / abs(true)


#: scenario kinds of the extended benchmark and their shares
SCENARIOS = (("single", 0.22), ("two", 0.27), ("three", 0.15), ("none", 0.07), ("out_of_vocabulary", 0.05),
             ("artefact_only", 0.11), ("artefact_and_effect", 0.05), ("short", 0.04), ("one_way", 0.04))


def draw_scenario(seed: int, actuator_share: float = 0.2) -> dict:
    """The keyword arguments of :func:`make_case` for one case of the extended benchmark, from ``seed``:
    one, two or three effects at once (rotor cogging through the gearbox in a third of the cogging
    cases), effect-free and out-of-vocabulary data, sensor artefacts with and without effects, gait-like
    motion in a quarter of the ankle cases, one-directional motion and short records."""
    rng = np.random.default_rng(seed + 7_000_000)
    kinds, shares = zip(*SCENARIOS)
    kind = str(rng.choice(kinds, p=np.array(shares) / sum(shares)))
    plant = "actuator" if kind in ("single", "two", "none") and rng.uniform() < actuator_share else "ankle"
    pool = list(ANKLE_EFFECTS if plant == "ankle" else MOTOR_EFFECTS)
    spec: dict = {"seed": seed, "plant": plant, "cause": "none", "artefacts": (), "motion": "multisine",
                  "rotor_cogging": False}
    count = {"single": 1, "two": 2, "three": 3, "artefact_and_effect": 1, "short": 1}.get(kind, 0)
    if count:
        spec["cause"] = [str(c) for c in rng.choice(pool, count, replace=False)]
    if kind == "out_of_vocabulary":
        spec["cause"] = str(rng.choice(OUT_OF_VOCABULARY))
    if kind in ("artefact_only", "artefact_and_effect"):
        spec["artefacts"] = (str(rng.choice(ARTEFACTS)),)
        if spec["artefacts"] == ("sg_drift",) and "torque_offset" in spec["cause"]:
            spec["cause"] = ["stribeck"]    # a drifting gauge hides a load offset (docs/diagnosis.md, limits)
    if kind == "short":
        spec["ident_s"], spec["valid_s"] = 4.0, 2.0
    if kind == "one_way":
        spec["motion"] = "one_way"
        spec["cause"] = "cogging" if rng.uniform() < 0.5 else "none"
    elif plant == "ankle" and not spec["artefacts"] and rng.uniform() < 0.25:
        spec["motion"] = "gait"
    causes = [spec["cause"]] if isinstance(spec["cause"], str) else spec["cause"]
    spec["rotor_cogging"] = "cogging" in causes and rng.uniform() < 0.34
    return spec
