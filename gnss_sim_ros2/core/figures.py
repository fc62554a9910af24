"""Figures without a screen: matplotlib's pyplot on the Agg backend, and writing a figure to PNG.

Every plot of gnss_sim (sky plots, comparison reports, sweep summaries, bench plots) starts from
``pyplot()`` and ends with ``save_figure``."""
from __future__ import annotations

from pathlib import Path


def pyplot():
    """matplotlib.pyplot with the Agg backend (PNG files, no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path, dpi: int = 110) -> Path:
    """Lay out, write (PNG, folders made) and close a matplotlib figure; its path."""
    plt = pyplot()
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path
