"""Figures without a screen: matplotlib's pyplot on the Agg backend, and writing a figure to PNG.

Every plot of gnss_sim (sky plots, comparison reports, sweep summaries, bench plots) starts from
``pyplot()`` and ends with ``save_figure``."""
from __future__ import annotations

from pathlib import Path

from .user_cache import write_whole


def pyplot():
    """matplotlib.pyplot with the Agg backend (PNG files, no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def check_png_name(path, where: str) -> Path:
    """``path`` when :func:`save_figure` writes it as a PNG (a .png name, or none: .png is added); ValueError
    naming ``where`` otherwise, before any work (matplotlib's own "Format 'txt' is not supported" names no option
    and comes after the run)."""
    path = Path(path)
    if path.suffix.lower() not in ("", ".png"):
        raise ValueError(f"{where}: the figure is a PNG, give a file name ending in .png")
    return path


def save_figure(fig, path, dpi: int = 110) -> Path:
    """Lay out, write (PNG, folders made) and close a matplotlib figure; its path (``.png`` added to a name
    without suffix, as matplotlib does).  Written under a temporary name beside it and renamed when complete:
    a killed or failed write leaves no torn figure and the previous one in place (core/output_folder.py)."""
    plt = pyplot()
    fig.tight_layout()
    path = Path(path)
    if not path.suffix:
        path = path.with_name(path.name + ".png")
    try:
        write_whole(path, lambda f: fig.savefig(f, dpi=dpi, format=path.suffix[1:].lower()))
    finally:
        plt.close(fig)
    return path
