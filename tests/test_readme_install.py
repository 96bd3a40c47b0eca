"""The README's quick start works on a fresh machine exactly as written.

The two command lines are read from README.md (so the test and the README cannot drift), and run in
a new virtual environment (no system site-packages: the install has to bring every dependency) in a
clean clone of this checkout's HEAD. The first installs the project and runs the main job on the
simulator; the second installs the test extra and runs pytest. To keep CI to one pass over the suite,
the nested pytest gets ``PYTEST_ADDOPTS`` naming one test file: the command line itself is unchanged,
and the run still proves that pytest, hypothesis (imported by conftest) and the project import.
Then the example controller plugin is installed into the same venv and found through its entry point.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
NESTED_PYTEST_SELECTION = "tests/test_config.py"


def quick_start_commands(readme: str) -> list[str]:
    """The command lines of the first ``sh`` block under ``## Quick start``."""
    section = readme.split("## Quick start", 1)[1]
    block = re.search(r"```sh\n(.*?)```", section, re.S)
    assert block, "README.md: no ```sh block under '## Quick start'"
    return [line.strip() for line in block.group(1).splitlines() if line.strip()]


def test_ci_runs_the_readme_test_command():
    commands = quick_start_commands((ROOT / "README.md").read_text())
    assert len(commands) == 2 and "pytest" in commands[1]
    ci = [line.strip() for line in (ROOT / ".ci" / "run").read_text().splitlines()]
    assert commands[1] in ci


@pytest.mark.slow
def test_readme_quick_start_in_a_fresh_venv_from_a_clean_clone(tmp_path):
    if not (ROOT / ".git").exists() or shutil.which("git") is None:
        pytest.skip("not a git checkout: nothing to clone")
    clone, venv = tmp_path / "clone", tmp_path / "venv"
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(clone)], check=True)
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV", "PYTEST_ADDOPTS")}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["MPLBACKEND"] = "Agg"
    install_and_run, install_and_test = quick_start_commands((clone / "README.md").read_text())

    main = subprocess.run(["bash", "-c", install_and_run], cwd=clone, env=env, capture_output=True, text=True)
    assert main.returncode == 0, main.stdout[-3000:] + main.stderr[-3000:]
    assert "final state ACTIVE" in main.stdout, main.stdout[-3000:]
    assert list((clone / "logs").glob("run-*.arlog")) and list((clone / "logs").glob("run-*.png"))

    tests = subprocess.run(["bash", "-c", install_and_test], cwd=clone, capture_output=True, text=True,
                           env={**env, "PYTEST_ADDOPTS": NESTED_PYTEST_SELECTION})
    assert tests.returncode == 0, tests.stdout[-3000:] + tests.stderr[-3000:]
    assert re.search(r"\d+ passed", tests.stdout) and " failed" not in tests.stdout, tests.stdout[-3000:]

    # The example controller plugin, installed as a user would: found through its real entry point.
    example = "examples/ankle-rt-example-controller"
    plugin = subprocess.run(["bash", "-c", f"python3 -m pip install -e {example} && "
                             f"ankle-rt config check {example}/run.yaml"],
                            cwd=clone, env=env, capture_output=True, text=True)
    assert plugin.returncode == 0, plugin.stdout[-3000:] + plugin.stderr[-3000:]
    assert "controller:  load_stiffening (plugin)" in plugin.stdout, plugin.stdout[-3000:]
