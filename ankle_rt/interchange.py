"""The measured-data interchange format (docs/design.md): one CSV row per control cycle, SI units.

Reading checks the file the way a person would want it checked: a file that is not UTF-8 text (a
leading byte-order mark is fine), a missing required column, a row with more or fewer cells than the
header, a non-numeric, non-finite or implausibly large cell, or time that does not increase is an
:class:`InterchangeError` naming the column and the row (1-based data row, the header being row 0;
reported as the file's line number too). Unknown columns are ignored. Whether the sampling and the
units fit a configuration is :mod:`ankle_rt.sampling`'s check.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Mapping

import numpy as np

from ankle_rt.textfile import TextFileError, iter_lines

KNOWN_COLUMNS = (
    "t", "motor_pos_1", "motor_pos_2", "current_cmd_1", "current_cmd_2",
    "motor_torque_1", "motor_torque_2", "sg_torque_dp", "sg_torque_ie",
    "ankle_dp", "ankle_ie", "ref_dp", "ref_ie",
)


class InterchangeError(ValueError):
    """A data file does not follow the interchange format; the message names column and row."""

    def __init__(self, message: str, path: str | Path | None = None, column: str | None = None,
                 row: int | None = None):
        self.path, self.column, self.row = (str(path) if path else None), column, row
        parts = [str(path)] if path else []
        if column is not None:
            parts.append(f"column {column!r}")
        if row is not None:
            parts.append(f"row {row} (line {row + 1})")
        super().__init__(f"{', '.join(parts)}: {message}" if parts else message)


@dataclass
class Recording:
    """Columns of one interchange file as float arrays, keyed by column name."""

    columns: dict[str, np.ndarray]
    source: str = "<memory>"
    extra: dict[str, object] = field(default_factory=dict)

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __len__(self) -> int:
        return len(self.columns["t"])

    @property
    def two_motors(self) -> bool:
        return "motor_pos_2" in self.columns

    @property
    def input_kind(self) -> str:
        """'current' (set values in A) or 'torque' (motor torques in N m, used as-is)."""
        return "current" if "current_cmd_1" in self.columns else "torque"

    def motor_input(self, kt: float | None) -> np.ndarray:
        """N x motors array of motor torque (N m, or N for a linear axis): torques as-is, or kt * current."""
        n = 2 if self.two_motors else 1
        if self.input_kind == "torque":
            return np.column_stack([self.columns[f"motor_torque_{i}"] for i in range(1, n + 1)])
        if kt is None:
            raise InterchangeError("current set values need a torque constant (give a config)", self.source,
                                   "current_cmd_1")
        return kt * np.column_stack([self.columns[f"current_cmd_{i}"] for i in range(1, n + 1)])

    @property
    def dt(self) -> float:
        """Median sample period (s)."""
        return float(np.median(np.diff(self.columns["t"])))


def _header_hint(header: list[str]) -> str:
    """The header as read, and the usual reason a required name is not in it (another separator, a
    comment line first, units in the names), for the error that says it is missing."""
    shown = ", ".join(repr(h[:40]) for h in header[:6]) + (", ..." if len(header) > 6 else "")
    if len(header) == 1 and any(sep in header[0] for sep in ";\t|"):
        return f"; the header is one cell, {header[0][:60]!r}: the columns must be separated by commas"
    if header and header[0].startswith("#"):
        return f"; the first line is {header[0][:60]!r}: the header must be the first line"
    required = {"t", "motor_pos_1"}
    if any(re.split(r"[\s\[(]", h, maxsplit=1)[0] in required - {h} for h in header):
        return f"; the header is {shown}: a name carries no unit ('t', not 't [s]'; every unit is SI)"
    if "t" not in header and any(h.lower() in ("t", "time", "timestamp", "time_s") for h in header):
        return f"; the header is {shown}: the time column is named 't' (in s; every name lower case)"
    return f"; the header is {shown}"


def _repeated_stamp_hint(before: float, stamp: float) -> str:
    """Why a clock's large stamp may repeat: written with too few digits (a UNIX time to 9 significant
    digits keeps whole seconds), which the file's reader cannot undo."""
    if stamp != before or abs(stamp) < 100.0:
        return ""
    return (f" ({stamp!r} twice: a clock's stamps written with too few digits? write t with 17 significant "
            "digits, or in s from the record's start)")


def _required_columns(header: list[str], path: str | Path) -> None:
    if "t" not in header:
        raise InterchangeError("required column missing (time in s)" + _header_hint(header), path, "t", 0)
    if "motor_pos_1" not in header:
        raise InterchangeError("required column missing (motor angle in rad)" + _header_hint(header), path,
                               "motor_pos_1", 0)
    two = "motor_pos_2" in header
    pairs = ("current_cmd", "motor_torque")
    suffixes = ("_1", "_2") if two else ("_1",)
    if not any(all(p + s in header for s in suffixes) for p in pairs):
        want = " or ".join("+".join(p + s for s in suffixes) for p in pairs)
        raise InterchangeError(f"required input columns missing: need {want}", path,
                               "current_cmd_1", 0)


MAX_CSV_BYTES = 256 << 20
"""Largest interchange file read (256 MiB: about 2.5 hours at 1 kHz with every column)."""

# Largest magnitude a value of each column can plausibly have (SI units); beyond it the file is not in
# the units this format states (or is damaged), and numerical tools would fail on it further down.
PLAUSIBLE_ABS: dict[str, tuple[float, str]] = {
    "t": (1e10, "s"),              # a clock's absolute seconds (UNIX time) pass, its milliseconds do not
    "motor_pos_1": (1e4, "rad"), "motor_pos_2": (1e4, "rad"),          # at the gearbox output
    "current_cmd_1": (100.0, "A"), "current_cmd_2": (100.0, "A"),
    "motor_torque_1": (1e3, "N m"), "motor_torque_2": (1e3, "N m"),
    "sg_torque_dp": (1e3, "N m"), "sg_torque_ie": (1e3, "N m"),
    "ankle_dp": (2 * math.pi, "rad"), "ankle_ie": (2 * math.pi, "rad"),
    "ref_dp": (2 * math.pi, "rad"), "ref_ie": (2 * math.pi, "rad"),
}
_UNIT_HINTS = {"s": "time in ms rather than s?", "rad": "degrees or counts rather than rad?",
               "A": "mA rather than A?", "N m": "N mm rather than N m?"}


def read_columns(path: str | Path, columns: Iterable[str], check_header: Callable[[list[str]], None],
                 min_rows: int = 2, *, limit_bytes: int = MAX_CSV_BYTES,
                 plausible: Mapping[str, tuple[float, str]] = PLAUSIBLE_ABS) -> dict[str, list[float]]:
    """Read the named ``columns`` of a CSV with a header row as lists of floats, checking every cell.

    ``check_header(header)`` raises for missing required columns; names in ``columns`` that the
    header lacks are skipped. Raises :class:`InterchangeError` naming column and row for a file that
    is not a regular UTF-8 text file of at most ``limit_bytes``, a non-numeric or non-finite cell, a
    value beyond the column's ``plausible`` magnitude, a row with fewer or more cells than the
    header, a file shorter than ``min_rows`` data rows, or a ``t`` column that does not increase.
    The file is streamed (:func:`ankle_rt.textfile.iter_lines`), never read whole into memory."""
    try:
        reader = csv.reader(iter_lines(path, limit_bytes))
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise InterchangeError("empty file (expected a header row)", path) from None
        check_header(header)
        wanted = set(columns)
        dupes = {h for h in header if header.count(h) > 1 and h in wanted}
        if dupes:
            raise InterchangeError("column appears more than once", path, sorted(dupes)[0], 0)
        keep = [(i, h, *plausible.get(h, (math.inf, ""))) for i, h in enumerate(header) if h in wanted]
        data: dict[str, list[float]] = {h: [] for _, h, _, _ in keep}
        times = data.get("t")
        width = len(header)
        for row_no, row in enumerate(reader, start=1):
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) != width:
                column = header[len(row)] if len(row) < width else f"#{width + 1} (no header)"
                raise InterchangeError(f"row has {len(row)} cells, header has {width}", path, column, row_no)
            for i, name, bound, unit in keep:
                cell = row[i].strip()
                try:
                    value = float(cell)
                except ValueError:
                    raise InterchangeError(f"not a number: {cell[:40]!r}", path, name, row_no) from None
                if not math.isfinite(value):
                    raise InterchangeError(f"not a finite number: {cell[:40]!r}", path, name, row_no)
                if not -bound <= value <= bound:
                    raise InterchangeError(f"implausible value {value:.6g}: beyond +/-{bound:g} {unit} "
                                           f"({_UNIT_HINTS[unit]} or a damaged file)", path, name, row_no)
                data[name].append(value)
            if times is not None and len(times) > 1 and times[-1] <= times[-2]:
                raise InterchangeError("time does not increase" + _repeated_stamp_hint(times[-2], times[-1]),
                                       path, "t", row_no)
    except TextFileError as exc:
        raise InterchangeError(str(exc), path) from None
    except csv.Error as exc:
        raise InterchangeError(f"not a CSV file ({exc})", path) from None
    n = len(next(iter(data.values()))) if data else 0
    if n < min_rows:
        raise InterchangeError(f"too short: {n} data rows, need at least {min_rows}", path, "t", n)
    return data


def read_table(path: str | Path, columns: Iterable[str], check_header: Callable[[list[str]], None],
               min_rows: int = 2) -> dict[str, np.ndarray]:
    """:func:`read_columns` as float arrays."""
    return {k: np.asarray(v, dtype=float) for k, v in read_columns(path, columns, check_header, min_rows).items()}


def read_csv(path: str | Path, min_rows: int = 2) -> Recording:
    """Read and check an interchange CSV. Raises :class:`InterchangeError` naming column and row."""
    return Recording(read_table(path, KNOWN_COLUMNS, lambda header: _required_columns(header, path), min_rows),
                     str(path))


def write_csv(path: str | Path, columns: Mapping[str, Iterable[float]]) -> None:
    """Write columns (all the same length) as an interchange CSV, in the order given."""
    names = list(columns)
    arrays = [np.asarray(columns[n], dtype=float) for n in names]
    lengths = {len(a) for a in arrays}
    if len(lengths) > 1:
        raise ValueError(f"columns differ in length: {dict(zip(names, map(len, arrays)))}")
    with Path(path).open("w", newline="") as handle:
        handle.write(",".join(names) + "\n")
        np.savetxt(handle, np.column_stack(arrays) if arrays else np.zeros((0, 0)), delimiter=",", fmt="%.9g")
