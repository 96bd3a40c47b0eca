"""Adversarial pass over `ankle-rt diagnose` (issue 21: every valid file gets a verdict).

One effect-free record, 10 s at 1 kHz (its 4 s validation record for the pairs), of generator A
(tests/diagnosis_cases.py, seed 7, multisine, PD law) or with ``--base b`` of generator B
(tests/diagnosis_cases_b.py, seed 7, walking, impedance law, jittered time stamps) is mutated into
valid-but-unusual and invalid interchange files; each is run through the CLI in this process
(``ankle-rt diagnose FILE --config config/sim.yaml --json``, or ``--plant actuator`` where it says so).
A valid file must exit 0 with a verdict; an invalid one (or one too short for the filters) must exit 2
naming the problem, and one at the length limit either; an exception escaping the CLI (a traceback) is a
failure whatever the file. Prints a line
per mutation (exit code, verdict or the error's first line, seconds) and exits 1 if any failed.

    python benchmarks/fuzz_diagnose.py [--base a|b] [--only NAME ...] [--long-s 600] [--outputs]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from ankle_rt.cli import main  # noqa: E402  (first: it limits the BLAS threads before numpy loads)

import numpy as np  # noqa: E402
from tests.diagnosis_cases import SIM_CONFIG, make_case  # noqa: E402
from tests.diagnosis_cases_b import make_case_b  # noqa: E402

Columns = dict[str, np.ndarray]


def _replace(cols: Columns, **values: float) -> Columns:
    """``cols`` with each named column a constant."""
    return {**cols, **{k: np.full(len(cols["t"]), v) for k, v in values.items()}}


def _rows(cols: Columns, sel: slice | np.ndarray) -> Columns:
    """The rows ``sel`` of every column."""
    return {k: v[sel] for k, v in cols.items()}


def _without(cols: Columns, *names: str) -> Columns:
    return {k: v for k, v in cols.items() if k not in names}


def _jitter(cols: Columns, share: float, seed: int = 1) -> Columns:
    """Time stamps on the median period's grid moved by up to ``share`` of a period each way (still
    increasing)."""
    t = cols["t"]
    dt = float(np.median(np.diff(t)))
    moved = np.arange(len(t)) + np.random.default_rng(seed).uniform(-share, share, len(t))
    return {**cols, "t": t[0] + dt * moved}


def _one_way(cols: Columns) -> Columns:
    """Each motor's path folded to one direction (its travel summed, never reversing)."""
    out = dict(cols)
    for k in ("motor_pos_1", "motor_pos_2"):
        x = cols[k]
        out[k] = x[0] + np.concatenate([[0.0], np.cumsum(np.abs(np.diff(x)))])
    return out


def _tiled(cols: Columns, seconds: float) -> Columns:
    """The record run forwards and backwards in turn (every column continuous) to ``seconds``, time
    running on."""
    n = len(cols["t"])
    dt = float(np.median(np.diff(cols["t"])))
    reps = int(np.ceil(seconds / (n * dt)))
    out = {k: np.concatenate([v if i % 2 == 0 else v[::-1] for i in range(reps)]) for k, v in cols.items()}
    out["t"] = cols["t"][0] + dt * np.arange(n * reps)
    return out


def _held(cols: Columns) -> Columns:
    """Every sensor value held for two rows (a 500 Hz sensor logged at 1 kHz); set values and time as logged."""
    held = np.arange(len(cols["t"])) // 2 * 2
    return {k: (v if k in ("t", "current_cmd_1", "current_cmd_2") else v[held]) for k, v in cols.items()}


def _csv_text(cols: Columns) -> str:
    """The columns as CSV text, every value exact (the interchange writer's 9 digits lose the steps of a
    time 1e6 s from zero)."""
    buf = io.StringIO()
    buf.write(",".join(cols) + "\n")
    np.savetxt(buf, np.column_stack(list(cols.values())), delimiter=",", fmt="%.17g")
    return buf.getvalue()


def _text_rows(cols: Columns, edit: Callable[[list[str]], list[str]]) -> str:
    """The CSV as text lines (header first), edited."""
    return "\n".join(edit(_csv_text(cols).splitlines())) + "\n"


def mutations(cols: Columns, valid: Columns, long_s: float) -> list[tuple[str, bool | None, object, list[str]]]:
    """(name, valid (None: at the length limit, where the rows left after screening and a new time grid
    decide: a verdict or a refusal naming the length), content: columns or CSV text, or a pair of them
    (identification, validation), extra CLI arguments)."""
    n = len(cols["t"])
    rng = np.random.default_rng(3)
    order = list(cols)
    rng.shuffle(order)
    gaps = np.ones(n, dtype=bool)
    gaps[rng.choice(np.arange(10, n - 10), n // 20, replace=False)] = False     # 5 % of rows dropped
    t = cols["t"]
    dup = _text_rows(cols, lambda lines: lines[:500] + [lines[500]] + lines[500:])
    nan_row = _text_rows(cols, lambda lines: lines[:300] + [",".join(["nan"] * len(cols))] + lines[301:])
    empty_cell = _text_rows(cols, lambda lines: lines[:300] + [lines[300].rsplit(",", 1)[0] + ","] + lines[301:])
    return [
        ("unmutated", True, cols, []),
        ("rows 40 (too short)", False, _rows(cols, slice(0, 40)), []),
        ("rows 150", False, _rows(cols, slice(0, 150)), []),
        ("rows 400 (held-out part too short)", False, _rows(cols, slice(0, 400)), []),
        ("rows 816 (held-out part at the limit)", None, _rows(cols, slice(0, 816)), []),
        ("rows 1000", True, _rows(cols, slice(0, 1000)), []),
        ("time jitter 30 %", True, _jitter(cols, 0.3), []),
        ("time jitter 49 %", True, _jitter(cols, 0.49), []),
        ("5 % rows dropped", True, _rows(cols, gaps), []),
        ("duplicated time stamp", False, dup, []),
        ("time decreasing once", False, {**cols, "t": np.where(np.arange(n) == 700, t[698], t)}, []),
        ("time starting at 1e6 s", True, {**cols, "t": t + 1e6}, []),
        ("time starting negative", True, {**cols, "t": t - 100.0}, []),
        ("motors never move", True, _replace(cols, motor_pos_1=0.3, motor_pos_2=-0.2), []),
        ("motor 1 never moves", True, _replace(cols, motor_pos_1=0.3), []),
        ("all-zero current", True, _replace(cols, current_cmd_1=0.0, current_cmd_2=0.0), []),
        ("constant current", True, _replace(cols, current_cmd_1=0.5, current_cmd_2=-0.5), []),
        ("gauges constant", True, _replace(cols, sg_torque_dp=0.7, sg_torque_ie=-0.3), []),
        ("gauges zero", True, _replace(cols, sg_torque_dp=0.0, sg_torque_ie=0.0), []),
        ("ankle encoders constant", True, _replace(cols, ankle_dp=0.01, ankle_ie=0.0), []),
        ("everything zero but time", True, _replace(cols, **{k: 0.0 for k in cols if k != "t"}), []),
        ("one NaN row", False, nan_row, []),
        ("one empty cell", False, empty_cell, []),
        ("columns shuffled", True, {k: cols[k] for k in order}, []),
        ("extra unknown columns", True, {**cols, "note": np.zeros(n), "seq": np.arange(n, dtype=float)}, []),
        ("CRLF line endings", True, _text_rows(cols, lambda lines: [ln + "\r" for ln in lines]), []),
        ("currents beyond the config (99 A)", False,
         {**cols, "current_cmd_1": 99.0 * np.sign(cols["current_cmd_1"])}, []),
        ("currents at the config's bound (22 A)", True,
         {**cols, "current_cmd_1": 22.0 * np.sign(cols["current_cmd_1"])}, []),
        ("gauges at the config's bound (330 N m)", True,
         {**cols, "sg_torque_dp": 330.0 * np.tanh(cols["sg_torque_dp"])}, []),
        ("huge values, actuator, no config", True,
         {"t": t, "motor_pos_1": cols["motor_pos_1"] * 1e3, "current_cmd_1": cols["current_cmd_1"] * 99.0
          / np.max(np.abs(cols["current_cmd_1"]))}, ["--plant", "actuator", "--no-config"]),
        ("positions offset 9000 rad", True, {**cols, "motor_pos_1": cols["motor_pos_1"] + 9000.0,
                                             "motor_pos_2": cols["motor_pos_2"] - 9000.0}, []),
        ("tiny values (1e-300)", True, {**cols, "current_cmd_1": cols["current_cmd_1"] * 1e-300,
                                        "current_cmd_2": cols["current_cmd_2"] * 1e-300}, []),
        ("no ankle encoders", True, _without(cols, "ankle_dp", "ankle_ie"), []),
        ("no references", True, _without(cols, "ref_dp", "ref_ie"), []),
        ("no ankle encoders, no references", True, _without(cols, "ankle_dp", "ankle_ie", "ref_dp", "ref_ie"), []),
        ("only ankle_dp of the joint encoders", True, _without(cols, "ankle_ie"), []),
        ("only ref_dp of the references", True, _without(cols, "ref_ie"), []),
        ("only sg_torque_dp of the gauges", False, _without(cols, "sg_torque_ie"), []),
        ("current 1 and motor torque 2", False, {**_without(cols, "current_cmd_2"),
                                                "motor_torque_2": 0.1 * cols["current_cmd_2"]}, []),
        ("no gauges (ankle plant)", False, _without(cols, "sg_torque_dp", "sg_torque_ie"), []),
        ("no motor 2 (ankle plant)", False, _without(cols, "motor_pos_2", "current_cmd_2"), []),
        ("motor 1 only, actuator plant", True,
         {k: cols[k] for k in ("t", "motor_pos_1", "current_cmd_1")}, ["--plant", "actuator"]),
        ("motor 1 only, actuator, no config", True,
         {k: cols[k] for k in ("t", "motor_pos_1", "current_cmd_1")}, ["--plant", "actuator", "--no-config"]),
        ("motor torques instead of currents", True,
         {**_without(cols, "current_cmd_1", "current_cmd_2"), "motor_torque_1": 0.1 * cols["current_cmd_1"],
          "motor_torque_2": 0.1 * cols["current_cmd_2"]}, []),
        ("one direction of motion", True, _one_way(cols), []),
        ("one direction, actuator, no config", True,
         {k: v for k, v in _one_way(cols).items() if k in ("t", "motor_pos_1", "current_cmd_1")},
         ["--plant", "actuator", "--no-config"]),
        ("motor 1 reversed sign", True, {**cols, "motor_pos_1": -cols["motor_pos_1"]}, []),
        ("coarse encoder (0.01 rad)", True, {**cols, "motor_pos_1": np.round(cols["motor_pos_1"], 2),
                                              "motor_pos_2": np.round(cols["motor_pos_2"], 2)}, []),
        ("coarse joint encoders (0.02 rad)", True, {**cols, "ankle_dp": np.round(cols["ankle_dp"] / 0.02) * 0.02,
                                                    "ankle_ie": np.round(cols["ankle_ie"] / 0.02) * 0.02}, []),
        ("coarse joint encoders (0.3 rad)", True, {**cols, "ankle_dp": np.round(cols["ankle_dp"] / 0.3) * 0.3,
                                                   "ankle_ie": np.round(cols["ankle_ie"] / 0.3) * 0.3}, []),
        ("motors dither by 1e-12 rad", True, {**cols, "motor_pos_1": 0.3 + 1e-12 * rng.standard_normal(n),
                                               "motor_pos_2": -0.2 + 1e-12 * rng.standard_normal(n)}, []),
        ("motors step once", True, {**cols, "motor_pos_1": np.where(np.arange(n) < n // 2, 0.3, 0.31),
                                    "motor_pos_2": np.where(np.arange(n) < n // 3, -0.2, -0.21)}, []),
        ("time stamps in pairs 1 us apart", False,
         {**cols, "t": np.where(np.arange(n) % 2 == 1, np.roll(t, 1) + 1e-6, t)}, []),
        ("500 Hz (every other row)", True, _rows(cols, slice(0, n, 2)), []),
        ("sensors held two rows each", True, _held(cols), []),
        ("current square wave", True, {**cols, "current_cmd_1": np.where(np.arange(n) % 200 < 100, 1.0, -1.0)}, []),
        (f"long ({long_s:g} s)", True, _tiled(cols, long_s), []),
        # (identification, validation): the second file given as --validation
        ("validation without ankle encoders", True, (cols, _without(valid, "ankle_dp", "ankle_ie")), []),
        ("validation without gauges", False, (cols, _without(valid, "sg_torque_dp", "sg_torque_ie")), []),
        ("validation in motor torques", True,
         (cols, {**_without(valid, "current_cmd_1", "current_cmd_2"), "motor_torque_1": 0.1 * valid["current_cmd_1"],
                 "motor_torque_2": 0.1 * valid["current_cmd_2"]}), []),
        ("validation at 500 Hz", True, (cols, _rows(valid, slice(0, None, 2))), []),
        ("validation motors never move", True, (cols, _replace(valid, motor_pos_1=0.3, motor_pos_2=-0.2)), []),
        ("validation all zero but time", True, (cols, _replace(valid, **{k: 0.0 for k in valid if k != "t"})), []),
        ("validation 300 rows", True, (cols, _rows(valid, slice(0, 300))), []),
        ("validation 204 rows (the limit)", None, (cols, _rows(valid, slice(0, 204))), []),
        ("both 204 rows (the limit)", None, (_rows(cols, slice(0, 204)), _rows(valid, slice(0, 204))), []),
        ("identification without ankle encoders", True, (_without(cols, "ankle_dp", "ankle_ie"), valid), []),
    ]


def run_one(path: Path, extra: list[str], outputs: bool) -> tuple[int | None, str, str]:
    """(exit code or None for an escaped exception, stdout, stderr); with ``outputs`` also --report and
    --write-model beside ``path``."""
    args = ["diagnose", str(path), "--json", "--no-closed-loop"]
    if outputs:
        args += ["--report", str(path.with_suffix(".report")), "--write-model", str(path.with_suffix(".yaml"))]
    if "--no-config" in extra:
        extra = [a for a in extra if a != "--no-config"]
    else:
        args += ["--config", str(SIM_CONFIG)]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(args + extra)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 2
        except Exception:      # noqa: BLE001 - a traceback is what this pass looks for
            traceback.print_exc(file=err)
            code = None
    return code, out.getvalue(), err.getvalue()


def main_fuzz() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", help="run only mutations whose name contains one of these")
    ap.add_argument("--long-s", type=float, default=600.0, help="length of the long file (s)")
    ap.add_argument("--base", choices=("a", "b"), default="a", help="the record mutated: a, generator A's multisine "
                    "under the PD law; b, generator B's walking under the impedance law with jittered time stamps")
    ap.add_argument("--outputs", action="store_true", help="also write --report and --write-model for each file")
    args = ap.parse_args()
    case = (make_case(seed=7, plant="ankle", cause="none", ident_s=10.0, valid_s=4.0) if args.base == "a"
            else make_case_b(7, [], "impedance", "walking", jitter=True, ident_s=10.0, valid_s=4.0))
    cols = dict(case.ident.columns)
    failed = 0
    with tempfile.TemporaryDirectory() as tmp:
        for i, (name, valid, content, extra) in enumerate(mutations(cols, dict(case.valid.columns), args.long_s)):
            if args.only and not any(s in name for s in args.only):
                continue
            path = Path(tmp) / f"m{i}.csv"
            contents = content if isinstance(content, tuple) else (content,)
            for j, c in enumerate(contents):
                path.with_suffix(f".{j}.csv").write_text(c if isinstance(c, str) else _csv_text(c))
            if len(contents) > 1:
                extra = extra + ["--validation", str(path.with_suffix(".1.csv"))]
            path = path.with_suffix(".0.csv")
            t0 = time.perf_counter()
            code, out, err = run_one(path, extra, args.outputs)
            dt = time.perf_counter() - t0
            if code == 0 and out:
                what = ",".join(json.loads(out)["causes"])
            else:
                lines = [ln for ln in err.splitlines() if ln.strip()]
                what = (lines[-1] if code is None else next((ln for ln in lines if "warning" not in ln),
                                                            lines[-1] if lines else ""))
            ok = code in ((0, 2) if valid is None else (0 if valid else 2,))
            failed += not ok
            kind = "limit" if valid is None else "valid" if valid else "invalid"
            print(f"{'ok  ' if ok else 'FAIL'} {name:<38} {kind:<8} exit {code!s:<4} {dt:6.1f} s  {what[:150]}",
                  flush=True)
            if code is None:
                print(err, flush=True)
    print(f"{failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main_fuzz())
