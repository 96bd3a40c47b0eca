"""Benchmark of `ankle-rt diagnose` on N random seeded cases (tests/diagnosis_cases.py).

Prints per case and in summary: top-1 accuracy, false-positive rate on effect-free data, wrong-name
rate on the out-of-vocabulary effects (torque constant dropping at high current; a return spring),
primary-parameter error
(median, 90th percentile), validation NRMSE reduction, detection rate against effect magnitude, and the
diagnose runtime on a 30 s, 1 kHz, two-motor file. Goals (issue 6): top-1 >= 95 %, FP <= 2 %, median
parameter error <= 10 %, NRMSE reduced >= 30 % whenever an effect is present, runtime <= 20 s.

    python benchmarks/bench_diagnose.py [--n 60] [--seed 1000] [--actuator-share 0.25]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

# The regressions are small (thousands of rows, tens of columns): BLAS threads only fight over the two
# shared cores (3x slower measured under load). Set before numpy loads OpenBLAS.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from ankle_rt.diagnosis import diagnose  # noqa: E402
from tests.diagnosis_cases import make_case, primary_error  # noqa: E402


def pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=60, help="number of random cases (>= 50 for the issue's figures)")
    ap.add_argument("--seed", type=int, default=1000, help="first seed; case i uses seed + i")
    ap.add_argument("--actuator-share", type=float, default=0.25, help="fraction of single-actuator cases")
    ap.add_argument("--ident-s", type=float, default=12.0)
    ap.add_argument("--valid-s", type=float, default=6.0)
    ap.add_argument("--runtime-s", type=float, default=30.0, help="length of the runtime file (0: skip)")
    ap.add_argument("--sweep", type=float, nargs="*", default=[0.5, 0.25, 0.1],
                    help="strengths below the weakest plausible size for the detection sweep (none: skip)")
    args = ap.parse_args()

    rows = []
    print(f"{'seed':>6} {'plant':<8} {'truth':<24} {'named':<24} {'mag':>4} {'conf':>5} {'p.err':>7} "
          f"{'NRMSE b->e':>16} {'diag s':>6}")
    for i in range(args.n):
        seed = args.seed + i
        plant = "actuator" if np.random.default_rng(seed + 10**6).uniform() < args.actuator_share else "ankle"
        case = make_case(seed, plant, None, ident_s=args.ident_s, valid_s=args.valid_s)
        t0 = time.perf_counter()
        diag = diagnose(case.ident, case.valid, plant=plant, cfg=case.nominal_cfg)
        dt = time.perf_counter() - t0
        err = primary_error(case, diag.parameters) if diag.cause == case.cause else None
        truth = case.effect["type"] if case.effect else "none"
        rows.append((case, diag, err, dt))
        print(f"{seed:>6} {plant:<8} {truth:<24} {diag.cause:<24} {case.magnitude:>4.2f} {diag.confidence:>5.2f} "
              f"{'' if err is None else f'{100 * err:6.1f}%':>7} "
              f"{diag.nrmse_baseline:7.4f}->{diag.nrmse_extended:7.4f} {dt:>6.2f}", flush=True)

    effect_cases = [r for r in rows if r[0].cause not in ("none", "unknown")]
    none_cases = [r for r in rows if r[0].cause == "none"]
    oov_cases = [r for r in rows if r[0].cause == "unknown"]
    top1_all = np.mean([r[1].cause == r[0].cause for r in rows])
    top1_eff = np.mean([r[1].cause == r[0].cause for r in effect_cases]) if effect_cases else float("nan")
    fp = np.mean([r[1].cause != "none" for r in none_cases]) if none_cases else float("nan")
    wrong = np.mean([r[1].cause not in ("unknown", "none") for r in oov_cases]) if oov_cases else float("nan")
    oov_unknown = np.mean([r[1].cause == "unknown" for r in oov_cases]) if oov_cases else float("nan")
    errs = np.array([r[2] for r in effect_cases if r[2] is not None])
    red = np.array([1.0 - r[1].nrmse_extended / r[1].nrmse_baseline for r in effect_cases
                    if r[1].cause == r[0].cause])
    print()
    print(f"cases: {len(rows)} ({len(effect_cases)} with a vocabulary effect, {len(none_cases)} effect-free, "
          f"{len(oov_cases)} out of vocabulary); seeds {args.seed}..{args.seed + args.n - 1}")
    print(f"top-1 accuracy, all cases:            {pct(top1_all)}")
    print(f"top-1 accuracy, effect cases:         {pct(top1_eff)}   (goal >= 95 %)")
    print(f"false-positive rate, effect-free:     {pct(fp)}   (goal <= 2 %)")
    print(f"wrong-name rate, out of vocabulary:   {pct(wrong)}   (named unknown: {pct(oov_unknown)})")
    if errs.size:
        print(f"primary parameter error:              median {pct(np.median(errs))}, 90th pct "
              f"{pct(np.percentile(errs, 90))}   (goal median <= 10 %)")
    if red.size:
        print(f"validation NRMSE reduction (named):   median {pct(np.median(red))}, min {pct(red.min())}, "
              f">= 30 % in {pct(np.mean(red >= 0.3))} of cases")
    print("detection rate against magnitude (0 = weakest plausible, 1 = strongest):")
    for lo, hi in ((0.0, 1 / 3), (1 / 3, 2 / 3), (2 / 3, 1.0001)):
        sel = [r for r in effect_cases if lo <= r[0].magnitude < hi]
        if sel:
            rate = np.mean([r[1].cause == r[0].cause for r in sel])
            print(f"  magnitude {lo:.2f}-{min(hi, 1):.2f}: {pct(rate)} of {len(sel)}")
    by_effect: dict[str, list[bool]] = {}
    for r in effect_cases:
        by_effect.setdefault(r[0].cause, []).append(r[1].cause == r[0].cause)
    print("per effect: " + ", ".join(f"{k} {sum(v)}/{len(v)}" for k, v in sorted(by_effect.items())))
    print(f"diagnose time per case ({args.ident_s:g} s + {args.valid_s:g} s files): median "
          f"{np.median([r[3] for r in rows]):.2f} s")

    if args.sweep:
        print("detection below the plausible range (strength x the weakest plausible size; 1 seed per cell):")
        effects = ("stribeck", "asymmetric_friction", "load_dependent_friction", "cogging", "delay", "backlash",
                   "stiffness_nonlinear")
        print("  " + " " * 24 + "".join(f"{s:>8g}" for s in args.sweep))
        for k, name in enumerate(effects):
            cells = []
            for j, strength in enumerate(args.sweep):
                case = make_case(args.seed + 5000 + 10 * k + j, "ankle", name, ident_s=args.ident_s,
                                 valid_s=args.valid_s, strength=strength)
                diag = diagnose(case.ident, case.valid, plant="ankle", cfg=case.nominal_cfg)
                cells.append("hit" if diag.cause == name else diag.cause[:7])
            print(f"  {name:<24}" + "".join(f"{c:>8}" for c in cells), flush=True)

    if args.runtime_s > 0:
        case = make_case(args.seed - 1, "ankle", "stribeck", ident_s=args.runtime_s, valid_s=args.runtime_s / 3)
        t0 = time.perf_counter()
        diag = diagnose(case.ident, case.valid, plant="ankle", cfg=case.nominal_cfg)
        dt = time.perf_counter() - t0
        print(f"runtime: diagnose on a {args.runtime_s:g} s, 1 kHz, two-motor file (+ {args.runtime_s / 3:g} s "
              f"validation): {dt:.1f} s (goal <= 20 s); named {diag.cause}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
