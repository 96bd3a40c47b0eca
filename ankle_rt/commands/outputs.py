"""The check every command that writes a file makes before its work starts: the output path must
take a file without destroying what the command reads."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable


def output_problem(path: str, inputs: Iterable[str | None], what: str = "input files") -> str | None:
    """Why ``path`` cannot take an output file, or None: it must be a regular file or not exist yet,
    in an existing directory, and none of the ``inputs`` (files read; None entries are skipped,
    ``what`` names them in the message)."""
    out = Path(path)
    if out.exists() or out.is_symlink():
        if out.is_dir():
            return "is a directory, not a regular file; give a file name"
        if not out.is_file():
            return "exists and is not a regular file"
        if any(p and Path(p).exists() and os.path.samefile(out, p) for p in inputs):
            return f"is one of the {what} (it would be overwritten); choose another path"
    elif not out.parent.is_dir():
        return f"no such directory: {out.parent}"
    return None
