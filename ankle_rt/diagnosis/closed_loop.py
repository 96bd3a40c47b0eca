"""The second kind of gain: free-run closed-loop simulation error of the positions.

Where the controller and the references are known (a daemon run: its config names them, and the log
holds ``ref_dp``/``ref_ie``), the run is simulated again through the daemon's own lockstep loop
(``ankle_rt.daemon.run_lockstep``, which opens the backend by name: the core never imports the
simulator) once with the re-fitted baseline and once with the extended model, and the simulated motor
(and joint) angles are compared with the measured ones (NRMSE = RMS error / measured range, averaged over
the angles: the identification tools' ``compare``, as ``ankle-rt validate`` reports it).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ankle_rt.diagnosis.core import Diagnosis
from ankle_rt.diagnosis.resample import GRID_GAP_S
from ankle_rt.interchange import Recording

POSITION_COLUMNS = ("motor_pos_1", "motor_pos_2", "ankle_dp", "ankle_ie")


@dataclass
class ClosedLoopGain:
    nrmse_baseline: float
    nrmse_extended: float
    columns: tuple[str, ...]
    duration_s: float
    traces: dict[str, Any]   # "t" -> s; "measured" / "baseline" / "extended" -> column -> samples at those t

    @property
    def gain(self) -> float:
        return self.nrmse_baseline / self.nrmse_extended if self.nrmse_extended > 0 else 1.0

    def to_json(self) -> dict:
        return {"nrmse_baseline": self.nrmse_baseline, "nrmse_extended": self.nrmse_extended,
                "gain": self.gain, "columns": list(self.columns), "duration_s": self.duration_s}


def applicable(rec: Recording) -> bool:
    """A daemon run with references (the controller then comes from the run's config), without a pause
    longer than the uniform grid bridges: a re-run spans the record's whole time, a day's pause included."""
    return "ref_dp" in rec and "ref_ie" in rec and float(np.max(np.diff(rec["t"]))) <= GRID_GAP_S


def closed_loop_gain(rec: Recording, config_path: str | Path, diag: Diagnosis) -> ClosedLoopGain:
    """Re-run the recorded experiment on the simulator, baseline and extended (see module docstring)."""
    from ankle_rt.config import load_config
    from ankle_rt.daemon import run_lockstep
    from ankle_rt.identification.validation import compare

    refit = {"actuator": dict(diag.actuator_refit)} if diag.actuator_refit else {}
    # the simulation runs from t = 0: the record's own time from its first sample (a file's stamps may
    # start anywhere, negative or a clock's uptime), and the simulation taken at the record's instants
    # (its rate need not be the config's: compare() pairs samples by index)
    t = np.asarray(rec["t"], dtype=float) - float(rec["t"][0])
    duration = float(t[-1] + rec.dt)
    cols = tuple(c for c in POSITION_COLUMNS if c in rec)
    angles = {c: rec[c] for c in cols}
    measured = Recording({"t": t, **angles}, rec.source)
    traces: dict[str, Any] = {"t": t, "measured": angles}
    out = {}
    for name, effects in (("baseline", []), ("extended", diag.sim_effects)):
        cfg = load_config(config_path, overrides={**refit, "sim": {"effects": effects}})
        run = run_lockstep(cfg, duration)
        sim = Recording(run.interchange(), f"{name} simulation")
        at = {c: np.interp(t, sim["t"], sim[c]) for c in cols}
        errors, _ = compare(measured, Recording({"t": t, **at}, f"{name} simulation"), cols, relative=False)
        out[name] = float(np.mean([e.nrmse for e in errors]))
        traces[name] = at
    return ClosedLoopGain(out["baseline"], out["extended"], cols, duration, traces)
