"""core/figures.py: every plot is written by save_figure (laid out, folders made, closed), none by savefig."""
from __future__ import annotations

import re
from pathlib import Path

from gnss_sim_ros2.core.figures import pyplot, save_figure

REPO = Path(__file__).resolve().parents[1]


def test_save_figure_writes_closes_and_makes_folders(tmp_path):
    plt = pyplot()
    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    path = save_figure(fig, tmp_path / "a" / "b" / "line.png")
    assert path == tmp_path / "a" / "b" / "line.png"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not plt.fignum_exists(fig.number)


def test_no_plot_bypasses_save_figure():
    own = REPO / "gnss_sim_ros2" / "core" / "figures.py"
    files = [p for folder in ("gnss_sim_ros2", "scripts", "bench") for p in (REPO / folder).rglob("*.py") if p != own]
    bypass = [f"{p.relative_to(REPO)}:{i}" for p in files
              for i, line in enumerate(p.read_text().splitlines(), 1) if re.search(r"\.savefig\(", line)]
    assert not bypass, f"plots written without core/figures.save_figure: {bypass}"
