"""The sweep engine over a folder of recordings: ``ankle-rt diagnose --batch DIR`` (run logs) and
``ankle-rt identify EXPERIMENT --batch DIR`` (identification sessions).

Every run log (``*.arlog``) and interchange CSV under DIR (recursively) is diagnosed on its own
(:func:`ankle_rt.diagnosis.diagnose`, the public entry point), on all cores or a Dask cluster, one
row per log: file, device (the sub-folder it is in, "." at the top), start time (the log header's
``started_utc``; a CSV's modification time), cause and confidence, the re-fitted baseline per motor
and cable axis (friction, inertia, stiffness) and the effect's parameters. A log that cannot be read
or diagnosed gets a row with its error; the others go on. The trends of the re-fitted parameters
over time, one line per device, are plotted (friction rising with cable wear shows as a slope).

``identify --batch``: every folder under DIR holding the experiment's recordings (``stiction.csv``,
``viscous.csv``, ``inertia.csv``: what ``identify --out`` writes) is one session, identified by
:func:`ankle_rt.identification.actuator.identify`; its row has the estimated ``actuator.*`` values,
the device (the session folder's parent) and the time (the newest recording's modification time).
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any, Callable, Sequence

SUFFIXES = (".arlog", ".csv")


def find_logs(directory: Path) -> list[Path]:
    return sorted(p for p in directory.rglob("*") if p.is_file() and p.suffix in SUFFIXES)


def _started(rec: Any, path: Path) -> str:
    meta = (getattr(rec, "extra", None) or {}).get("log_meta") or {}
    started = meta.get("started_utc")
    return started if isinstance(started, str) else time.strftime("%Y-%m-%dT%H:%M:%SZ",
                                                                     time.gmtime(path.stat().st_mtime))


def diagnose_log(task: tuple[str, str, str | None, str]) -> dict[str, Any]:
    """One row for the log ``(path, device, config path, plant)`` (runs on a worker)."""
    from ankle_rt.config import ConfigError, load_config
    from ankle_rt.diagnosis import DiagnosisError, diagnose
    from ankle_rt.identification.data import load_recording
    from ankle_rt.interchange import InterchangeError

    path, device, config, plant = task
    row: dict[str, Any] = {"file": path, "device": device}
    try:
        rec = load_recording(path, gaps_masked=True)      # the diagnosis' screening masks around time gaps
        row["started_utc"] = _started(rec, Path(path))
        diag = diagnose(rec, None, plant=plant, cfg=load_config(config) if config else None).to_json()
    except (InterchangeError, DiagnosisError, ConfigError, OSError, ValueError) as exc:
        row.update({"started_utc": row.get("started_utc", ""), "cause": "error", "error": str(exc)})
        return row
    row.update({"cause": diag["cause"], "causes": "+".join(diag["causes"]), "confidence": diag["confidence"], "error": "",
                "data_warnings": "; ".join(diag["data_warnings"]),
                "nrmse_baseline": diag["nrmse_baseline"], "nrmse_extended": diag["nrmse_extended"],
                "gain": diag["gain"]})
    for channel, params in (diag["baseline"] or {}).items():
        for name, p in params.items():
            for i, v in enumerate(p["value"], 1):
                row[f"{channel}.{name}.{i}"] = float(v)
    for effect in diag["effects"]:
        for name, p in effect["parameters"].items():
            row[f"effect.{effect['type']}.{name}"] = float(p["value"])
    return row


def diagnose_folder(directory: Path, config: str | None, plant: str, *, scheduler: Any = None,
                    workers: int | None = None) -> list[dict[str, Any]]:
    """One row per log under ``directory``, sorted by device and start time."""
    logs = find_logs(directory)
    tasks = [(str(p), str(p.parent.relative_to(directory)), config, plant) for p in logs]
    return _rows("diagnose", tasks, diagnose_log, scheduler, workers)


def identify_session(task: tuple[str, str, str, int, str | None]) -> dict[str, Any]:
    """One row for the session folder ``(folder, device, experiment, motor, config path)``."""
    import yaml

    from ankle_rt.config import ConfigError, load_config
    from ankle_rt.identification.actuator import EXPERIMENTS, MIN_ROWS, identify
    from ankle_rt.identification.data import load_recording
    from ankle_rt.identification.report import parameter_yaml
    from ankle_rt.identification.signals import IdentificationError
    from ankle_rt.interchange import InterchangeError

    folder, device, experiment, motor, config = task
    names = EXPERIMENTS if experiment == "all" else (experiment,)
    files = [Path(folder) / f"{n}.csv" for n in names]
    row: dict[str, Any] = {"file": folder, "device": device,
                           "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ",
                                                        time.gmtime(max(f.stat().st_mtime for f in files)))}
    try:
        cfg = load_config(config) if config else None
        recordings = {n: load_recording(f, MIN_ROWS[n]) for n, f in zip(names, files)}
        result = identify(recordings, motor, cfg["actuator"]["torque_constant"] if cfg else None,
                          prior=cfg["actuator"] if cfg else None)
        params = yaml.safe_load(parameter_yaml(result, "")) or {}
    except (InterchangeError, IdentificationError, ConfigError, OSError, ValueError) as exc:
        row.update({"cause": "error", "error": str(exc)})
        return row
    row.update({"cause": "identified", "error": ""})
    for section, values in params.items():
        for name, value in (values or {}).items():
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                row[f"{section}.{name}"] = float(value)
    return row


def identify_folder(directory: Path, experiment: str, motor: int, config: str | None, *,
                    scheduler: Any = None, workers: int | None = None) -> list[dict[str, Any]]:
    """One row per session folder under ``directory``, sorted by device and time."""
    from ankle_rt.identification.actuator import EXPERIMENTS
    names = EXPERIMENTS if experiment == "all" else (experiment,)
    folders = sorted({p.parent for p in directory.rglob(f"{names[0]}.csv")
                      if all((p.parent / f"{n}.csv").is_file() for n in names)})
    tasks = [(str(f), str(f.parent.relative_to(directory)) if f != directory else ".", experiment, motor, config)
             for f in folders]
    return _rows("identify", tasks, identify_session, scheduler, workers)


def _rows(label: str, tasks: list, fn: Callable[[Any], dict[str, Any]], scheduler: Any,
          workers: int | None) -> list[dict[str, Any]]:
    """``fn`` over ``tasks`` (locally or on Dask, with a progress bar), one row each, sorted by
    device and time."""
    from ankle_rt.progress import Progress
    from ankle_rt.sweep.engine import run_tasks

    rows: list[dict[str, Any]] = []
    with Progress(label, len(tasks)) as bar:

        def finished(_task: Any, row: dict[str, Any]) -> None:
            rows.append(row)
            bar.update(len(rows))

        run_tasks(tasks, finished, fn, scheduler=scheduler, workers=workers)
    rows.sort(key=lambda r: (r["device"], r["started_utc"], r["file"]))
    return rows


def trend_columns(rows: Sequence[dict[str, Any]]) -> list[str]:
    """The re-fitted parameters present in the rows (baseline per motor / axis, effect parameters)."""
    cols: list[str] = []
    for r in rows:
        for k in r:
            if (k.startswith(("motor.", "cable.", "actuator.", "effect.")) and k not in cols
                    and isinstance(r[k], float)):
                cols.append(k)
    return cols


def plot_trends(rows: Sequence[dict[str, Any]], path: Path) -> Path | None:
    """Each re-fitted parameter against the log's start time, one line per device."""
    from datetime import datetime

    from ankle_rt.plotting import pyplot

    plt = pyplot()
    cols = trend_columns(rows)
    if plt is None or not cols:
        return None
    fig, axes = plt.subplots(len(cols), 1, figsize=(9, 2.2 * len(cols)), sharex=True, squeeze=False)
    devices = sorted({r["device"] for r in rows})
    for ax, col in zip(axes[:, 0], cols):
        for dev in devices:
            pts = [(datetime.strptime(r["started_utc"], "%Y-%m-%dT%H:%M:%SZ"), r[col]) for r in rows
                   if r["device"] == dev and isinstance(r.get(col), float) and math.isfinite(r[col])]
            if pts:
                ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", label=dev)
        ax.set_ylabel(col, fontsize=8)
    axes[0, 0].legend(fontsize=8)
    axes[0, 0].set_title("re-fitted parameters over time")
    fig.autofmt_xdate()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def identify_batch_command(args: Any) -> int:
    """``ankle-rt identify EXPERIMENT --batch DIR``: a row per session, trends over time."""
    import sys

    directory = Path(args.batch)
    if not directory.is_dir():
        print(f"ankle-rt identify: --batch {directory}: not a directory", file=sys.stderr)
        return 2
    if args.source:
        print("ankle-rt identify: give either --from or --batch, not both", file=sys.stderr)
        return 2
    rows = identify_folder(directory, args.experiment, args.motor, args.config, scheduler=args.scheduler)
    if not rows:
        print(f"ankle-rt identify: no session folders with the {args.experiment} recordings under {directory}",
              file=sys.stderr)
        return 2
    return _write_and_print(rows, Path(args.out), as_json=False)


def batch_command(args: Any) -> int:
    """``ankle-rt diagnose --batch DIR``: the table, the trends plot and one line per log."""
    import sys

    directory = Path(args.batch)
    if not directory.is_dir():
        print(f"ankle-rt diagnose: --batch {directory}: not a directory", file=sys.stderr)
        return 2
    if args.data is not None:
        print("ankle-rt diagnose: give either a data file or --batch DIR, not both", file=sys.stderr)
        return 2
    rows = diagnose_folder(directory, args.config, args.plant, scheduler=args.scheduler)
    if not rows:
        print(f"ankle-rt diagnose: no run logs (*.arlog) or CSV files under {directory}", file=sys.stderr)
        return 2
    return _write_and_print(rows, Path(args.report) if args.report else Path("diagnose-batch"), args.json)


def _write_and_print(rows: list[dict[str, Any]], out: Path, as_json: bool) -> int:
    import json

    from ankle_rt.sweep.engine import write_table

    out.mkdir(parents=True, exist_ok=True)
    table = write_table(rows, out)
    plot = plot_trends([r for r in rows if r["cause"] != "error"], out / "trends.png")
    if as_json:
        print(json.dumps({"rows": rows, "table": str(table), "trends": str(plot) if plot else None},
                         default=float))
        return 0
    cols = trend_columns(rows)
    for r in rows:
        if r["cause"] == "error":
            print(f"{r['file']}: ERROR {r['error']}")
            continue
        params = ", ".join(f"{c} {r[c]:.4g}" for c in cols if isinstance(r.get(c), float))
        confidence = f" ({r['confidence']:.2f})" if "confidence" in r else ""
        print(f"{r['device']}  {r['started_utc']}  {Path(r['file']).name}: {r.get('causes', r['cause'])}{confidence}; {params}")
        if r.get("data_warnings"):
            print(f"    data warnings (the figures above may not mean much): {r['data_warnings']}")
    print(f"{len(rows)} recordings; table {table}" + (f", trends {plot}" if plot else ""))
    return 0
