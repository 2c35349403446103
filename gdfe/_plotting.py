"""matplotlib for files, not screens: the one place the project sets up pyplot.

Figures are written with :func:`gdfe.io.save_figure` (atomically, then closed).
"""

from __future__ import annotations

__all__ = ["pyplot"]


def pyplot():
    """matplotlib's pyplot with the non-interactive Agg backend (imported on first use)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
