"""Benchmark of `ankle-rt diagnose` on N seeded cases of two generators, side by side.

Generator A, the extended generator (tests/diagnosis_cases.py, the project's simulator and effect classes:
one, two or three effects at once, rotor cogging through the gearbox, torque offsets, effect-free and
out-of-vocabulary data, clipped / drifting / held strain gauges, currents at the amplifier limit, dropped
samples, gait-like and one-directional motion, short records).

Prints per case and in summary: exact-set accuracy (the named set equals the hidden one), recall and
false-name rate per effect, false names on effect-free or artefact-only data, artefact warnings,
single-effect top-1, primary-parameter error (median, 90th percentile), the README identification
trajectory with 486-period rotor cogging at 1 % of the rated torque, and the diagnose runtime on a 30 s,
1 kHz, two-motor file. Goals (issue 11): >= 60 cases, >= 30 % with several effects; exact set >= 90 %,
recall >= 95 % per effect, false names <= 2 %, single-effect top-1 100 %, parameter error median <= 10 %,
the 486-period cogging named with its count exact, runtime <= 20 s.

Generator B (tests/diagnosis_cases_b.py, issue 21): its own plant integration and effect forms (cogging
per motor with harmonics at 1134 / 1944 periods per output turn, per-cable backlash, k(1+|s|/s0)
stiffening, ...), walking-only logs, the impedance controller, irregular time stamps, calibration and
sensor conditions (truth `none` with a finding expected). Both report exact-set accuracy, recall per
word, false names, files without a verdict (diagnose raised), flags given where expected, seconds per file.

Generator C (benchmarks/diagnosis_cases_c.py, diag4): written without the diagnosis' or A/B's code (exact
linear discretisation with Heun nonlinear forces, quantised sensors in the loop, a Coulomb transition
sharper than the config's, own effect forms, quadratic drag and a viscoelastic cable outside the vocabulary).

Generator D (benchmarks/diagnosis_cases_d.py, diagD): written blind as well, from a real device's physics and
logs (semi-implicit integration with a true stuck state, capstan sheath friction, gear backlash with impact,
LuGre bristles, a first-order current loop, late control ticks, a 500 Hz log, stale and dropped rows).

    python benchmarks/bench_diagnose.py [--n 64] [--seed 1000] [--generator a|b|c|d|both|all]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from ankle_rt.blas_threads import limit_blas_threads  # noqa: E402

limit_blas_threads()    # as `ankle-rt` runs the diagnosis (before numpy loads OpenBLAS)

import numpy as np  # noqa: E402

from ankle_rt.diagnosis import diagnose  # noqa: E402
from ankle_rt.diagnosis.core import Diagnosis  # noqa: E402
from ankle_rt.timing_reference import reference_step_s  # noqa: E402
from tests.diagnosis_cases import README_RUN_YAML, draw_scenario, make_case, primary_error  # noqa: E402
from tests.diagnosis_cases_b import draw_case_b, make_case_b, write_case_b  # noqa: E402
from benchmarks.diagnosis_cases_c import draw_case_c, make_case_c, write_case_c  # noqa: E402
from benchmarks.diagnosis_cases_d import draw_case_d, make_case_d, write_case_d  # noqa: E402

NAMES_EXCLUDED = ("none", "unknown")
REF_S = [float("nan")]     # s per reference step, measured once per run in main()


def pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def readme_rotor_cogging() -> str:
    """The README's identification run (chirp, 20 s, daemon on the simulator) with rotor cogging of 6
    periods per motor turn through the 81:1 gearbox (486 per output turn) at 1 % of the rated torque."""
    from ankle_rt.config import load_config
    from ankle_rt.daemon import run_lockstep
    from ankle_rt.interchange import Recording

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.yaml"
        path.write_text(README_RUN_YAML)
        nominal = load_config(path)
        rated = nominal["actuator"]["torque_constant"] * nominal["amplifier"]["current_limit_continuous"]
        n = 6 * int(nominal["actuator"]["gear_ratio"])
        effect = {"type": "cogging", "amplitude": 0.01 * rated, "periods_per_rev": n, "phase": 0.7}
        truth = load_config(path, overrides={"sim": {"effects": [effect]}})
        rec = Recording(run_lockstep(truth, 20.0).interchange(), "README run")
    t0 = time.perf_counter()
    diag = diagnose(rec, None, plant="ankle", cfg=nominal)
    dt = time.perf_counter() - t0
    found = next((e for e in diag.effects if e["type"] == "cogging"), None)
    if found is None:
        return f"NOT named (causes {diag.causes}) in {dt:.1f} s"
    p = found["parameters"]
    return (f"causes {diag.causes}; periods_per_rev {p['periods_per_rev']['value']:.0f} (true {n}), amplitude "
            f"{p['amplitude']['value']:.4f} N m (true {effect['amplitude']:.4f}), {dt:.1f} s")


@dataclass
class Row:
    """One benchmark file: its truth, what diagnose said (None: no verdict, ``error`` says why), its time."""

    seed: int
    truth: tuple[str, ...]
    diag: Diagnosis | None
    seconds: float
    expect_flag: bool = False
    error: str = ""

    @property
    def named(self) -> list[str]:
        return list(self.diag.causes) if self.diag is not None else []

    @property
    def exact(self) -> bool:
        return sorted(self.named) == sorted(self.truth)


def flagged(diag: Diagnosis) -> bool:
    """A data warning or a calibration finding was given."""
    return bool(diag.data_warnings or diag.calibration)


def run_case(seed: int, ident, valid, plant: str, cfg, truth, expect_flag: bool = False) -> Row:
    """Diagnose one case; an exception is a file without a verdict (counted, never fatal)."""
    t0 = time.perf_counter()
    try:
        diag, error = diagnose(ident, valid, plant=plant, cfg=cfg), ""
    except Exception as exc:   # noqa: BLE001 - the benchmark counts it as "no verdict"
        diag, error = None, f"{type(exc).__name__}: {exc}"
    return Row(seed, tuple(truth), diag, time.perf_counter() - t0, expect_flag, error)


def print_misses(name: str, rows: list[Row]) -> None:
    """Every case whose named set differs from its truth, or that expected a flag and got none."""
    missed = [r for r in rows if not r.exact or (r.expect_flag and not (r.diag and flagged(r.diag)))]
    print(f"generator {name} misses: {len(missed)}")
    for r in missed:
        flag = "  (no flag)" if r.expect_flag and not (r.diag and flagged(r.diag)) else ""
        print(f"  seed {r.seed}: truth {','.join(sorted(r.truth))} -> named {','.join(r.named) or r.error}{flag}")


def summary(rows: list[Row]) -> dict[str, str]:
    """The figures both generators report, as printable strings."""
    if not rows:
        return {"cases": "0"}
    recall: dict[str, list[bool]] = {}
    false_names: dict[str, int] = {}
    for r in rows:
        for x in r.truth:
            recall.setdefault(x, []).append(x in r.named)
        for x in r.named:
            if x not in r.truth:
                false_names[x] = false_names.get(x, 0) + 1
    times = [r.seconds for r in rows]
    expect = [r for r in rows if r.expect_flag]
    return {
        "cases": str(len(rows)),
        "exact-set accuracy": f"{sum(r.exact for r in rows)}/{len(rows)} ({pct(np.mean([r.exact for r in rows]))})",
        "files without a verdict": str(sum(r.diag is None for r in rows)),
        "flag expected and given": (f"{sum(flagged(r.diag) for r in expect if r.diag)}/{len(expect)}"
                                    if expect else "-"),
        "false names (cases)": ", ".join(f"{k} {v}" for k, v in sorted(false_names.items())) or "none",
        "seconds per file": f"median {np.median(times):.2f}, max {max(times):.2f}",
        "ref steps per file": f"median {np.median(times) / REF_S[0]:.3g}, max {max(times) / REF_S[0]:.3g}",
        **{f"recall {k}": f"{sum(v)}/{len(v)}" for k, v in sorted(recall.items())},
    }


def generator_a(args: argparse.Namespace) -> list[Row]:
    """Generator A (tests/diagnosis_cases.py) with its own detailed figures (issue 11's goals)."""
    rows, cases = [], []
    print(f"{'seed':>6} {'plant':<8} {'motion':<9} {'artefact':<13} {'truth':<44} {'named':<44} {'s':>5}")
    for i in range(args.n):
        spec = draw_scenario(args.seed + i)
        case = make_case(**spec)
        row = run_case(case.seed, case.ident, case.valid, case.plant, case.nominal_cfg, case.causes)
        rows.append(row)
        cases.append(case)
        mark = "" if row.exact else "  <-- differs"
        print(f"{case.seed:>6} {case.plant:<8} {case.motion:<9} {','.join(case.artefacts) or '-':<13} "
              f"{','.join(case.causes):<44} {','.join(row.named) or row.error:<44} {row.seconds:>5.2f}{mark}",
              flush=True)
    pairs = [(c, r) for c, r in zip(cases, rows) if r.diag is not None]
    multi = [(c, r) for c, r in pairs if len([x for x in c.causes if x not in NAMES_EXCLUDED]) >= 2]
    single = [(c, r) for c, r in pairs if len(c.effects) == 1 and c.causes[0] not in NAMES_EXCLUDED]
    clean = [(c, r) for c, r in pairs if not c.effects]
    artefact_cases = [(c, r) for c, r in pairs if c.artefacts]
    false_clean = [p for p in clean if any(x not in NAMES_EXCLUDED for x in p[1].named)]
    unknown_clean = [p for p in clean if "unknown" in p[1].named]
    errors = [e for c, r in pairs for d in r.diag.effects if d["type"] in c.causes
              for e in [primary_error(c, d["parameters"], d["type"])] if e is not None]
    print()
    print(f"generator A, cases: {len(rows)} (seeds {args.seed}..{args.seed + args.n - 1}): {len(multi)} with two or "
          f"more effects ({pct(len(multi) / len(rows))}), {len(single)} single-effect, {len(clean)} effect-free or "
          f"artefact-only, {len(artefact_cases)} with sensor artefacts")
    print(f"exact-set accuracy:                      {pct(np.mean([r.exact for r in rows]))}   (goal >= 90 %)")
    if multi:
        print(f"exact-set accuracy, several effects:     {pct(np.mean([r.exact for _, r in multi]))}")
    if single:
        print(f"single-effect top-1:                     "
              f"{pct(np.mean([r.named[0] == c.causes[0] for c, r in single]))}   (goal 100 %)")
    print(f"false names, effect-free/artefact-only:  {pct(len(false_clean) / max(1, len(clean)))}   (goal <= 2 %); "
          f"'unknown' there: {pct(len(unknown_clean) / max(1, len(clean)))}")
    if artefact_cases:
        print(f"artefact cases with a data warning:      {pct(np.mean([flagged(r.diag) for _, r in artefact_cases]))}")
    if errors:
        print(f"primary parameter error (named effects): median {pct(np.median(errors))}, 90th pct "
              f"{pct(np.percentile(errors, 90))}   (goal median <= 10 %)")
    print(f"README trajectory, 486-period rotor cogging at 1 % rated torque: {readme_rotor_cogging()}")
    if args.runtime_s > 0:
        case = make_case(args.seed - 1, "ankle", ["stribeck", "delay"], ident_s=args.runtime_s,
                         valid_s=args.runtime_s / 3)
        t0 = time.perf_counter()
        diag = diagnose(case.ident, case.valid, plant="ankle", cfg=case.nominal_cfg)
        dt = time.perf_counter() - t0
        print(f"runtime: diagnose on a {args.runtime_s:g} s, 1 kHz, two-motor file (+ {args.runtime_s / 3:g} s "
              f"validation): {dt:.1f} s = {dt / REF_S[0]:.3g} ref steps (goal <= 20 s); named {diag.causes}")
    return rows


def run_generated(name: str, cases: Iterable, save: Path | None, write: Callable, head: str,
                  cells: Callable) -> list[Row]:
    """Diagnose the cases of an independent generator (B, C) one by one, a line each (``head`` / ``cells``:
    the generator's own columns); with ``save`` each is also written as interchange CSVs, its truth in
    truth.txt."""
    rows = []
    print(f"{'seed':>6} {head} {'truth':<36} {'named':<36} {'s':>5}")
    for case in cases:
        if save:
            write(case, save)
            with open(save / "truth.txt", "a") as f:
                f.write(f"{name}{case.seed}: causes {','.join(case.causes)}; flag expected {case.expect_flag}; "
                        f"{case.describe()}\n")
        row = run_case(case.seed, case.ident, case.valid, "ankle", case.nominal_cfg, case.causes, case.expect_flag)
        rows.append(row)
        flag = "" if not case.expect_flag else (" flag ok" if row.diag and flagged(row.diag) else " NO FLAG")
        mark = "" if row.exact else "  <-- differs"
        print(f"{case.seed:>6} {cells(case)} {','.join(case.causes):<36} {','.join(row.named) or row.error:<36} "
              f"{row.seconds:>5.2f}{mark}{flag}", flush=True)
    return rows


def print_runtime(name: str, case, runtime_s: float) -> None:
    """Diagnose a long walking file under the impedance law and print the time it took."""
    row = run_case(case.seed, case.ident, case.valid, "ankle", case.nominal_cfg, case.causes)
    print(f"\nruntime, generator {name}: diagnose on a {runtime_s:g} s walking file under the impedance law "
          f"(+ {runtime_s / 3:g} s validation): {row.seconds:.1f} s = {row.seconds / REF_S[0]:.3g} ref steps "
          f"(goal <= 20 s); named {row.named} (truth {list(case.causes)})")


def generator_b(args: argparse.Namespace) -> list[Row]:
    """Generator B (tests/diagnosis_cases_b.py): its own plant integration and effect forms."""
    cases = (make_case_b(**draw_case_b(args.seed + i)) for i in range(args.n))
    rows = run_generated("b", cases, args.save_b, write_case_b,
                         f"{'ctl':<9} {'motion':<9} {'jit':<3} {'conditions':<52}",
                         lambda c: f"{c.controller:<9} {c.motion:<9} {'y' if c.jitter else '-':<3} "
                                   f"{','.join(c.kinds) or '-':<52}")
    if args.runtime_s > 0:   # walking under the impedance law: slow motor reversals widen the cogging search
        print_runtime("B", make_case_b(args.seed - 1, ["stribeck", "asymmetric_friction"], "impedance", "walking",
                                       ident_s=args.runtime_s, valid_s=args.runtime_s / 3), args.runtime_s)
    return rows


def _independent(name: str, make, draw, save, write, runtime_effects: list[str], args: argparse.Namespace) -> list[Row]:
    """Generator ``name`` (C or D: the same case interface): ``args.n`` drawn cases, then the runtime
    file, walking under the impedance law with ``runtime_effects``."""
    cases = (make(**draw(args.seed + i)) for i in range(args.n))
    rows = run_generated(name.lower(), cases, save, write, f"{'ctl':<9} {'motion':<9} {'kinds':<52}",
                         lambda c: f"{c.controller:<9} {c.motion:<9} {','.join(c.kinds) or '-':<52}")
    if args.runtime_s > 0:
        print_runtime(name, make(args.seed - 1, runtime_effects, controller="impedance", motion="walking",
                                 ident_s=args.runtime_s, valid_s=args.runtime_s / 3), args.runtime_s)
    return rows


def generator_c(args: argparse.Namespace) -> list[Row]:
    """Generator C (benchmarks/diagnosis_cases_c.py): written without the diagnosis' or A/B's code; its
    runtime file has three effects at once, cogging among them."""
    return _independent("C", make_case_c, draw_case_c, args.save_c, write_case_c,
                        ["cogging", "load_dependent_friction", "backlash"], args)


def generator_d(args: argparse.Namespace) -> list[Row]:
    """Generator D (benchmarks/diagnosis_cases_d.py): a real device's physics and logs, written blind; its
    runtime file has three effects, backlash's impacts among them."""
    return _independent("D", make_case_d, draw_case_d, args.save_d, write_case_d,
                        ["backlash", "load_dependent_friction", "cogging"], args)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=64, help="number of cases per generator (>= 60 for the issue's figures)")
    ap.add_argument("--seed", type=int, default=1000, help="first seed; case i uses seed + i")
    ap.add_argument("--runtime-s", type=float, default=30.0, help="length of the runtime file (0: skip)")
    ap.add_argument("--generator", choices=("a", "b", "c", "d", "both", "all"), default="both",
                    help="a: the project simulator's cases; b, c: the independent generators; both: a and b side "
                    "by side; all: a, b, c and d")
    ap.add_argument("--save-b", type=Path, metavar="DIR", help="also write generator B's cases there as interchange "
                    "CSVs (b<seed>_ident.csv, b<seed>_valid.csv) with their truth in truth.txt")
    ap.add_argument("--save-c", type=Path, metavar="DIR", help="the same for generator C (c<seed>_*.csv)")
    ap.add_argument("--save-d", type=Path, metavar="DIR", help="the same for generator D (d<seed>_*.csv)")
    args = ap.parse_args()
    for d in (args.save_b, args.save_c, args.save_d):
        if d:
            d.mkdir(parents=True, exist_ok=True)
    REF_S[0] = reference_step_s()     # the machine-independent unit (ankle_rt.timing_reference)
    print(f"reference step (plain-Python RK4 of the cable model): {REF_S[0] * 1e6:.1f} us on this machine")

    results, rows = {}, {}
    if args.generator in ("a", "both", "all"):
        rows["A"] = generator_a(args)
        print()
    if args.generator in ("b", "both", "all"):
        rows["B"] = generator_b(args)
        print()
    if args.generator in ("c", "all"):
        rows["C"] = generator_c(args)
        print()
    if args.generator in ("d", "all"):
        rows["D"] = generator_d(args)
        print()
    for name, generated in rows.items():
        results[name] = summary(generated)
        print_misses(name, generated)
    print()
    keys = list(dict.fromkeys(k for s in results.values() for k in s if not k.startswith("recall")))
    keys += sorted({k for s in results.values() for k in s if k.startswith("recall")})
    print(f"{'':<34}" + "".join(f"{'generator ' + g:<40}" for g in results))
    for k in keys:
        print(f"{k:<34}" + "".join(f"{s.get(k, '-'):<40}" for s in results.values()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
