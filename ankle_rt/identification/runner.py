"""Running an experiment (a CycleController) on the configured backend through the daemon's own
loop, and the configuration the actuator experiments need (motors off the cables)."""

from __future__ import annotations

from typing import Callable, Protocol

import numpy as np

from ankle_rt.config import Config, ConfigError, merge
from ankle_rt.estimation import Estimate
from ankle_rt.identification.signals import IdentificationError
from ankle_rt.interchange import Recording


#: s of zero torque at the start of every experiment, counted from activation: the daemon's soft start
#: (controller.soft_start_s, 0.2 s by default) is over before any excitation begins
LEAD_S = 0.3


class Experiment(Protocol):
    """A CycleController that knows how long it runs."""

    duration_s: float

    def reset(self, est: Estimate) -> None: ...

    def update(self, est: Estimate, out_torque: np.ndarray) -> None: ...


#: runs ``controller`` for ``duration_s`` on ``cfg``'s backend and returns the interchange columns
Runner = Callable[[Config, Experiment, float], Recording]


def run_lockstep_recording(cfg: Config, controller: Experiment | None, duration_s: float) -> Recording:
    """The daemon's loop in lockstep (``ankle_rt.daemon.run_lockstep``), as an interchange Recording.
    ``controller=None`` runs the config's controller and reference. ``duration_s`` counts from
    activation, which follows the strain-gauge tare."""
    from ankle_rt.daemon import run_lockstep

    tare_s = cfg["estimation"]["tare_samples"] / cfg["controller"]["rate_hz"]  # the loop activates after the tare
    result = run_lockstep(cfg, duration_s + tare_s, controller=controller)
    name = type(controller).__name__ if controller is not None else "configured controller"
    return recording_of(result, f"{name} on backend {cfg['backend']!r}")


def recording_of(result, source: str) -> Recording:
    """The interchange columns of a daemon RunResult; a run that faulted is an error (its data stops)."""
    fault = result.summary.get("fault", "NONE")
    if fault != "NONE":
        raise IdentificationError(f"{source}: the daemon stopped the run with fault {fault}")
    return Recording({k: np.asarray(v, dtype=float) for k, v in result.interchange().items()}, source)


def with_overrides(cfg: Config, **sections: object) -> Config:
    """A deep copy of ``cfg`` with ``sections`` merged key by key, recursively (e.g.
    ``sim={"cables": False}``). The values must already be valid (they are not re-checked)."""
    out = cfg.deep_copy()
    merge(out, sections)
    return out


def actuator_config(cfg: Config) -> tuple[Config, str]:
    """The config for the actuator experiments (the paper's section 3: motors off the cables).

    ``sim.cables: false`` states that the motors are detached from the Bowden cables. The simulator
    then drops the cables itself, so for ``backend: sim`` the flag is set here, and the configured
    ankle disturbances are dropped too (they would swing the detached foot, whose joint encoders the
    safety layer still checks). On hardware the flag is a declaration by the operator that the cables
    are physically off (the experiments spin the motors for many turns, which would drive an attached
    ankle far past its limits; with the flag the daemon checks only the joint encoders, not the ankle
    angle estimated from the motors); the experiments refuse to run on hardware without it.
    Returns the config and a note for the report.
    """
    if cfg["backend"] == "sim":
        note = "motors off the cables (sim.cables: false" + (")" if not cfg["sim"]["cables"] else ", set for this run)")
        return with_overrides(cfg, sim={"cables": False, "disturbances": []}), note
    if not cfg["sim"]["cables"]:
        return cfg, "motors off the cables (sim.cables: false)"
    raise ConfigError("the actuator experiments need the motors detached from the Bowden cables: detach them "
                      "and set sim.cables: false to say so", getattr(cfg, "source", None), "sim.cables")
