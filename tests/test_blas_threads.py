"""The CLI runs numpy on one BLAS thread unless the environment sets it (ankle_rt.blas_threads): under load the
default thread per core made the diagnosis 5-10x slower, and on the prosthesis computer those threads would
compete with the real-time loop."""

from __future__ import annotations

import os
import subprocess
import sys

from ankle_rt.blas_threads import VARIABLES

PROBE = "import os, ankle_rt.cli, numpy; print(' '.join(os.environ[v] for v in %r))" % (VARIABLES,)


def _probe(**env: str) -> list[str]:
    clean = {k: v for k, v in os.environ.items() if k not in VARIABLES}
    out = subprocess.run([sys.executable, "-c", PROBE], env={**clean, **env}, capture_output=True, text=True, check=True)
    return out.stdout.split()


def test_the_cli_sets_one_blas_thread_before_numpy_loads():
    assert _probe() == ["1"] * len(VARIABLES)


def test_a_thread_count_the_user_set_is_kept():
    assert _probe(OPENBLAS_NUM_THREADS="3") == ["3"] + ["1"] * (len(VARIABLES) - 1)
