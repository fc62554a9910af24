"""Polar sky plot (PNG, matplotlib Agg): satellites by system and line-of-sight state, scene skyline.

North up, azimuth clockwise, zenith at the centre, horizon at the rim (radius = 90 - elevation).
Visible satellites are filled discs, attenuated ones (foliage, diffraction) hollow discs, those received
only by a reflection (core/multipath) hollow diamonds, blocked ones crosses, those below the elevation mask
(state ``below_mask``, or an elevation under ``mask_deg``) small hollow grey discs: the receiver does not
use them, whatever the scene does to them.  The scene is drawn from the casts over the whole sky (``sky``:
the blocked cells of ``Scene.sky_grid`` shaded grey, foliage cells green, so open sky under an overhang stays
white) and/or as skylines (``horizon`` / ``foliage_horizon``, ``Scene.horizon_profile``): the scene's edge
drawn as a line (grey, green for foliage), everything below it shaded when there is no ``sky``.
"""
from __future__ import annotations

import numpy as np

#: colour per RINEX system letter
SYSTEM_COLORS = {"G": "#1f77b4", "R": "#d62728", "E": "#2ca02c", "C": "#ff7f0e", "J": "#9467bd", "I": "#8c564b",
                 "S": "#7f7f7f"}
SYSTEM_NAMES = {"G": "GPS", "R": "GLONASS", "E": "Galileo", "C": "BeiDou", "J": "QZSS", "I": "NavIC", "S": "SBAS"}


#: how a satellite of each drawn state looks: (marker, marker size, filled, label of its legend entry)
MARKERS = {"visible": ("o", 11, True, "visible"), "attenuated": ("o", 11, False, "attenuated"),
           "reflected": ("D", 9, False, "reflected only"), "blocked": ("x", 9, True, "blocked"),
           "below_mask": ("o", 7, False, "below mask")}
BELOW_MASK_COLOR = "0.3"


def plot_skyplot(png_path, sv, az_deg, el_deg, state, horizon=None, foliage_horizon=None, mask_deg=None,
                 title: str | None = None, sky=None, sky_mask=None) -> dict:
    """Write a sky plot.  ``state``: names ("visible", "blocked", "attenuated", "reflected", "below_mask") or
    STATE_* codes; a satellite under ``mask_deg`` is drawn as below the mask whatever its state.

    ``horizon`` / ``foliage_horizon``: (az_deg, el_deg) skyline arrays, e.g. from ``Scene.horizon_profile``
    (outlined; shaded below when there is no ``sky``); ``sky``: (az_edges_deg, el_edges_deg, opaque, foliage)
    from ``Scene.sky_grid`` (cells shaded); ``sky_mask``: (az_deg, el_deg) of a measured sky mask
    (core/visibility/sky_mask.py), a dashed magenta line joined across north.  Returns the figure's artists:
    {"satellites": {sv: (drawn state, Line2D)}, "skyline": Line2D or None, "foliage": Line2D or None, "sky_mask":
    Line2D or None, "legend": [labels]} (the figure is closed).
    """
    from matplotlib.lines import Line2D

    from .figures import pyplot, save_figure

    plt = pyplot()

    from .scene.visibility import STATE_NAMES

    sv = np.asarray(sv, dtype=str)
    az = np.asarray(az_deg, dtype=float)
    el = np.asarray(el_deg, dtype=float)
    st = np.asarray(state)
    if st.dtype.kind in "iu":
        # int8 STATE_* codes; a uint8 message field carries STATE_BELOW_MASK (-1) as 255
        codes = [int(s) - 256 if int(s) > 127 else int(s) for s in st]
        bad = sorted({c for c in codes if c not in STATE_NAMES})
        if bad:
            raise ValueError(f"plot_skyplot: state codes {bad} are not STATE_* codes {sorted(STATE_NAMES)}")
        st = np.array([STATE_NAMES[c] for c in codes], dtype=object)
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

    def outline(hz, color, alpha, label, fill):
        haz, hel = (np.asarray(x, float) for x in hz)
        th = np.radians(np.append(haz, haz[0] + 360.0 if len(haz) else 0.0))
        r = 90.0 - np.append(hel, hel[0] if len(hel) else 0.0)
        if fill:
            ax.fill_between(th, r, 90.0, color=color, alpha=alpha, lw=0, label=label)
        return ax.plot(th, r, color=color, lw=1.0)[0]

    if sky is not None:
        from matplotlib.colors import ListedColormap

        az_e, el_e, opaque, foliage = (np.asarray(x) for x in sky)
        th, r = np.meshgrid(np.radians(az_e), 90.0 - np.asarray(el_e, float), indexing="ij")
        # opaque colours (#606060 at 55 %, #2e8b57 at 35 % over white): translucent cells show seams
        for cells, color in ((foliage, "#b6d6c4"), (opaque, "#a8a8a8")):
            if np.any(cells):
                ax.pcolormesh(th, r, np.ma.masked_where(~cells.astype(bool), np.ones(cells.shape)),
                              cmap=ListedColormap([color]), shading="flat", lw=0, edgecolors="none",
                              antialiased=False, zorder=0.5)     # under the elevation grid
    out = {"satellites": {}, "skyline": None, "foliage": None, "sky_mask": None, "legend": []}
    # the skylines as lines over the cells (the scene's edge, the tree's outline), shaded when there are no cells
    if foliage_horizon is not None:
        out["foliage"] = outline(foliage_horizon, "#2e8b57", 0.25, "foliage", sky is None)
    if horizon is not None:
        out["skyline"] = outline(horizon, "#404040", 0.45, "buildings", sky is None)
    if sky_mask is not None:
        maz, mel = (np.asarray(x, float) for x in sky_mask)
        th = np.radians(np.append(maz, maz[0] + 360.0))
        out["sky_mask"] = ax.plot(th, 90.0 - np.clip(np.append(mel, mel[0]), 0.0, 90.0), color="#d000d0", lw=1.3,
                                  ls="--")[0]
    if mask_deg:
        th = np.linspace(0, 2 * np.pi, 361)
        ax.plot(th, np.full_like(th, 90.0 - mask_deg), ls="--", color="k", lw=0.7, label=f"mask {mask_deg:g}°")

    for s, a, e, state_name in zip(sv, az, el, st):
        if e < 0:
            continue
        if state_name == "below_mask" or (mask_deg and e < mask_deg):
            state_name = "below_mask"      # not used by the receiver: never drawn as visible or blocked
        elif state_name not in MARKERS:
            raise ValueError(f"plot_skyplot: {s}: state {str(state_name)!r} is not one of {sorted(MARKERS)}")
        marker, ms, filled, _ = MARKERS[state_name]
        color = BELOW_MASK_COLOR if state_name == "below_mask" else SYSTEM_COLORS.get(s[:1], "k")
        th, r = np.radians(a), 90.0 - e
        line = ax.plot(th, r, marker=marker, ms=ms, mew=1.2 if state_name == "below_mask" else 2.0, color=color,
                       mfc=color if filled else "none", ls="none")[0]
        out["satellites"][str(s)] = (state_name, line)
        ax.annotate(s, (th, r), textcoords="offset points", xytext=(7, 5), fontsize=7,
                    color="0.4" if state_name in ("blocked", "below_mask") else "k")

    systems = sorted({s[:1] for s in sv})
    handles = [Line2D([], [], marker="o", ls="none", color=SYSTEM_COLORS.get(k, "k"), label=SYSTEM_NAMES.get(k, k))
               for k in systems]
    drawn = {state_name for state_name, _ in out["satellites"].values()}
    for name, (marker, _, filled, label) in MARKERS.items():
        if name in ("visible", "attenuated", "blocked") or name in drawn:
            color = BELOW_MASK_COLOR if name == "below_mask" else "k"
            handles.append(Line2D([], [], marker=marker, ls="none", color=color, mfc=color if filled else "none",
                                  label=label))
    if out["skyline"] is not None:
        handles.append(Line2D([], [], color=out["skyline"].get_color(), label="skyline"))
    if out["foliage"] is not None:
        handles.append(Line2D([], [], color=out["foliage"].get_color(), label="foliage"))
    if out["sky_mask"] is not None:
        handles.append(Line2D([], [], color=out["sky_mask"].get_color(), ls="--", label="measured mask"))
    leg = ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.04), ncol=5, fontsize=8,
                    frameon=False)
    out["legend"] = [t.get_text() for t in leg.get_texts()]
    if title:
        ax.set_title(title, fontsize=10, pad=18)
    save_figure(fig, png_path)
    return out
