"""A study: the base config, the parameters to vary and how, the scenarios, and every run's config.

A spec is YAML (docs/sweeps.md)::

    base: ../config/sim.yaml          # relative to the spec file
    duration_s: 5.0
    sampling: {method: lhs, runs: 1000, seed: 1}    # lhs | sobol | random | grid
    parameters:
      transmission.cable_stiffness: {dist: uniform, low: 0.7, high: 1.3, relative: true}
      sim.effects.0.delay: {dist: uniform, low: 0.0, high: 0.004}
    overrides: {sim: {effects: [{type: delay, delay: 0.0}]}}   # applied to the base first
    scenarios: [step, gait, disturbance]
    criteria: {max_tracking_rms_deg: 1.0}
    dask: {scheduler: tcp://host:8786}

Every run's config is built and validated before anything runs, so a bad spec (unknown key, a
distribution that cannot be sampled, a value the config rejects) fails at once, naming the key.
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ankle_rt.config import Config, ConfigError, config_from_data, merge, parse_yaml, read_with_includes

DISTRIBUTIONS = ("uniform", "normal", "log-uniform", "choice")
METHODS = ("lhs", "sobol", "random", "grid")
DEFAULT_PRETENSION_N = 20.0   # N per cable [assumed: the paper gives no value]; slack at 2 r T0 = 0.51 N m

# The built-in scenarios: config overrides on top of each sampled config.
SCENARIOS: dict[str, dict] = {
    # the paper's section 7: steps of 10 deg DP and 5 deg IE, 0.5 N m on both axes from 2 s to 3 s
    "step": {"reference": {"profile": "step", "step": {"dp": 0.17453, "ie": 0.08727, "start_s": 0.5}},
             "sim": {"disturbances": [{"start": 2.0, "stop": 3.0, "torque_dp": 0.5, "torque_ie": 0.5}]}},
    # a gait-like cycle (1.2 s strides from 0.5 s) with the foot loaded during each stance phase
    # (the first 60 % of a stride): 2 N m DP, 0.5 N m IE at the ankle
    "gait": {"reference": {"profile": "gait", "gait": {"stride_s": 1.2, "scale": 1.0, "start_s": 0.5}},
             "sim": {"disturbances": [{"start": 0.5 + 1.2 * k, "stop": 0.5 + 1.2 * k + 0.72,
                                       "torque_dp": 2.0, "torque_ie": 0.5} for k in range(25)]}},
    # hold the ankle at rest and push it: 1 N m DP and 0.5 N m IE from 1.0 s to 2.0 s
    "disturbance": {"reference": {"profile": "hold", "hold": {"dp": 0.0, "ie": 0.0}},
                    "sim": {"disturbances": [{"start": 1.0, "stop": 2.0, "torque_dp": 1.0, "torque_ie": 0.5}]}},
}


MAX_SPEC_BYTES = 1 << 20
# Every run's config is built up front: a typo like runs: 1000000000000 must fail by name, not by memory.
MAX_RUNS = 100_000            # samples x scenarios


class SpecError(ValueError):
    """A bad study spec; ``key`` names the spec entry."""

    def __init__(self, key: str, message: str):
        self.key = key
        super().__init__(f"{key}: {message}")


@dataclass
class Parameter:
    key: str                 # config key path, dots (list items by index)
    dist: str
    args: dict[str, Any]
    relative: bool = False

    @property
    def column(self) -> str:
        """The table column: the key, or for a relative parameter the factor on the base value."""
        return f"{self.key} (factor)" if self.relative else self.key

    def from_unit(self, u: np.ndarray) -> np.ndarray | list:
        """Values for uniform numbers ``u`` in [0, 1) (inverse CDF)."""
        a = self.args
        if self.dist == "uniform":
            return a["low"] + u * (a["high"] - a["low"])
        if self.dist == "log-uniform":
            return np.exp(math.log(a["low"]) + u * (math.log(a["high"]) - math.log(a["low"])))
        if self.dist == "normal":
            from statistics import NormalDist
            nd = NormalDist(a["mean"], a["std"])
            return np.array([nd.inv_cdf(min(max(v, 1e-12), 1 - 1e-12)) for v in u])
        values = a["values"]
        return [values[min(int(v * len(values)), len(values) - 1)] for v in u]

    def grid(self) -> list:
        a = self.args
        if self.dist == "choice":
            return list(a["values"])
        if "steps" not in a:
            raise SpecError(f"parameters.{self.key}", "grid sampling needs 'steps' (or a choice distribution)")
        n = a["steps"]
        if self.dist == "uniform":
            return list(np.linspace(a["low"], a["high"], n))
        if self.dist == "log-uniform":
            return list(np.exp(np.linspace(math.log(a["low"]), math.log(a["high"]), n)))
        raise SpecError(f"parameters.{self.key}", "a normal distribution has no grid; use uniform with steps")


@dataclass
class Run:
    run_id: int
    sample: int
    scenario: str
    seed: int
    values: dict[str, Any]       # sampled values by table column (relative ones as the factor)
    config: Config
    batch_key: tuple             # ankle_rt.sweep.cycle.batch_key(config), found by the preflight


@dataclass
class Study:
    path: Path
    base: Path
    duration_s: float
    method: str
    runs_requested: int
    seed: int
    parameters: list[Parameter]
    scenarios: dict[str, dict]
    overrides: dict
    criteria: dict[str, float]
    batch_size: int
    scheduler: str | None
    cable_pretension_n: float
    runs: list[Run] = field(default_factory=list)
    base_data: dict = field(default_factory=dict)   # the base config with its includes merged

    @property
    def fingerprint(self) -> str:
        """Changes when anything that decides the runs changes, the base config's included files
        too (resume refuses a different study)."""
        h = hashlib.sha256()
        h.update(json.dumps([self.duration_s, self.method, self.runs_requested, self.seed, self.cable_pretension_n,
                             self.batch_size, self.criteria,
                             [(p.key, p.dist, p.args, p.relative) for p in self.parameters],
                             self.scenarios, self.overrides], sort_keys=True, default=str).encode())
        h.update(json.dumps(self.base_data, sort_keys=True, default=str).encode())  # includes too
        return h.hexdigest()[:16]


def _number(key: str, d: dict, name: str, *, positive: bool = False) -> float:
    v = d.get(name)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise SpecError(key, f"'{name}' must be a finite number, got {v!r}")
    if positive and v <= 0:
        raise SpecError(key, f"'{name}' must be > 0, got {v!r}")
    return float(v)


def parse_parameter(key: str, entry: Any) -> Parameter:
    where = f"parameters.{key}"
    if not isinstance(entry, dict):
        raise SpecError(where, f"expected a mapping like {{dist: uniform, low: ..., high: ...}}, got {entry!r}")
    dist = entry.get("dist")
    if dist not in DISTRIBUTIONS:
        raise SpecError(where, f"unknown distribution {dist!r} (known: {', '.join(DISTRIBUTIONS)})")
    allowed = {"dist", "relative", "steps"} | {"uniform": {"low", "high"}, "log-uniform": {"low", "high"},
                                                "normal": {"mean", "std"}, "choice": {"values"}}[dist]
    extra = sorted(set(entry) - allowed)
    if extra:
        raise SpecError(where, f"unknown field {extra[0]!r} for {dist} (expected: {', '.join(sorted(allowed))})")
    args: dict[str, Any] = {}
    if dist in ("uniform", "log-uniform"):
        args["low"], args["high"] = _number(where, entry, "low"), _number(where, entry, "high")
        if not args["low"] < args["high"]:
            raise SpecError(where, f"low ({args['low']:g}) must be below high ({args['high']:g})")
        if dist == "log-uniform" and args["low"] <= 0:
            raise SpecError(where, f"a log-uniform distribution needs low > 0, got {args['low']:g}")
    elif dist == "normal":
        args["mean"] = _number(where, entry, "mean")
        args["std"] = _number(where, entry, "std", positive=True)
    else:
        values = entry.get("values")
        if not isinstance(values, list) or not values:
            raise SpecError(where, f"a choice needs a non-empty list 'values', got {values!r}")
        args["values"] = values
    if "steps" in entry:
        s = entry["steps"]
        if isinstance(s, bool) or not isinstance(s, int) or s < 2:
            raise SpecError(where, f"'steps' must be an integer >= 2, got {s!r}")
        args["steps"] = s
    relative = entry.get("relative", False)
    if not isinstance(relative, bool):
        raise SpecError(where, f"'relative' must be true or false, got {relative!r}")
    if relative and dist == "choice" and not all(isinstance(v, (int, float)) for v in args["values"]):
        raise SpecError(where, "relative choices must be numbers (factors of the base value)")
    return Parameter(key, dist, args, relative)


def _get(data: Any, key: str) -> Any:
    node = data
    for part in key.split("."):
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise KeyError(part)
            node = node[int(part)]
        elif isinstance(node, dict) and part in node:
            node = node[part]
        else:
            raise KeyError(part)
    return node


def _set(data: dict, key: str, value: Any) -> None:
    parts = key.split(".")
    node: Any = data
    for i, part in enumerate(parts[:-1]):
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise SpecError(f"parameters.{key}", f"no list item {part!r} at {'.'.join(parts[:i + 1])} "
                                                     f"(the list has {len(node)})")
            node = node[int(part)]
        else:
            node = node.setdefault(part, {})
            if not isinstance(node, (dict, list)):
                raise SpecError(f"parameters.{key}", f"{'.'.join(parts[:i + 1])} is a value, not a section")
    last = parts[-1]
    if isinstance(node, list):
        if not last.isdigit() or int(last) >= len(node):
            raise SpecError(f"parameters.{key}", f"no list item {last!r} (the list has {len(node)})")
        node[int(last)] = value
    else:
        node[last] = value


def unit_samples(method: str, n: int, d: int, seed: int) -> np.ndarray:
    """(n, d) points in [0, 1): Latin hypercube or scrambled Sobol (scipy.stats.qmc), or plain random."""
    if d == 0:
        return np.zeros((n, 0))
    if method == "random":
        return np.random.default_rng(seed).random((n, d))
    try:
        from scipy.stats import qmc
    except ImportError:
        raise SpecError("sampling.method", f"{method} needs scipy (pip install 'ankle-rt[sweep]')") from None
    if method == "lhs":
        return qmc.LatinHypercube(d=d, seed=seed).random(n)
    import warnings
    with warnings.catch_warnings():      # Sobol warns when n is not a power of two; the points stay valid
        warnings.simplefilter("ignore")
        return qmc.Sobol(d=d, scramble=True, seed=seed).random(n)


def load_study(path: str | Path, *, runs: int | None = None, scheduler: str | None = None) -> Study:
    """Read, check and expand a spec into its runs (each config validated). ``runs`` overrides
    ``sampling.runs``; ``scheduler`` the spec's ``dask.scheduler``. Raises SpecError / ConfigError."""
    path = Path(path)
    from ankle_rt.textfile import TextFileError, read_text
    try:
        raw = parse_yaml(read_text(path, MAX_SPEC_BYTES), str(path))   # no duplicate keys, no aliases
    except TextFileError as exc:
        raise SpecError("spec", f"cannot read {path}: {exc}") from None
    except ConfigError as exc:
        raise SpecError("spec", f"{path}: {exc.message}") from None
    known = {"base", "duration_s", "sampling", "parameters", "overrides", "scenarios", "criteria", "dask",
             "batch_size", "metrics"}
    unknown = sorted(set(raw) - known)
    if unknown:
        raise SpecError(unknown[0], f"unknown spec key (expected one of: {', '.join(sorted(known))})")
    from ankle_rt.paths import default_config_path
    if "base" in raw and not isinstance(raw["base"], str):
        raise SpecError("base", f"expected the path of a config file, got {raw['base']!r}")
    base = (path.parent / raw["base"]).resolve() if "base" in raw else default_config_path()
    duration = raw.get("duration_s", 5.0)
    if isinstance(duration, bool) or not isinstance(duration, (int, float)) or not 0 < duration <= 600:
        raise SpecError("duration_s", f"must be a number of seconds in (0, 600], got {duration!r}")
    sampling = raw.get("sampling", {}) or {}
    if not isinstance(sampling, dict):
        raise SpecError("sampling", "expected a mapping {method, runs, seed}")
    method = sampling.get("method", "lhs")
    if method not in METHODS:
        raise SpecError("sampling.method", f"unknown method {method!r} (known: {', '.join(METHODS)})")
    n_runs = runs if runs is not None else sampling.get("runs", 100)
    if isinstance(n_runs, bool) or not isinstance(n_runs, int) or n_runs < 1:
        raise SpecError("sampling.runs", f"must be a positive integer, got {n_runs!r}")
    seed = sampling.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SpecError("sampling.seed", f"must be a non-negative integer, got {seed!r}")
    params_raw = raw.get("parameters", {}) or {}
    if not isinstance(params_raw, dict):
        raise SpecError("parameters", "expected a mapping of config keys to distributions")
    parameters = [parse_parameter(str(k), v) for k, v in params_raw.items()]
    scen_raw = raw.get("scenarios", ["step"])
    scenarios: dict[str, dict] = {}
    for i, s in enumerate(scen_raw if isinstance(scen_raw, list) else [scen_raw]):
        if isinstance(s, str):
            if s not in SCENARIOS:
                raise SpecError(f"scenarios.{i}", f"unknown scenario {s!r} (built in: {', '.join(SCENARIOS)}; "
                                                  "or give {name: ..., overrides: {...}})")
            scenarios[s] = SCENARIOS[s]
        elif isinstance(s, dict) and isinstance(s.get("name"), str) and isinstance(s.get("overrides", {}), dict):
            scenarios[s["name"]] = s.get("overrides", {})
        else:
            raise SpecError(f"scenarios.{i}", f"expected a scenario name or {{name, overrides}}, got {s!r}")
    overrides = raw.get("overrides", {}) or {}
    if not isinstance(overrides, dict):
        raise SpecError("overrides", "expected a mapping of config sections")
    criteria = raw.get("criteria", {}) or {}
    if not isinstance(criteria, dict):
        raise SpecError("criteria", f"expected a mapping of criteria to limits, got {criteria!r}")
    from ankle_rt.sweep.metrics import CRITERIA
    for k, v in criteria.items():
        if k not in CRITERIA:
            raise SpecError(f"criteria.{k}", f"unknown criterion (known: {', '.join(CRITERIA)})")
        _number(f"criteria.{k}", criteria, k, positive=True)
    metrics = raw.get("metrics", {}) or {}
    if not isinstance(metrics, dict):
        raise SpecError("metrics", f"expected a mapping like {{cable_pretension_n: 20}}, got {metrics!r}")
    if set(metrics) - {"cable_pretension_n"}:
        raise SpecError(f"metrics.{sorted(set(metrics) - {'cable_pretension_n'})[0]}",
                        "unknown metrics option (known: cable_pretension_n)")
    pretension = _number("metrics.cable_pretension_n", {"v": metrics.get("cable_pretension_n", DEFAULT_PRETENSION_N)},
                         "v", positive=True)
    batch_size = raw.get("batch_size", 128)
    if isinstance(batch_size, bool) or not isinstance(batch_size, int) or batch_size < 1:
        raise SpecError("batch_size", f"must be a positive integer, got {batch_size!r}")
    dask = raw.get("dask", {}) or {}
    if not isinstance(dask, dict) or set(dask) - {"scheduler"} or not isinstance(dask.get("scheduler", ""), str):
        raise SpecError("dask", "expected {scheduler: ADDRESS}")
    study = Study(path=path, base=base, duration_s=float(duration), method=method, runs_requested=n_runs, seed=seed,
                  parameters=parameters, scenarios=scenarios, overrides=overrides, criteria=criteria,
                  batch_size=batch_size, scheduler=scheduler or dask.get("scheduler"), cable_pretension_n=pretension)
    n_samples = math.prod(len(p.args["values"]) if p.dist == "choice" else p.args.get("steps", 1)
                          for p in parameters) if method == "grid" else n_runs
    if n_samples * len(scenarios) > MAX_RUNS:
        raise SpecError("sampling.method" if method == "grid" else "sampling.runs",
                        f"{n_samples} samples x {len(scenarios)} scenarios is more than {MAX_RUNS} runs")
    study.runs = expand(study)
    return study


def sample_values(study: Study) -> list[dict[str, Any]]:
    """The sampled parameter values of each sample (the same for the same spec and seed)."""
    ps = study.parameters
    if study.method == "grid":
        grids = [p.grid() for p in ps]
        return [dict(zip((p.column for p in ps), combo)) for combo in itertools.product(*grids)]
    u = unit_samples(study.method, study.runs_requested, len(ps), study.seed)
    columns = [p.from_unit(u[:, i]) for i, p in enumerate(ps)]
    return [{p.column: _plain(columns[i][r]) for i, p in enumerate(ps)} for r in range(study.runs_requested)]


def _plain(v: Any) -> Any:
    return v.item() if isinstance(v, np.generic) else v


def expand(study: Study) -> list[Run]:
    """Every (sample, scenario) run with its validated config; errors name the spec key."""
    origins: dict = {}
    base_raw = read_with_includes(study.base, origins)
    study.base_data = copy.deepcopy(base_raw)
    merge(base_raw, study.overrides)
    for p in study.parameters:                     # the key must exist in the (overridden) base
        try:
            base_value = _get(base_raw, p.key)
        except KeyError:
            base_value = _missing
        if p.relative:
            if base_value is _missing or isinstance(base_value, bool) or not isinstance(base_value, (int, float)):
                raise SpecError(f"parameters.{p.key}", "relative: true needs a number at this key in the base config")
    runs: list[Run] = []
    source = str(study.base)
    for sample, values in enumerate(sample_values(study)):
        for scen_name, scen in study.scenarios.items():
            data = copy.deepcopy(base_raw)
            merge(data, scen)
            run_id = len(runs)
            seed = study.seed * 1_000_003 + run_id
            data.setdefault("sim", {})["seed"] = seed
            for p in study.parameters:
                v = values[p.column]
                if p.relative:
                    v = v * _get(base_raw, p.key)
                base_value = _get_or_none(base_raw, p.key)
                if isinstance(base_value, int) and not isinstance(base_value, bool) and isinstance(v, float):
                    v = int(round(v))          # an integer key (substeps, tare_samples) gets the nearest integer
                _set(data, p.key, v)
            try:
                cfg = config_from_data(data, lambda _k: source, source)
            except ConfigError as exc:
                hint = next((p.key for p in study.parameters if exc.key and (exc.key == p.key or
                             exc.key.startswith(p.key + ".") or p.key.startswith(exc.key + "."))), None)
                raise SpecError(f"parameters.{hint}" if hint else "overrides",
                                f"run {run_id} (sample {sample}, {scen_name}): the config rejects it: "
                                f"{exc.key}: {exc.message}") from None
            key = _preflight(cfg, run_id, sample, scen_name, values, study)
            runs.append(Run(run_id, sample, scen_name, cfg["sim"]["seed"], values, cfg, key))
    return runs


_missing = object()


def _get_or_none(data: Any, key: str) -> Any:
    try:
        return _get(data, key)
    except KeyError:
        return None


def _preflight(cfg: Config, run_id: int, sample: int, scenario: str, values: dict[str, Any], study: Study) -> tuple:
    """What the config validation leaves to the plant, the reference and the controller (effect
    parameters, the disturbance times, the profile, a controller the batch runs, impedance gains
    inside the joint-torque loop's limits, the friction model), checked before any run starts. The
    error names the key and the run's sampled values (a sampled plant parameter can move the impedance
    limits, which the daemon derives from the config's actuator). Returns the run's batch key, found
    once here (it builds the controller): what :func:`ankle_rt.sweep.engine.plan` groups by."""
    from ankle_rt.backend import batch_plant_class
    from ankle_rt.sweep.cycle import batch_key

    try:
        batch_plant_class(cfg["backend"], cfg.source).check_config(cfg)
        return batch_key(cfg)      # builds the reference and the controller as the batch will
    except ConfigError as exc:
        hint = next((p.key for p in study.parameters if exc.key and p.key.startswith(exc.key.rsplit(".", 1)[0])), None)
        sampled = "".join(f", {k}={v:g}" if isinstance(v, float) else f", {k}={v}" for k, v in values.items())
        raise SpecError(f"parameters.{hint}" if hint else "overrides",
                        f"run {run_id} (sample {sample}, {scenario}{sampled}): the config rejects it: "
                        f"{exc.key}: {exc.message}") from None
