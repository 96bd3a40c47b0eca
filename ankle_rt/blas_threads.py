"""One BLAS thread per process unless the environment says otherwise.

numpy's OpenBLAS runs every large product and solve on a thread per core. On a shared machine under load those
threads wait for cores other processes hold: on this 2-core machine at load 3-7 the diagnosis of a 30 s file
took 43-73 s where one thread takes 9 s (a 60 000 x 30 least squares: 410 ms against 114 ms; docs/diagnosis.md,
diag24), and on the prosthesis computer they would compete with the real-time loop for its cores. The
variables are read when numpy is first imported, so :func:`limit_blas_threads` must run before that; a variable
the user has set is kept (``OPENBLAS_NUM_THREADS=4 ankle-rt diagnose ...``). One thread changes the last digits
of a diagnosis (relative 3e-14 at most), not its verdict.
"""

from __future__ import annotations

import os

VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def limit_blas_threads() -> None:
    """Set each of VARIABLES to 1 where the environment leaves it unset."""
    for name in VARIABLES:
        os.environ.setdefault(name, "1")
