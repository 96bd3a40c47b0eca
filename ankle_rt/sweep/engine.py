"""Running a study: runs grouped into batches, batches run locally (a process pool over all cores)
or as tasks on a Dask distributed cluster, each batch's rows written to its own file as it finishes.

The batch plan depends only on the study, and a batch's rows only on its runs, so the same study
gives the same table whichever executor ran it, and a study interrupted and started again runs only
the batches whose files are missing (``batches/`` in the output directory, with the study's
fingerprint in ``study.json``: a changed spec starts afresh).
"""

from __future__ import annotations

import json
import os
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable

from ankle_rt.progress import Progress
from ankle_rt.sweep.spec import Run, Study

# a batch records 24 bytes per plant and tick (ankle, reference, current; float32): long runs get
# smaller batches so that one stays under ~250 MB
MAX_PLANT_TICKS = 10_000_000


@dataclass
class BatchTask:
    """What a worker needs for one batch (picklable, no study object)."""

    index: int
    runs: list[dict[str, Any]]       # run_id, sample, scenario, seed, values
    configs: list[dict]
    duration_s: float
    criteria: dict[str, float]
    cable_pretension_n: float


def plan(study: Study) -> list[BatchTask]:
    """Runs that can share a batch (same structure and controller), in run order, cut at batch_size
    (fewer for long runs, see MAX_PLANT_TICKS)."""
    groups: dict[tuple, list[Run]] = {}
    for r in study.runs:
        groups.setdefault(r.batch_key, []).append(r)
    tasks = []
    for runs in groups.values():
        ticks = study.duration_s * runs[0].config["controller"]["rate_hz"]
        size = max(1, min(study.batch_size, int(MAX_PLANT_TICKS // ticks)))
        for i in range(0, len(runs), size):
            chunk = runs[i:i + size]
            tasks.append(BatchTask(len(tasks), [{"run_id": r.run_id, "sample": r.sample, "scenario": r.scenario,
                                                 "seed": r.seed, "values": r.values} for r in chunk],
                                   [dict(r.config) for r in chunk], study.duration_s, dict(study.criteria),
                                   study.cable_pretension_n))
    return tasks


def run_batch(task: BatchTask) -> list[dict[str, Any]]:
    """One row per run: identifiers, the sampled values, the metrics (runs on a worker)."""
    import numpy as np

    from ankle_rt.config import Config
    from ankle_rt.sweep.cycle import BatchRun
    from ankle_rt.sweep.metrics import run_metrics

    cfgs = [Config(c) for c in task.configs]
    slack = np.array([2.0 * c["transmission"]["pulley_radius"] * task.cable_pretension_n for c in cfgs])
    trace = BatchRun(cfgs, task.duration_s, slack_torque=slack).run()
    rows = []
    for j, (meta, cfg) in enumerate(zip(task.runs, cfgs)):
        row = {"run_id": meta["run_id"], "sample": meta["sample"], "scenario": meta["scenario"], "seed": meta["seed"]}
        row.update(meta["values"])
        row.update(run_metrics(trace, j, cfg, task.criteria))
        rows.append(row)
    return rows


def _batch_file(out: Path, index: int) -> Path:
    return out / "batches" / f"batch-{index:05d}.json"


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def prepare_output(study: Study, out: Path) -> None:
    """Create the output directory; keep finished batches only if they belong to this very study."""
    (out / "batches").mkdir(parents=True, exist_ok=True)
    meta_path = out / "study.json"
    meta = {"fingerprint": study.fingerprint, "spec": str(study.path), "runs": len(study.runs)}
    old = None
    if meta_path.exists():
        try:
            old = json.loads(meta_path.read_text()).get("fingerprint")
        except (OSError, ValueError):
            old = None
    if old != study.fingerprint:
        for f in (out / "batches").glob("batch-*.json"):
            f.unlink()
    _write_atomic(meta_path, json.dumps(meta))


def execute(study: Study, out: Path, *, scheduler: Any = None, workers: int | None = None,
            progress: bool | None = None, on_batch: Callable[[int], None] | None = None) -> list[dict[str, Any]]:
    """Run the study's missing batches and return every row in run order.

    ``scheduler``: a Dask scheduler address (or a ``distributed.Client``); None runs locally on
    ``workers`` processes (default: all cores; 1 runs in this process)."""
    prepare_output(study, out)
    tasks = plan(study)
    todo = [t for t in tasks if not _batch_file(out, t.index).exists()]
    done = {"runs": 0, "batches": 0}
    with Progress("sweep", sum(len(t.runs) for t in todo), enabled=progress) as bar:

        def finished(task: BatchTask, rows: list[dict[str, Any]]) -> None:
            _write_atomic(_batch_file(out, task.index), json.dumps(rows))
            done["runs"] += len(rows)
            done["batches"] += 1
            bar.update(done["runs"], f"{done['batches']}/{len(todo)} batches")
            if on_batch is not None:
                on_batch(task.index)

        run_tasks(todo, finished, run_batch, scheduler=scheduler, workers=workers)
    rows: list[dict[str, Any]] = []
    for t in tasks:
        rows.extend(json.loads(_batch_file(out, t.index).read_text()))
    rows.sort(key=lambda r: r["run_id"])
    return rows


def run_tasks(tasks: list, finished: Callable[[Any, Any], None], fn: Callable, *, scheduler: Any = None,
              workers: int | None = None) -> None:
    """``fn`` over ``tasks`` on the Dask ``scheduler`` when given, else on a local process pool of
    ``workers`` (default: all cores), calling ``finished(task, result)`` as each one ends."""
    if not tasks:
        return
    if scheduler is not None:
        run_dask(tasks, scheduler, finished, fn=fn)
    else:
        run_local(tasks, workers or os.cpu_count() or 1, finished, fn=fn)


def run_local(tasks: list, workers: int, finished, fn: Callable = run_batch) -> None:
    """``fn`` over ``tasks`` on a process pool of ``workers`` (1: in this process), calling
    ``finished(task, result)`` as each one ends."""
    if workers <= 1 or len(tasks) == 1:
        for t in tasks:
            finished(t, fn(t))
        return
    with ProcessPoolExecutor(max_workers=min(workers, len(tasks))) as pool:
        futures: dict[Future, Any] = {pool.submit(fn, t): t for t in tasks}
        for fut in as_completed(futures):
            finished(futures[fut], fut.result())


def run_dask(tasks: list, scheduler: Any, finished, fn: Callable = run_batch) -> None:
    """The same on a Dask cluster (scheduler address or ``distributed.Client``), tasks as futures."""
    try:
        from distributed import Client, as_completed as dask_completed
    except ImportError:
        raise RuntimeError("--scheduler needs dask distributed (pip install 'ankle-rt[sweep]')") from None
    client = scheduler if isinstance(scheduler, Client) else Client(scheduler)
    try:
        futures = client.map(fn, tasks, pure=False)
        by_key = {f.key: t for f, t in zip(futures, tasks)}
        for fut in dask_completed(futures):
            finished(by_key[fut.key], fut.result())
    finally:
        if client is not scheduler:
            client.close()


def write_table(rows: Iterable[dict[str, Any]], out: Path) -> Path:
    """``results.parquet`` (pyarrow installed) or ``results.csv``: one row per run."""
    rows = list(rows)
    columns: list[str] = []
    for r in rows:
        for k in r:
            if k not in columns:
                columns.append(k)
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        import csv
        path = out / "results.csv"
        with path.open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=columns)
            w.writeheader()
            for r in rows:
                w.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in r.items()})
        return path
    table = pa.table({c: [r.get(c) for r in rows] for c in columns})
    path = out / "results.parquet"
    pq.write_table(table, path)
    return path


def read_table(path: Path) -> list[dict[str, Any]]:
    """The rows of a table written by :func:`write_table` (for tests and tools)."""
    if path.suffix == ".parquet":
        import pyarrow.parquet as pq
        return pq.read_table(path).to_pylist()
    import csv
    with path.open() as f:
        return list(csv.DictReader(f))
