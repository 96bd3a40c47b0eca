"""The config fragment that switches the diagnosed effects on in the simulator (``--write-model``)."""

from __future__ import annotations

import os
from pathlib import Path

import yaml

from ankle_rt.diagnosis.core import Diagnosis


def _rounded(entry: dict) -> dict:
    return {k: (float(f"{v:.6g}") if isinstance(v, float) else v) for k, v in entry.items()}


def fragment(diag: Diagnosis, config_path: str | None = None, out_path: str | Path | None = None) -> dict:
    """``include`` of the diagnosed config (when given; relative to ``out_path``'s directory, so the
    pair can be moved together), the re-fitted actuator baseline (SI, when a config gave the units) and
    ``sim.effects`` with every named effect (empty for none / unknown)."""
    out: dict = {}
    if config_path:
        base = Path(out_path).resolve().parent if out_path is not None else Path.cwd()
        out["include"] = [Path(os.path.relpath(Path(config_path).resolve(), base)).as_posix()]
    if diag.actuator_refit:
        out["actuator"] = {k: float(f"{v:.6g}") for k, v in diag.actuator_refit.items()}
    out["sim"] = {"effects": [_rounded(e) for e in diag.sim_effects]}
    return out


def write_fragment(path: str | Path, diag: Diagnosis, config_path: str | None = None) -> None:
    header = (f"# written by `ankle-rt diagnose`: causes {', '.join(diag.causes)} (confidence "
              f"{diag.confidence:.2f}), validation NRMSE {diag.nrmse_baseline:.4f} -> {diag.nrmse_extended:.4f}\n"
              "# A complete config when it includes the diagnosed one: `ankle-rt run --config THIS_FILE`.\n")
    Path(path).write_text(header + yaml.safe_dump(fragment(diag, config_path, path), sort_keys=False))
