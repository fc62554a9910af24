"""The threat timeline of a run: C/N0 per band, satellites tracked and used, the fix's horizontal error and the
scenario's truth labels over time, from what a run writes (``fix.csv`` with its ``active_events`` column and the
RINEX observation file) and the antenna's true path (``gnss-sim threats-plot``, docs/SCENARIOS.md)."""
from __future__ import annotations

import csv
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..figures import pyplot, save_figure
from ..frames import geodetic_to_ecef
from ..metrics import horizontal_errors_m
from ..rinex.obs_read import load_rinex
from ..time import GnssTime


@dataclass
class Timeline:
    """Per epoch of ``fix.csv`` (E,): seconds after the first epoch, satellites used, fix or not, the active events,
    the horizontal error [m] (NaN without a fix or a truth); per epoch of the RINEX file: satellites tracked and
    the median C/N0 of the tracked signals per band (RINEX band digit)."""

    t_s: np.ndarray
    n_used: np.ndarray
    is_fix: np.ndarray
    active: list
    h_err_m: np.ndarray
    obs_t_s: np.ndarray
    n_tracked: np.ndarray
    cn0_dbhz: dict
    #: per epoch of fix.csv: satellites a spoofer has captured, i.e. tracked on at least one counterfeit signal (its
    #: ``spoofed`` column; a subset of the tracked satellites, counted like ``n_tracked``; None without a spoofer)
    n_spoofed: np.ndarray | None = None

    @property
    def events(self) -> list[str]:
        """Event names in order of first activity."""
        out: list[str] = []
        for names in self.active:
            out += [n for n in names if n not in out]
        return out

    def event_spans(self, name: str) -> list[tuple[float, float]]:
        """(start, end) [s] of each run of epochs where ``name`` is active (end: the last such epoch + one step)."""
        on = np.array([name in names for names in self.active])
        step = float(np.median(np.diff(self.t_s))) if len(self.t_s) > 1 else 1.0
        edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
        return [(float(self.t_s[a]), float(self.t_s[b - 1]) + step) for a, b in zip(edges[::2], edges[1::2])]


def read_timeline(run_dir, truth=None, spherical=None) -> Timeline:
    """The timeline of a run folder (``fix.csv`` and one ``*_MO.rnx``); ``truth``: the antenna's true path
    (core/trajectory.Trajectory; its time 0 the run's first epoch), ``spherical``: the world's georeference for a
    world-frame path.  ValueError naming the file when something is missing."""
    run_dir = Path(run_dir)
    fix_path = run_dir / "fix.csv"
    if not fix_path.is_file():
        raise ValueError(f"{run_dir}: no fix.csv (a folder of `gnss-sim simulate` or `gnss-sim run`)")
    with open(fix_path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise ValueError(f"{fix_path}: no epochs")
    if "active_events" not in rows[0]:
        raise ValueError(f"{fix_path}: no active_events column: the run had no threat scenario (--scenario)")
    times = [GnssTime.from_iso(r["time"], scale="GPS") for r in rows]
    t_s = np.array([float(t - times[0]) for t in times])
    is_fix = np.array([r["status"] != "no_fix" for r in rows])
    n_used = np.array([int(r["n_sats"] or 0) for r in rows])
    active = [[n for n in r["active_events"].split(";") if n] for r in rows]
    n_spoofed = np.array([len(r["spoofed"].split()) for r in rows]) if "spoofed" in rows[0] else None
    h_err = np.full(len(rows), np.nan)
    if truth is not None:
        est = np.array([geodetic_to_ecef(float(r["lat_deg"] or "nan"), float(r["lon_deg"] or "nan"),
                                         float(r["h_m"] or "nan")) for r in rows])
        h_err = np.where(is_fix, horizontal_errors_m(est, _truth_ecef(truth, t_s, spherical)), np.nan)
    obs_files = sorted(run_dir.glob("*_MO.rnx"))
    if not obs_files:
        raise ValueError(f"{run_dir}: no RINEX observation file (*_MO.rnx)")
    table = load_rinex(obs_files[0])
    t0_np = np.datetime64(times[0].to_datetime("GPS").replace(tzinfo=None), "ns")
    obs_t = (table.time - t0_np) / np.timedelta64(1, "s")
    tracked = np.zeros((len(table.time), len(table.sv)), dtype=bool)
    cn0: dict[str, np.ndarray] = {}
    for band in sorted({c[1] for c in table.values if c[0] == "S"}):
        cols = np.stack([a for c, a in table.values.items() if c[0] == "S" and c[1] == band], axis=0)  # (C, E, S)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)           # an epoch without a signal in the band
            cn0[band] = np.nanmedian(cols.transpose(1, 0, 2).reshape(len(table.time), -1), axis=1)
        tracked |= np.isfinite(cols).any(axis=0)
    return Timeline(t_s, n_used, is_fix, active, h_err, np.asarray(obs_t, dtype=float), tracked.sum(axis=1), cn0,
                    n_spoofed)


def _truth_ecef(truth, t_s, spherical) -> np.ndarray:
    p = np.asarray(truth.position(t_s), dtype=float).reshape(-1, 3)
    if truth.frame == "world":
        if spherical is None:
            raise ValueError("a world-frame true path needs the world's georeference (spherical_coordinates)")
        return spherical.world_to_ecef(p)
    if truth.frame == "geodetic":
        return np.stack(geodetic_to_ecef(p[:, 0], p[:, 1], p[:, 2]), axis=-1)
    return p


BAND_NAMES = {"1": "L1/E1/B1", "2": "L2/B1-2", "5": "L5/E5a", "6": "E6/B3", "7": "E5b/B2", "8": "E5"}


def plot_timeline(tl: Timeline, path, title: str = "") -> Path:
    """Four panels over the run time: C/N0 per band, satellites tracked and used, horizontal error, labels."""
    plt = pyplot()
    fig, ax = plt.subplots(4, 1, figsize=(9.0, 8.0), sharex=True,
                           gridspec_kw={"height_ratios": [3, 2, 2, max(1, len(tl.events))]})
    for band, med in tl.cn0_dbhz.items():
        ax[0].plot(tl.obs_t_s, med, lw=1.2, label=f"band {band} ({BAND_NAMES.get(band, band)})")
    ax[0].set_ylabel("median C/N0\n[dB-Hz]")
    ax[0].legend(loc="lower left", fontsize=8, ncol=3)
    ax[1].plot(tl.obs_t_s, tl.n_tracked, lw=1.2, label="tracked")
    ax[1].plot(tl.t_s, tl.n_used, lw=1.2, label="used in the fix")
    if tl.n_spoofed is not None:
        ax[1].plot(tl.t_s, tl.n_spoofed, lw=1.2, color="tab:red", label="tracked on a spoofer's signal")
    ax[1].set_ylabel("satellites")
    ax[1].legend(loc="upper center", fontsize=8, ncol=3)
    ax[2].plot(tl.t_s, tl.h_err_m, lw=1.2, color="k")
    no_fix = ~tl.is_fix
    if no_fix.any():
        ax[2].plot(tl.t_s[no_fix], np.zeros(int(no_fix.sum())), "|", color="tab:red", ms=10, label="no fix")
        ax[2].legend(loc="upper left", fontsize=8)
    ax[2].set_ylabel("horizontal\nerror [m]")
    for k, name in enumerate(tl.events):
        ax[3].broken_barh([(a, b - a) for a, b in tl.event_spans(name)], (k - 0.4, 0.8), color=f"C{k + 3}")
    ax[3].set_yticks(range(len(tl.events)), tl.events)
    ax[3].set_ylim(-0.6, max(len(tl.events), 1) - 0.4)
    ax[3].set_ylabel("active\n(truth)")
    ax[3].set_xlabel("time after the run start [s]")
    for a in ax:
        a.grid(alpha=0.3)
    if title:
        ax[0].set_title(title)
    return save_figure(fig, path)


def summary(tl: Timeline) -> list[str]:
    """A line per event: its spans and what the receiver did meanwhile (epochs without a fix, worst error)."""
    out = []
    for name in tl.events:
        on = np.array([name in names for names in tl.active])
        err = tl.h_err_m[on & tl.is_fix]
        worst = f"{np.nanmax(err):.1f} m" if np.isfinite(err).any() else "n/a"
        spans = ", ".join(f"{a:g}-{b:g} s" for a, b in tl.event_spans(name))
        most = int(tl.n_spoofed[on].max()) if tl.n_spoofed is not None else 0
        captured = f", satellites captured max {most}" if most else ""
        out.append(f"{name}: active {spans}; {int((on & ~tl.is_fix).sum())} of {int(on.sum())} epochs without a "
                   f"fix, satellites used min {int(tl.n_used[on].min())}{captured}, worst horizontal error {worst}")
    return out
