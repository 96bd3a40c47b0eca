"""Random diagnosis cases: a hidden effect (or none, or one outside the vocabulary) in simulated data.

Shared by the diagnosis tests and benchmarks/bench_diagnose.py. A case draws, from its seed:
the effect and a plausible magnitude, the plant's physical parameters perturbed by +/-15 % around the
nominal config, and two different rich trajectories (identification and validation). The data carry
encoder quantisation, strain-gauge noise and amplifier current noise. ``--plant ankle`` cases run a
motor PD loop tracking multisine ankle references against a multisine load on the foot;
``--plant actuator`` cases drive the motors off the cables with open-loop multisine currents.

The out-of-vocabulary effects ``kt_saturation`` (the torque constant dropping at high current) and
``return_spring`` (a spring from each motor to the frame) are test material, registered here rather
than in sim_backend: they are not product effects, and keeping them out of the simulator's library
keeps the library equal to the vocabulary the diagnosis can name.
"""

from __future__ import annotations

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


# (effect, primary parameter, its range): the magnitude of a case is where its primary value lies
MAGNITUDES = {
    "stribeck": ("static_excess", (0.08, 0.3)),
    "asymmetric_friction": ("coulomb_asymmetry", (0.04, 0.12)),
    "load_dependent_friction": ("coefficient", (0.06, 0.3)),
    "cogging": ("amplitude", (0.04, 0.15)),
    "delay": ("delay", (0.002, 0.012)),
    "backlash": ("half_width", (5e-5, 4e-4)),
    "stiffness_nonlinear": ("hardening_stretch", (1.2e-3, 3e-4)),   # smaller stretch = stronger effect
    "kt_saturation": ("saturation_torque", (6.0, 2.5)),            # smaller = stronger
    "return_spring": ("stiffness", (0.2, 1.0)),
}
OUT_OF_VOCABULARY = ("kt_saturation", "return_spring")
MOTOR_EFFECTS = ("stribeck", "asymmetric_friction", "cogging", "delay")
ANKLE_EFFECTS = MOTOR_EFFECTS + ("load_dependent_friction", "backlash", "stiffness_nonlinear")


def draw_effect(name: str, rng: np.random.Generator, strength: float | None = None) -> tuple[dict, float]:
    """(sim.effects entry, magnitude in [0, 1]) with a plausible random size; ``strength`` < 1 instead
    makes it that fraction of the weakest plausible size (magnitude reported as 0)."""
    key, (lo, hi) = MAGNITUDES[name]
    mag = float(rng.uniform())
    value = lo + mag * (hi - lo)
    if strength is not None:
        mag = 0.0
        value = lo * strength if hi > lo else lo / strength
    entry: dict = {"type": name, key: value}
    if name == "stribeck":
        entry["stribeck_velocity"] = float(np.exp(rng.uniform(np.log(0.03), np.log(0.3))))
    elif name == "asymmetric_friction":
        sign = float(rng.choice([-1.0, 1.0]))
        entry[key] = sign * value
        entry["viscous_asymmetry"] = sign * float(rng.uniform(0.0, 0.015))
    elif name == "cogging":
        entry["periods_per_rev"] = int(rng.integers(6, 61))
        entry["phase"] = float(rng.uniform(0.0, 2 * math.pi))
    return entry, mag


@dataclass
class Case:
    seed: int
    plant: str                 # "ankle" or "actuator"
    cause: str                 # the vocabulary word expected ("none", ..., "unknown" for kt_saturation)
    effect: dict | None        # the hidden sim.effects entry
    magnitude: float           # 0 (weakest of the plausible range) .. 1 (strongest)
    truth_cfg: Config          # the perturbed plant that made the data
    nominal_cfg: Config        # what the diagnosis is given
    ident: Recording
    valid: Recording

    def describe(self) -> str:
        return f"seed={self.seed} plant={self.plant} cause={self.cause} effect={self.effect}"


def _nominal() -> Config:
    cfg = load_config(SIM_CONFIG)
    return cfg


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


def simulate(cfg: Config, plant_kind: str, rng: np.random.Generator, duration_s: float) -> Recording:
    """Run one experiment on a fresh SimulatedPlant and record it in interchange columns."""
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
        ref = np.column_stack([Multisine(rng, 0.1, 3.0, 7, 0.12).samples(t),
                               Multisine(rng, 0.1, 3.0, 7, 0.06).samples(t)]) @ R.T
        load = np.column_stack([Multisine(rng, 0.1, 4.0, 6, 4.0).samples(t),
                                Multisine(rng, 0.1, 4.0, 6, 2.0).samples(t)])
        fade_in = np.minimum(1.0, t / RAMP_S)[:, None]    # no start-up jump of the PD loop
        ref *= fade_in
        load *= fade_in
        kp, kd = 60.0, 1.0
    x = plant.model.x
    limit = 0.9 * cfg["amplifier"]["current_limit_continuous"]
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
        row = (k * dt, p1, p2, c1, c2, s1, s2, a1, a2)
        for name, v in zip(cols, row):
            cols[name][k] = v
        plant.step(c1 + noise[k, 0], c2 + noise[k, 1])
    if plant_kind == "actuator":
        cols = {k: v for k, v in cols.items() if k in ("t", "motor_pos_1", "current_cmd_1")}
    return Recording(cols, f"simulated {plant_kind} run")


def make_case(seed: int, plant: str = "ankle", cause: str | None = None, ident_s: float = 12.0,
              valid_s: float = 6.0, p_none: float = 0.25, p_unknown: float = 0.1,
              strength: float | None = None) -> Case:
    """Draw a case from ``seed``. ``cause``: force an effect name, "none" or an out-of-vocabulary one; else
    random (``p_none`` effect-free, ``p_unknown`` out of vocabulary, the rest uniform over the vocabulary).
    ``strength``: see :func:`draw_effect`."""
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
    nominal = _nominal()
    truth = perturbed(nominal, rng)
    truth["sim"]["seed"] = int(seed)
    truth["sim"]["cables"] = plant == "ankle"
    effect, mag = (None, 0.0) if cause == "none" else draw_effect(cause, rng, strength)
    truth["sim"]["effects"] = [effect] if effect else []
    ident = simulate(truth, plant, rng, ident_s)
    valid = simulate(truth, plant, rng, valid_s)
    expected = "unknown" if cause in OUT_OF_VOCABULARY else cause
    return Case(seed, plant, expected, effect, mag, truth, nominal, ident, valid)


def primary_error(case: Case, parameters: dict) -> float | None:
    """Relative error of the case's primary effect parameter (None when not applicable)."""
    if case.effect is None or case.cause == "unknown":
        return None
    key = MAGNITUDES[case.effect["type"]][0]
    if key not in parameters:
        return None
    true = case.effect[key]
    return abs(parameters[key]["value"] - true) / abs(true)
