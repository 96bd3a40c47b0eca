"""matplotlib for the offline tools: optional (the analysis extra), always on the file-only Agg backend."""

from __future__ import annotations

from typing import Any

MISSING = "matplotlib is not installed (pip install 'ankle-rt[analysis]')"


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend, or None when the analysis extra is not installed."""
    try:
        import matplotlib
    except ImportError:
        return None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt
