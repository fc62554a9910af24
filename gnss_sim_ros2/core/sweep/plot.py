"""Summary plot of a sweep: the horizontal error percentiles of every run, grouped by the axes
other than the seed (one box per group and percentile, every run a dot), and the fix availability."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..figures import pyplot, save_figure
from .table import PERCENTILES

#: input columns that make a group (the seed varies inside one)
GROUP_COLUMNS = ("start_time", "preset", "trajectory", "world")


def group_label(row: dict, columns) -> str:
    parts = []
    for c in columns:
        v = row.get(c) or ""
        parts.append(Path(v).stem if c in ("trajectory", "world") and v else (v or "-"))
    return " ".join(parts) if parts else "all runs"


def summary_plot(rows: list[dict], path: Path, title: str = "gnss-sim sweep") -> Path:
    plt = pyplot()

    ok = [r for r in rows if r.get("status") == "ok"]
    varying = [c for c in GROUP_COLUMNS if len({r.get(c) for r in rows}) > 1]
    groups: dict[str, list[dict]] = {}
    for r in sorted(ok, key=lambda r: r["index"]):
        groups.setdefault(group_label(r, varying), []).append(r)
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.8), gridspec_kw={"width_ratios": [3, 1]})
    n = max(len(groups), 1)
    width = 0.8 / n
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    rng = np.random.default_rng(0)          # dot jitter only
    for g, (label, members) in enumerate(groups.items()):
        color = colors[g % len(colors)]
        for k, p in enumerate(PERCENTILES):
            v = np.array([r[f"h_err_p{p}_m"] for r in members if r[f"h_err_p{p}_m"] is not None], dtype=float)
            if not v.size:
                continue
            x = k + (g - (n - 1) / 2) * width
            ax.boxplot(v, positions=[x], widths=width * 0.8, showfliers=False, patch_artist=True,
                       boxprops={"facecolor": color, "alpha": 0.35}, medianprops={"color": color})
            ax.plot(x + rng.uniform(-0.25, 0.25, v.size) * width, v, ".", color=color, ms=3,
                    label=label if k == 0 else None)
        fa = np.array([r["fix_availability"] for r in members if r["fix_availability"] is not None], dtype=float)
        if fa.size:
            ax2.boxplot(100 * fa, positions=[g], widths=0.6, showfliers=False, patch_artist=True,
                        boxprops={"facecolor": color, "alpha": 0.35}, medianprops={"color": color})
            ax2.plot(g + rng.uniform(-0.2, 0.2, fa.size), 100 * fa, ".", color=color, ms=3)
    ax.set_xticks(range(len(PERCENTILES)), [f"p{p}" for p in PERCENTILES])
    ax.set_xlim(-0.6, len(PERCENTILES) - 0.4)
    ax.set_ylabel("horizontal error of the fixes [m]")
    ax.set_xlabel("percentile over the epochs of one run (one dot per run)")
    ax.grid(True, axis="y", alpha=0.3)
    if len(groups) > 1:
        ax.legend(fontsize=8, title=" ".join(varying), title_fontsize=8)
    names = [label if len(label) <= 14 else f"{i + 1}" for i, label in enumerate(groups)] if len(groups) > 1 else [""]
    ax2.set_xticks(range(len(groups)), names, rotation=20 if len(groups) > 3 else 0, fontsize=8)
    ax2.set_ylabel("fix availability [%]")
    ax2.grid(True, axis="y", alpha=0.3)
    failed = len(rows) - len(ok)
    fig.suptitle(f"{title}: {len(ok)} runs" + (f", {failed} failed" if failed else ""))
    return save_figure(fig, path)
