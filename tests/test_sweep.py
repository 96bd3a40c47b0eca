"""ankle-rt sweep: spec checking, the same table locally and on Dask, resuming, metrics that find a fault."""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest
import yaml

from ankle_rt.cli import main
from ankle_rt.sweep.engine import execute, read_table, write_table
from ankle_rt.sweep.report import summarize
from ankle_rt.sweep.spec import SpecError, load_study

ROOT = Path(__file__).resolve().parent.parent
BASE = ROOT / "config" / "sim.yaml"


def _spec(tmp_path: Path, **changes) -> Path:
    spec = {
        "base": str(BASE),
        "duration_s": 1.5,
        "sampling": {"method": "lhs", "runs": 6, "seed": 7},
        "batch_size": 4,
        # a stiff kp inside controller.gain_limits: with little damping (kd 0.3 keeps the linear margin,
        # kd 0 would be refused) the 10 deg step saturates into a +-15 A relay oscillation
        "overrides": {"sim": {"effects": [{"type": "delay", "delay": 0.0}]}, "controller": {"step_gains": {"kp": 200.0}}},
        "parameters": {
            "transmission.cable_stiffness": {"dist": "uniform", "low": 0.7, "high": 1.3, "relative": True},
            "sim.effects.0.delay": {"dist": "uniform", "low": 0.0, "high": 0.004},
            "controller.step_gains.kd": {"dist": "choice", "values": [5.0, 0.3]},
        },
        "scenarios": ["step", "disturbance"],
    }
    spec.update(changes)
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def _same(a: list[dict], b: list[dict]) -> None:
    assert len(a) == len(b)
    for ra, rb in zip(a, b):
        assert ra.keys() == rb.keys()
        for k in ra:
            va, vb = ra[k], rb[k]
            if isinstance(va, float) and math.isnan(va):
                assert isinstance(vb, float) and math.isnan(vb), k
            else:
                assert va == vb, (k, va, vb)


@pytest.mark.parametrize("changes, key", [
    ({"parameters": {"transmission.cable_stifness": {"dist": "uniform", "low": 1.0, "high": 2.0}}},
     "transmission.cable_stifness"),
    ({"parameters": {"actuator.coulomb": {"dist": "uniform", "low": 0.3, "high": 0.2}}}, "parameters.actuator.coulomb"),
    ({"parameters": {"actuator.coulomb": {"dist": "log-uniform", "low": 0.0, "high": 0.2}}}, "parameters.actuator.coulomb"),
    ({"parameters": {"actuator.coulomb": {"dist": "normal", "mean": 0.3, "std": -0.1}}}, "parameters.actuator.coulomb"),
    ({"parameters": {"actuator.coulomb": {"dist": "gamma", "low": 0.1, "high": 0.2}}}, "parameters.actuator.coulomb"),
    ({"parameters": {"actuator.inertia": {"dist": "uniform", "low": -0.05, "high": -0.01}}}, "parameters.actuator.inertia"),
    ({"parameters": {"sim.effects.0.delay": {"dist": "uniform", "low": -0.01, "high": -0.001}}},
     "parameters.sim.effects.0.delay"),
    ({"parameters": {"sim.effects.3.delay": {"dist": "uniform", "low": 0.0, "high": 0.001}}},
     "parameters.sim.effects.3.delay"),
    ({"sampling": {"method": "halton", "runs": 4}}, "sampling.method"),
    ({"scenarios": ["stairs"]}, "scenarios.0"),
    ({"colour": "red"}, "colour"),
    ({"overrides": {"controller": {"type": "impedance"}},      # beyond what the joint-torque loop renders stably
      "parameters": {"controller.impedance.stiffness_dp": {"dist": "uniform", "low": 5000.0, "high": 6000.0}}},
     "parameters.controller.impedance.stiffness_dp"),
    ({"parameters": {"controller.step_gains.kp": {"dist": "uniform", "low": 600.0, "high": 700.0}}},  # > gain_limits.kp
     "parameters.controller.step_gains.kp"),
    ({"overrides": {"controller": {"type": "impedance"}},      # the loop's limits move with the sampled plant
      "parameters": {"transmission.cable_stiffness": {"dist": "uniform", "low": 1.35, "high": 1.36,  # 5.5 dB
                                                      "relative": True}}},
     "the config rejects it: controller.torque_loop.kp_dp"),
    ({"base": 5}, "base"),
    ({"criteria": ["max_overshoot_pct"]}, "criteria"),
    ({"metrics": ["cable_pretension_n"]}, "metrics"),
    ({"dask": {"scheduler": [1, 2]}}, "dask"),
    ({"sampling": {"method": "lhs", "runs": 10 ** 12}}, "sampling.runs"),     # not a MemoryError
    ({"sampling": {"method": "grid"},
      "parameters": {"actuator.coulomb": {"dist": "uniform", "low": 0.1, "high": 0.2, "steps": 10 ** 8}}},
     "sampling.method"),
])
def test_a_bad_spec_is_refused_naming_the_key_before_any_run(tmp_path, capsys, changes, key):
    spec = _spec(tmp_path, **changes)
    with pytest.raises(SpecError) as exc:
        load_study(spec)
    assert key in str(exc.value)
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out)]) == 2
    assert key in capsys.readouterr().err
    assert not out.exists()


def test_sampling_is_reproducible_and_recorded(tmp_path):
    a, b = load_study(_spec(tmp_path)), load_study(_spec(tmp_path))
    assert [r.values for r in a.runs] == [r.values for r in b.runs]
    assert len(a.runs) == 12 and [r.scenario for r in a.runs[:2]] == ["step", "disturbance"]
    factors = [r.values["transmission.cable_stiffness (factor)"] for r in a.runs[::2]]
    assert all(0.7 <= f <= 1.3 for f in factors) and len(set(factors)) == 6
    # LHS: one sample in each sixth of the range
    assert sorted(int((f - 0.7) / 0.1) for f in factors) == list(range(6))
    k0 = 218800.0
    for r in a.runs:
        assert r.config["transmission"]["cable_stiffness"] == pytest.approx(k0 * r.values["transmission.cable_stiffness (factor)"])
        assert r.config["sim"]["effects"][0]["delay"] == r.values["sim.effects.0.delay"]
        assert r.config["sim"]["seed"] == r.seed
    other = load_study(_spec(tmp_path, sampling={"method": "lhs", "runs": 6, "seed": 8}))
    assert [r.values for r in other.runs] != [r.values for r in a.runs]


@pytest.mark.slow
def test_local_and_dask_give_the_same_table_and_a_study_resumes(tmp_path):
    distributed = pytest.importorskip("distributed", reason="dask distributed is not installed (the sweep extra)")
    study = load_study(_spec(tmp_path))
    local = execute(study, tmp_path / "local", workers=1, progress=False)
    assert len(local) == 12 and [r["run_id"] for r in local] == list(range(12))

    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        on_dask = execute(study, tmp_path / "dask", scheduler=cluster.scheduler_address, progress=False)
    _same(local, on_dask)

    class Interrupted(Exception):
        pass

    def stop_after_first(_index):
        raise Interrupted

    with pytest.raises(Interrupted):
        execute(study, tmp_path / "resumed", workers=1, progress=False, on_batch=stop_after_first)
    ran = []
    resumed = execute(study, tmp_path / "resumed", workers=1, progress=False, on_batch=ran.append)
    assert len(ran) == 2          # 3 batches of at most 4 runs; the first was already written
    _same(local, resumed)
    table = write_table(resumed, tmp_path)
    if table.suffix == ".parquet":          # a CSV (no pyarrow) reads back as text
        _same(local, read_table(table))


def test_metrics_find_the_unstable_gain_and_summary_ranks_it_first(tmp_path):
    study = load_study(_spec(tmp_path))
    rows = execute(study, tmp_path / "out", workers=1, progress=False)
    for r in rows:
        kd = r["controller.step_gains.kd"]
        if kd == 0.3 and r["scenario"] == "step":        # the step kicks the barely damped stiff loop into a fault
            assert r["faulted"] and r["fault"] in ("oscillation", "motor_jump") and not r["passed"]
            assert not r["stable"]
        elif kd == 0.3:                                 # a 1 N m push does not
            assert not r["faulted"]
        else:
            assert r["passed"] and r["stable"] and not r["faulted"]
            assert r["current_rms_ratio"] < 1.0 and r["current_peak_a"] <= 15.0
            if r["scenario"] == "step":      # 10 deg DP step: tracked, settled
                assert 0.1 < r["tracking_rms_dp_deg"] < 5.0 and r["settling_dp_s"] < 1.0
            else:                            # a hold has no step
                assert math.isnan(r["overshoot_dp_pct"])
    s = summarize(study, rows)
    assert s["influence"][0]["parameter"] == "controller.step_gains.kd"
    assert s["worst"][0]["parameters"]["controller.step_gains.kd"] == 0.3
    assert 0.0 < s["pass_rate"] < 1.0


def test_rerun_replays_one_case_as_a_logged_run(tmp_path, capsys):
    spec = _spec(tmp_path, duration_s=0.6)
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--rerun", "3"]) == 0
    assert (tmp_path / "out" / "rerun" / "run-3.arlog").stat().st_size > 0
    text = (tmp_path / "out" / "rerun" / "run-3.yaml").read_text()
    assert "run 3 of" in text and "scenario disturbance" in text


def test_runs_of_different_structure_go_to_different_batches(tmp_path):
    from ankle_rt.sweep.engine import plan

    study = load_study(_spec(tmp_path, parameters={
        "sim.substeps": {"dist": "uniform", "low": 1.6, "high": 3.4},          # integer key: rounded
        "controller.type": {"dist": "choice", "values": ["pd", "impedance"]}}))
    seen = {(r.config["sim"]["substeps"], r.config["controller"]["type"]) for r in study.runs}
    assert {s for s, _ in seen} <= {2, 3} and len(seen) > 2
    tasks = plan(study)
    assert sorted(r["run_id"] for t in tasks for r in t.runs) == list(range(len(study.runs)))
    for t in tasks:
        assert len(t.runs) <= study.batch_size
        assert len({(c["sim"]["substeps"], c["controller"]["type"]) for c in t.configs}) == 1


def test_impedance_runs_open_and_closed_loop_go_to_different_batches_and_run(tmp_path):
    """The batched cycle runs one impedance law per batch, the joint-torque loop closed or not; closed,
    it renders the commanded stiffness under the disturbance (friction holds the ankle open loop)."""
    from ankle_rt.sweep.engine import plan

    study = load_study(_spec(tmp_path, duration_s=2.5, scenarios=["disturbance"], batch_size=8,
                             sampling={"method": "random", "runs": 4, "seed": 2},
                             overrides={"controller": {"type": "impedance"}},
                             parameters={"controller.impedance.torque_feedback": {"dist": "choice",
                                                                                  "values": ["on", "off"]}}))
    feedback = [r.config["controller"]["impedance"]["torque_feedback"] for r in study.runs]
    assert set(feedback) == {"on", "off"}
    tasks = plan(study)
    assert sorted(len({c["controller"]["impedance"]["torque_feedback"] for c in t.configs}) for t in tasks) == [1, 1]
    rows = execute(study, tmp_path / "out", workers=1, progress=False)
    assert [r["run_id"] for r in rows] == list(range(4))
    for r, closed in zip(rows, feedback):
        assert r["fault"] == "none" and r["stable"], r
        for axis in ("dp", "ie"):
            error = abs(r[f"impedance_error_{axis}_pct"])
            assert (error < 40.0) if closed == "on" else (error > 100.0), (axis, r)


def test_the_table_falls_back_to_csv_without_pyarrow(tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pyarrow", None)       # import pyarrow raises ImportError
    rows = [{"run_id": 0, "scenario": "step", "x": 0.1 + 0.2, "passed": True},
            {"run_id": 1, "scenario": "gait", "x": float("nan"), "passed": False}]
    path = write_table(rows, tmp_path)
    assert path.name == "results.csv"
    back = read_table(path)
    assert [r["scenario"] for r in back] == ["step", "gait"]
    assert float(back[0]["x"]) == 0.1 + 0.2 and math.isnan(float(back[1]["x"]))


@pytest.mark.parametrize("method", ["sobol", "random", "grid"])
def test_every_sampling_method_maps_each_distribution_into_its_support(tmp_path, method):
    parameters = {
        "actuator.coulomb": {"dist": "normal", "mean": 0.28, "std": 0.02},
        # within what the joint-torque loop carries: more gauge noise than ~0.025 N m rings it past the oscillation
        # detector's share (ankle_rt.gain_margin.noise_refusal) and the config refuses the impedance runs
        "sensors.strain_gauge_noise_rms": {"dist": "log-uniform", "low": 0.006, "high": 0.024, "steps": 3},
        "actuator.damping": {"dist": "uniform", "low": 0.08, "high": 0.14, "steps": 2},
        "controller.type": {"dist": "choice", "values": ["pd", "impedance"]},
    }
    if method == "grid":
        parameters.pop("actuator.coulomb")         # a normal distribution has no grid
    # the joint-torque loop's least impedance damping grows as the sampled actuator damping falls
    spec = _spec(tmp_path, parameters=parameters, scenarios=["step"],
                 sampling={"method": method, "runs": 16, "seed": 3},
                 overrides={"controller": {"impedance": {"damping_dp": 1.0}}})
    study = load_study(spec)
    again = load_study(spec)
    assert [r.values for r in study.runs] == [r.values for r in again.runs]
    assert len(study.runs) == (12 if method == "grid" else 16)
    noise = [r.config["sensors"]["strain_gauge_noise_rms"] for r in study.runs]
    assert all(0.006 * (1 - 1e-12) <= v <= 0.024 * (1 + 1e-12) for v in noise)
    assert {r.config["controller"]["type"] for r in study.runs} == {"pd", "impedance"}
    if method == "grid":
        assert sorted(set(noise)) == pytest.approx([0.006, 0.012, 0.024])
    else:
        kc = [r.config["actuator"]["coulomb"] for r in study.runs]
        assert 0.2 < min(kc) and max(kc) < 0.36 and len(set(kc)) == 16


def test_grid_refuses_a_normal_distribution(tmp_path):
    spec = _spec(tmp_path, parameters={"actuator.coulomb": {"dist": "normal", "mean": 0.28, "std": 0.02}},
                 sampling={"method": "grid"})
    with pytest.raises(SpecError, match="parameters.actuator.coulomb"):
        load_study(spec)


def test_a_changed_study_does_not_resume_from_the_old_batches(tmp_path):
    out = tmp_path / "out"
    execute(load_study(_spec(tmp_path, duration_s=0.3)), out, workers=1, progress=False)
    ran = []
    changed = load_study(_spec(tmp_path, duration_s=0.3, sampling={"method": "lhs", "runs": 6, "seed": 8}))
    rows = execute(changed, out, workers=1, progress=False, on_batch=ran.append)
    assert len(ran) == 3
    assert [r["transmission.cable_stiffness (factor)"] for r in rows] == \
        [r.values["transmission.cable_stiffness (factor)"] for r in changed.runs]


@pytest.mark.parametrize("content, reason", [(b"base: \xff\xfe\n", "not UTF-8"), (b"\0\1\2", "binary"),
                                             (None, "a FIFO")])
def test_a_spec_that_is_not_a_text_file_is_refused_by_name(tmp_path, capsys, content, reason):
    spec = tmp_path / "spec.yaml"
    if content is None:
        os.mkfifo(spec)                  # must not block waiting for a writer
    else:
        spec.write_bytes(content)
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out")]) == 2
    assert reason in capsys.readouterr().err


def test_a_spec_with_a_yaml_alias_or_a_duplicate_key_is_refused(tmp_path):
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("a: &a [x, x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
                    "duration_s: 1.0\n")
    with pytest.raises(SpecError, match="alias"):
        load_study(bomb)
    twice = tmp_path / "twice.yaml"
    twice.write_text("duration_s: 1.0\nduration_s: 2.0\n")
    with pytest.raises(SpecError, match="duplicate key 'duration_s'"):
        load_study(twice)
