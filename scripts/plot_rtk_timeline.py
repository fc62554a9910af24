"""The RTK time line of a `gnss-sim run --rtk` on the demo path: fixed / float / single / none per epoch
and the horizontal error against the true path, with the parts of the path shaded.

    gnss-sim run --rtk --duration 175 --out demo_rtk          # the demo path's full length
    python scripts/plot_rtk_timeline.py demo_rtk --out docs/rtk-demo-timeline.png

Reads the run's ``rtk_timeline.csv`` and ``summary.json`` (commands/run/summary.py, core/rtk/summary.py).
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

#: the demo path's parts (core/trajectory.py DEMO_WAYPOINTS, worlds/README.md) [s]
DEMO_PARTS = ((0.0, 25.0, "open ground"), (25.0, 51.0, "gate"), (51.0, 70.0, "courtyard"),
              (70.0, 100.0, "under tree_1"), (100.0, 127.0, "courtyard"), (127.0, 157.0, "under the ledge"),
              (157.0, 175.0, "courtyard"))
LEVELS = {"fixed": 3, "float": 2, "single": 1, "none": 0}
COLORS = {"fixed": "tab:green", "float": "tab:orange", "single": "tab:red", "none": "0.5"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", help="output folder of gnss-sim run --rtk")
    ap.add_argument("--out", default="docs/rtk-demo-timeline.png", help="PNG to write")
    args = ap.parse_args(argv)
    run = Path(args.run_dir)
    try:
        summary = json.loads((run / "summary.json").read_text())
        rows = list(csv.DictReader((run / summary["rtk_timeline"]).open()))
    except (OSError, KeyError, json.JSONDecodeError) as exc:
        print(f"plot_rtk_timeline: error: {run} holds no RTK run (summary.json with rtk_timeline): {exc}",
              file=sys.stderr)
        return 2
    from gnss_sim_ros2.core.figures import pyplot, save_figure

    plt = pyplot()

    n = summary["epochs"]
    t = [float(r["t_s"]) for r in rows]
    q = [r["quality"] if r["quality"] in LEVELS else "single" for r in rows]
    err = [max(float(r["horizontal_error_m"]), 1e-4) for r in rows]
    seen = {round(x) for x in t}
    t_none = [float(k) for k in range(n) if k not in seen]
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(9, 4.8), gridspec_kw={"height_ratios": [1, 1.4]})
    for i, (a, b, name) in enumerate(DEMO_PARTS):
        for ax in (ax1, ax2):
            ax.axvspan(a, b, color="0.93" if i % 2 else "white", zorder=0)
        ax1.text((a + b) / 2, 3.55, name, ha="center", va="bottom", fontsize=7)
    for name, level in LEVELS.items():
        xs = t_none if name == "none" else [ti for ti, qi in zip(t, q) if qi == name]
        ax1.scatter(xs, [level] * len(xs), s=9, color=COLORS[name], label=f"{name} ({len(xs)})")
    ax1.set_yticks(list(LEVELS.values()), list(LEVELS))
    ax1.set_ylim(-1.3, 4.2)
    ax1.legend(loc="lower center", bbox_to_anchor=(0.42, 0.0), fontsize=7, ncol=4, frameon=False)
    for name in ("fixed", "float", "single"):
        xs = [(ti, ei) for ti, qi, ei in zip(t, q, err) if qi == name]
        ax2.scatter([x for x, _ in xs], [e for _, e in xs], s=7, color=COLORS[name])
    ax2.set_yscale("log")
    ax2.set_ylabel("horizontal error [m]")
    ax2.set_xlabel("time on the demo path [s]")
    ax2.set_xlim(0, max(n - 1, 1))
    ax1.set_title(f"gnss-sim run --rtk, demo path: RTK solution on {summary['rtk_solution_ratio']:.0%} of "
                  f"{n} epochs, fixed {summary['rtk_fixed_ratio']:.0%}, float {summary['rtk_float_ratio']:.0%}",
                  fontsize=9)
    out = save_figure(fig, args.out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
