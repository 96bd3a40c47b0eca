"""The project stands on its own: every Markdown file a tracked file names exists in the project
(paths from the repository root, the naming file's directory, or docs/). Names of files the commands
write (a diagnosis report) are outputs, not references."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
OUTPUTS = {"report.md", "report/report.md"}      # written by `ankle-rt diagnose --report DIR`
INSTALLED_PREFIX = "/opt/ankle-rt/src/"          # the unit's Documentation= points at the installed checkout


def tracked_text_files() -> list[Path]:
    try:
        names = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout")
    return [ROOT / n for n in names if not n.endswith((".eds", ".png", ".arlog"))]


def test_every_named_markdown_file_exists():
    missing = []
    for path in tracked_text_files():
        try:
            text = path.read_text()
        except (UnicodeDecodeError, FileNotFoundError):
            continue
        for name in re.findall(r"[A-Za-z0-9_./-]*[A-Za-z0-9_-]\.md\b", text):
            name = name.lstrip("/").removeprefix(INSTALLED_PREFIX.lstrip("/"))
            if name in OUTPUTS:
                continue
            if not any((base / name).is_file() for base in (ROOT, path.parent, ROOT / "docs")):
                missing.append(f"{path.relative_to(ROOT)}: {name}")
    assert not missing, missing


def test_design_notes_are_the_projects_own():
    design = (ROOT / "docs" / "design.md").read_text()
    for section in ("## Layout", "## Nominal model", "## The loop", "## Safety", "interchange format"):
        assert section in design
    assert "shared/" not in design
