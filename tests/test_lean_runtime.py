"""The prosthesis computer installs only the runtime dependencies (pyproject.toml: numpy, pyyaml, python-can,
canopen, pyserial; scipy and matplotlib are the `analysis` extra): the daemon must load, check and run the
shipped controllers without them. A module-level scipy import in the gait-phase controller's swing bound
once made config/walk.yaml need the extra."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# blocks the extras (an import of them raises ImportError), then builds and runs each config briefly
SCRIPT = """
import sys
for name in ("scipy", "matplotlib"):
    sys.modules[name] = None
from ankle_rt.config import load_config
from ankle_rt.daemon import run_lockstep
for path in sys.argv[1:]:
    print(path, run_lockstep(load_config(path), 0.2).summary["fault"])
"""


def test_the_daemon_runs_the_shipped_controllers_without_the_analysis_extra():
    configs = [str(ROOT / "config" / name) for name in ("sim.yaml", "walk.yaml")]
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    out = subprocess.run([sys.executable, "-c", SCRIPT, *configs], capture_output=True, text=True, env=env,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == [configs[0], "NONE", configs[1], "NONE"]
