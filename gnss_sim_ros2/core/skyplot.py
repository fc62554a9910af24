"""Polar sky plot (PNG, matplotlib Agg): satellites by system and line-of-sight state, scene skyline.

North up, azimuth clockwise, zenith at the centre, horizon at the rim (radius = 90 - elevation).
Visible satellites are filled discs, attenuated ones (foliage, diffraction) hollow discs, those received
only by a reflection (core/multipath) hollow diamonds, blocked ones crosses.  The scene is drawn either
from the casts over the whole sky (``sky``: the blocked cells of ``Scene.sky_grid`` shaded grey, foliage
cells green, so open sky under an overhang stays white) or as skylines (``horizon`` / ``foliage_horizon``:
everything below the highest blocked elevation shaded).
"""
from __future__ import annotations

import numpy as np

#: colour per RINEX system letter
SYSTEM_COLORS = {"G": "#1f77b4", "R": "#d62728", "E": "#2ca02c", "C": "#ff7f0e", "J": "#9467bd", "I": "#8c564b",
                 "S": "#7f7f7f"}
SYSTEM_NAMES = {"G": "GPS", "R": "GLONASS", "E": "Galileo", "C": "BeiDou", "J": "QZSS", "I": "NavIC", "S": "SBAS"}


def plot_skyplot(png_path, sv, az_deg, el_deg, state, horizon=None, foliage_horizon=None, mask_deg=None,
                 title: str | None = None, sky=None) -> None:
    """Write a sky plot.  ``state``: names ("visible", "blocked", "attenuated", "reflected") or STATE_* codes.

    ``horizon`` / ``foliage_horizon``: (az_deg, el_deg) skyline arrays, e.g. from ``Scene.horizon_profile``;
    ``sky``: (az_edges_deg, el_edges_deg, opaque, foliage) from ``Scene.sky_grid`` (drawn instead of them).
    """
    from matplotlib.lines import Line2D

    from .figures import pyplot

    plt = pyplot()

    from .scene.visibility import STATE_NAMES

    sv = np.asarray(sv, dtype=str)
    az = np.asarray(az_deg, dtype=float)
    el = np.asarray(el_deg, dtype=float)
    st = np.asarray(state)
    if st.dtype.kind in "iu":
        st = np.array([STATE_NAMES.get(int(s), "visible") for s in st], dtype=object)
    if not (len(sv) == len(az) == len(el) == len(st)):
        raise ValueError("plot_skyplot: sv, az_deg, el_deg and state must have the same length")

    fig = plt.figure(figsize=(7, 7.4))
    ax = fig.add_subplot(projection="polar")
    ax.set_theta_zero_location("N")
    ax.set_theta_direction(-1)
    ax.set_rlim(0, 90)
    ax.set_rticks([0, 15, 30, 45, 60, 75, 90])
    ax.set_yticklabels(["90°", "75°", "60°", "45°", "30°", "15°", "0°"], fontsize=7)
    ax.set_thetagrids(range(0, 360, 30), ["N", "30", "60", "E", "120", "150", "S", "210", "240", "W", "300", "330"])

    def shade(hz, color, alpha, label):
        haz, hel = (np.asarray(x, float) for x in hz)
        th = np.radians(np.append(haz, haz[0] + 360.0 if len(haz) else 0.0))
        r = 90.0 - np.append(hel, hel[0] if len(hel) else 0.0)
        ax.fill_between(th, r, 90.0, color=color, alpha=alpha, lw=0, label=label)
        ax.plot(th, r, color=color, lw=1.0)

    if sky is not None:
        from matplotlib.colors import ListedColormap

        az_e, el_e, opaque, foliage = (np.asarray(x) for x in sky)
        th, r = np.meshgrid(np.radians(az_e), 90.0 - np.asarray(el_e, float), indexing="ij")
        for cells, color, alpha in ((foliage, "#2e8b57", 0.35), (opaque, "#606060", 0.55)):
            if np.any(cells):
                ax.pcolormesh(th, r, np.ma.masked_where(~cells.astype(bool), np.ones(cells.shape)),
                              cmap=ListedColormap([color]), alpha=alpha, shading="flat", lw=0)
    else:
        if foliage_horizon is not None:
            shade(foliage_horizon, "#2e8b57", 0.25, "foliage")
        if horizon is not None:
            shade(horizon, "#606060", 0.45, "buildings")
    if mask_deg:
        th = np.linspace(0, 2 * np.pi, 361)
        ax.plot(th, np.full_like(th, 90.0 - mask_deg), ls="--", color="k", lw=0.7, label=f"mask {mask_deg:g}°")

    for s, a, e, state_name in zip(sv, az, el, st):
        if e < 0:
            continue
        color = SYSTEM_COLORS.get(s[:1], "k")
        th, r = np.radians(a), 90.0 - e
        if state_name == "blocked":
            ax.plot(th, r, marker="x", ms=9, mew=2.0, color=color, ls="none")
        elif state_name == "attenuated":
            ax.plot(th, r, marker="o", ms=11, mfc="none", mew=2.0, color=color, ls="none")
        elif state_name == "reflected":
            ax.plot(th, r, marker="D", ms=9, mfc="none", mew=2.0, color=color, ls="none")
        else:
            ax.plot(th, r, marker="o", ms=11, color=color, ls="none")
        ax.annotate(s, (th, r), textcoords="offset points", xytext=(7, 5), fontsize=7,
                    color="0.4" if state_name == "blocked" else "k")

    systems = sorted({s[:1] for s in sv})
    handles = [Line2D([], [], marker="o", ls="none", color=SYSTEM_COLORS.get(k, "k"), label=SYSTEM_NAMES.get(k, k))
               for k in systems]
    handles += [Line2D([], [], marker="o", ls="none", color="k", label="visible"),
                Line2D([], [], marker="o", ls="none", mfc="none", color="k", label="attenuated"),
                Line2D([], [], marker="D", ls="none", mfc="none", color="k", label="reflected only"),
                Line2D([], [], marker="x", ls="none", color="k", label="blocked")]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.04), ncol=5, fontsize=8, frameon=False)
    if title:
        ax.set_title(title, fontsize=10, pad=18)
    fig.tight_layout()
    fig.savefig(png_path, dpi=110)
    plt.close(fig)
