"""Running an experiment (a CycleController) on the configured backend through the daemon's own
loop, and the configuration the actuator experiments need (motors off the cables)."""

from __future__ import annotations

import copy
from typing import Callable, Protocol

import numpy as np

from ankle_rt.config import Config, ConfigError
from ankle_rt.interchange import Recording


class Experiment(Protocol):
    """A CycleController that knows how long it runs."""

    duration_s: float

    def reset(self, est) -> None: ...

    def update(self, est, out_torque: np.ndarray) -> None: ...


#: runs ``controller`` for ``duration_s`` on ``cfg``'s backend and returns the interchange columns
Runner = Callable[[Config, Experiment, float], Recording]


def run_lockstep_recording(cfg: Config, controller: Experiment, duration_s: float) -> Recording:
    """The daemon's loop in lockstep (``ankle_rt.daemon.run_lockstep``), as an interchange Recording."""
    from ankle_rt.daemon import run_lockstep

    result = run_lockstep(cfg, duration_s, controller=controller)
    columns = {k: np.asarray(v, dtype=float) for k, v in result.interchange().items()}
    return Recording(columns, f"{type(controller).__name__} on backend {cfg['backend']!r}")


def with_overrides(cfg: Config, **sections: dict) -> Config:
    """A deep copy of ``cfg`` with ``sections`` merged key by key (e.g. ``sim={"cables": False}``)."""
    out = Config(copy.deepcopy(dict(cfg)))
    out.source = getattr(cfg, "source", "<memory>")
    for name, values in sections.items():
        out[name].update(values)
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
