"""The config fragment that switches the diagnosed effect on in the simulator (``--write-model``)."""

from __future__ import annotations

from pathlib import Path

import yaml

from ankle_rt.diagnosis.core import Diagnosis


def fragment(diag: Diagnosis, config_path: str | None = None) -> dict:
    """``include`` of the diagnosed config (when given), the re-fitted actuator baseline (SI, when a
    config gave the units) and ``sim.effects`` with the fitted effect (empty for none / unknown)."""
    out: dict = {}
    if config_path:
        out["include"] = [str(Path(config_path).resolve())]
    if diag.actuator_refit:
        out["actuator"] = {k: float(f"{v:.6g}") for k, v in diag.actuator_refit.items()}
    effect = {k: (float(f"{v:.6g}") if isinstance(v, float) else v) for k, v in (diag.effect or {}).items()}
    out["sim"] = {"effects": [effect] if effect else []}
    return out


def write_fragment(path: str | Path, diag: Diagnosis, config_path: str | None = None) -> None:
    header = (f"# written by `ankle-rt diagnose`: cause {diag.cause} (confidence {diag.confidence:.2f}), "
              f"validation NRMSE {diag.nrmse_baseline:.4f} -> {diag.nrmse_extended:.4f}\n"
              "# A complete config when it includes the diagnosed one: `ankle-rt run --config THIS_FILE`.\n")
    Path(path).write_text(header + yaml.safe_dump(fragment(diag, config_path), sort_keys=False))
