"""The paper's section 3 as one procedure: run (or read) the stiction, viscous and inertia experiments,
estimate in the order that lets each use the others (viscous -> inertia with the sliding friction
-> stiction with J and D), and turn the result into config parameters.

Which estimate becomes which config key (``parameter_fragment``):
- ``actuator.inertia`` = J of the step fits;
- ``actuator.damping`` = kv from the viscous experiment (mean of both directions), else D of the
  step fits: the steady-state measurement is the direct one (the paper also sets D = kv);
- ``actuator.coulomb`` = the sliding Coulomb level of the viscous experiment, else the stiction
  (breakaway) level: the simulator's friction law kc tanh(w / v_eps) is the sliding friction;
- a significant direction difference becomes an ``asymmetric_friction`` effect in ``sim.effects``
  (coulomb_asymmetry = (kc+ - kc-) / 2, viscous_asymmetry = (kv+ - kv-) / 2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

from ankle_rt.config import Config
from ankle_rt.identification.inertia import InertiaResult, TorqueStepExperiment, estimate_inertia
from ankle_rt.identification.runner import Runner, run_lockstep_recording
from ankle_rt.identification.signals import IdentificationError
from ankle_rt.identification.stats import Measured
from ankle_rt.identification.stiction import StictionExperiment, StictionResult, estimate_stiction
from ankle_rt.identification.viscous import VelocityHoldExperiment, ViscousResult, estimate_viscous
from ankle_rt.interchange import Recording

EXPERIMENTS = ("stiction", "viscous", "inertia")
#: fewest rows (one cycle each) a recording needs for each experiment: one ramp, two plateaus
#: per direction, one step with its coast-down at 1 kHz.
MIN_ROWS = {"stiction": 1000, "viscous": 2000, "inertia": 600}
#: an asymmetry smaller than this (N m) is not written as an effect
ASYMMETRY_FLOOR = 0.005


def make_experiment(name: str, motor: int, repeats: int):
    """The experiment controller of ``name`` with its default schedule."""
    cls = {"stiction": StictionExperiment, "viscous": VelocityHoldExperiment, "inertia": TorqueStepExperiment}[name]
    return cls(motor=motor, repeats=repeats)


def run_experiments(cfg: Config, names: tuple[str, ...], motor: int = 1, repeats: int = 3,
                    run: Runner = run_lockstep_recording,
                    progress: Callable[[float, float, str], None] | None = None) -> dict[str, Recording]:
    """Run each experiment on ``cfg``'s backend (``cfg`` must already have the motors off the cables).
    ``progress(done, total, what)`` is called before and after each, in experiment seconds."""
    experiments = [make_experiment(name, motor, repeats) for name in names]
    total = sum(e.duration_s for e in experiments)
    done = 0.0
    recordings = {}
    for name, experiment in zip(names, experiments):
        if progress is not None:
            progress(done, total, name)
        recordings[name] = run(cfg, experiment, experiment.duration_s)
        done += experiment.duration_s
    if progress is not None:
        progress(total, total, "done")
    return recordings


@dataclass
class ActuatorIdentification:
    """Results of the experiments that were run (None for those that were not)."""

    stiction: StictionResult | None = None
    viscous: ViscousResult | None = None
    inertia: InertiaResult | None = None
    prior: dict = field(default_factory=dict)   # actuator config the run started from (may be empty)
    notes: list[str] = field(default_factory=list)

    def kc_pair(self) -> tuple[Measured, Measured] | None:
        """(kc+, kc-) for the config: sliding (viscous) if measured, else breakaway (stiction)."""
        if self.viscous is not None:
            return self.viscous.kc_pos, self.viscous.kc_neg
        if self.stiction is not None:
            return self.stiction.kc_pos, self.stiction.kc_neg
        return None

    def parameter_fragment(self) -> dict:
        """The config keys this identification sets (see the module docstring)."""
        actuator: dict[str, float] = {}
        out: dict = {"actuator": actuator}
        if self.inertia is not None:
            actuator["inertia"] = round(self.inertia.inertia.mean, 6)
        if self.viscous is not None:
            actuator["damping"] = round(self.viscous.kv, 6)
        elif self.inertia is not None:
            actuator["damping"] = round(self.inertia.damping.mean, 6)
        pair = self.kc_pair()
        if pair is not None:
            kc_pos, kc_neg = pair
            actuator["coulomb"] = round(0.5 * (kc_pos.mean + kc_neg.mean), 6)
            dc = 0.5 * (kc_pos.mean - kc_neg.mean)
            dv = 0.5 * (self.viscous.kv_pos.mean - self.viscous.kv_neg.mean) if self.viscous else 0.0
            sd = math.hypot(*(0.0 if math.isnan(m.sd) else m.sd for m in pair))
            if abs(2 * dc) > max(ASYMMETRY_FLOOR, 2 * sd):
                out["sim"] = {"effects": [{"type": "asymmetric_friction", "coulomb_asymmetry": round(dc, 6),
                                           "viscous_asymmetry": round(dv, 6)}]}
        return out


def identify(recordings: dict[str, Recording], motor: int = 1, kt: float | None = None,
             prior: dict | None = None) -> ActuatorIdentification:
    """Estimate from one recording per experiment (keys from EXPERIMENTS). ``prior`` is the config's
    actuator section: shown beside the results, and J and D for the stiction correction when the
    inertia experiment is absent. The estimates themselves never start from it."""
    prior = dict(prior or {})
    result = ActuatorIdentification(prior=prior)
    if "viscous" in recordings:
        result.viscous = estimate_viscous(recordings["viscous"], motor, kt)
    if "inertia" in recordings:
        coulomb = (result.viscous.kc_pos.mean, result.viscous.kc_neg.mean) if result.viscous else None
        result.inertia = estimate_inertia(recordings["inertia"], motor, kt, coulomb=coulomb)
        if coulomb is None:
            result.notes.append("inertia: kc fitted per step (no viscous experiment to fix it)")
    if "stiction" in recordings:
        if result.inertia is not None:
            J, D = result.inertia.inertia.mean, result.inertia.damping.mean
            source = "the inertia experiment"
        elif "inertia" in prior and "damping" in prior:
            J, D = prior["inertia"], prior["damping"]
            source = "the config"
        else:
            raise IdentificationError("the stiction estimate needs J and D for its acceleration correction: "
                                      "give --config or identify inertia too")
        result.stiction = estimate_stiction(recordings["stiction"], motor, kt, inertia=J, damping=D)
        result.notes.append(f"stiction: acceleration correction with J = {J:.4g} kg m^2, D = {D:.4g} N m s/rad from {source}")
    return result
