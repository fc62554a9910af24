"""What a calibration reads: a real observation file over a span, its broadcast navigation data and the antenna
position or path, turned into observations with the elevation of every (epoch, satellite).

The observations come from the project's one RINEX reader (core/rinex/obs_read.load_rinex: plain, gzip, Hatanaka),
the satellite positions from the broadcast ephemeris (core/ephemeris, as ``gnss-sim compare --nav`` and
``simulate --nav`` build it).  Antenna: a static ECEF point (default: the header's APPROX POSITION XYZ plus its
ANTENNA: DELTA H/E/N, RINEX 3.05 table A2: the antenna reference point) or a path (a trajectory CSV as
``gnss-sim simulate --trajectory`` reads it, ``t_s`` from the span's start).
"""
from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..ephemeris.broadcast import BroadcastEphemeris
from ..frames import az_el_from_ecef, check_receiver_position, ecef_to_geodetic, enu_to_ecef, geodetic_to_ecef
from ..rinex.header import parse_obs_header
from ..rinex.obs_read import load_rinex
from ..rinex.obs_table import GPS_EPOCH_NP, ObsTable
from ..time import GnssTime
from ..trajectory import Trajectory

#: systems the calibration describes (the simulator's; SBAS is left out)
CALIBRATED_SYSTEMS = "GRECJI"


@dataclass
class Recording:
    """A real recording over the chosen span, with elevations."""

    table: ObsTable              #: observations over the span
    header: dict                 #: core/rinex/header.parse_obs_header fields
    el_deg: np.ndarray           #: (E, S) elevation [deg] of each satellite at the antenna, NaN without a record
    interval_s: float            #: epoch interval (header INTERVAL, else the median step)
    antenna: str                 #: how the antenna position was given (for the report)
    path: str                    #: the observation file
    #: (E, S) bool: the scene leaves the satellite in the line of sight (None: no scene, every sample counts)
    los: np.ndarray | None = None
    scene: str = ""              #: the scene that selected ``los`` (for the report)
    #: (E, 3) the antenna placed in the scene's world frame (NaN where unknown; None: no scene)
    antenna_world_m: np.ndarray | None = None

    @property
    def span(self) -> tuple[str, str]:
        """First and last epoch, ISO (GPS time)."""
        t = self.table.time
        return (str(t[0])[:19], str(t[-1])[:19]) if len(t) else ("", "")


def gnss_times(times: np.ndarray) -> GnssTime:
    """(N,) datetime64 GPS time labels -> GnssTime array."""
    ns = ((np.asarray(times).astype("datetime64[ns]") - GPS_EPOCH_NP) / np.timedelta64(1, "ns")).astype(np.int64)
    return GnssTime(ns // 1_000_000_000, (ns % 1_000_000_000) * 1e-9)


def elevations_deg(eph, times: np.ndarray, svs: np.ndarray, rx_ecef_m: np.ndarray, present=None,
                   sat_out: np.ndarray | None = None) -> np.ndarray:
    """(E, S) elevation [deg] of satellites ``svs`` at ``times`` seen from ``rx_ecef_m`` ((3,) or (E, 3)), from
    the ephemeris provider ``eph`` (one vectorised ``states_at`` call); NaN without a healthy record, outside
    the provider's systems or where ``present`` ((E, S) bool, optional) is False.  ``sat_out``: an (E, S, 3)
    array that receives the satellites' ECEF positions [m] where the elevation is known."""
    n_e, n_s = len(times), len(svs)
    el = np.full((n_e, n_s), np.nan)
    rx = np.broadcast_to(np.asarray(rx_ecef_m, float).reshape(-1, 3), (n_e, 3)) if n_e else np.zeros((0, 3))
    want = np.isin(np.array([s[:1] for s in np.asarray(svs).tolist()]), list(CALIBRATED_SYSTEMS))[None, :] \
        & np.all(np.isfinite(rx), axis=1)[:, None]
    if present is not None:
        want &= present
    ie, js = np.nonzero(want)
    if not len(ie):
        return el
    t = gnss_times(np.asarray(times)[ie])
    st = eph.states_at(np.asarray(svs)[js], t)
    if not len(st.sv):
        return el
    # states_at keeps the input order, leaving out rows without a record: match them by (sv, time)
    key_in = np.char.add(np.asarray(svs)[js].astype("<U3"), (t.sec * 1000 + np.round(t.frac * 1000)).astype(str))
    key_out = np.char.add(np.asarray(st.sv).astype("<U3"),
                          (np.asarray(st.t.sec) * 1000 + np.round(np.asarray(st.t.frac) * 1000)).astype(str))
    pos = {k_: i for i, k_ in enumerate(key_out.tolist())}
    rows = np.array([pos.get(k_, -1) for k_ in key_in.tolist()])
    ok = rows >= 0
    _, e, _ = az_el_from_ecef(rx[ie[ok]], st.pos_ecef_m[rows[ok]])
    el[ie[ok], js[ok]] = e
    if sat_out is not None:
        sat_out[ie[ok], js[ok]] = st.pos_ecef_m[rows[ok]]
    return el


def parse_start(start_iso: str | None, duration_s: float | None) -> np.datetime64 | None:
    """GPS time of ``--start`` (None when not given), ``--duration`` checked; ValueError naming the option."""
    lo = None
    if start_iso is not None:
        try:
            lo = np.datetime64(str(start_iso).rstrip("Z"), "ns")
        except ValueError:
            raise ValueError(f"option --start: {start_iso!r} is not an ISO 8601 time (e.g. 2020-06-25T12:00:00)") \
                from None
    if duration_s is not None:
        if not np.isfinite(duration_s) or duration_s <= 0:
            raise ValueError(f"option --duration: {duration_s!r} must be a positive number of seconds")
    return lo


def antenna_from_header(hdr: dict, path) -> np.ndarray:
    """APPROX POSITION XYZ + ANTENNA: DELTA H/E/N (up, east, north at the marker) [m, ECEF]."""
    if hdr["approx"] is None:
        raise ValueError(f"{path}: no APPROX POSITION XYZ in the header: give --position-ecef X,Y,Z or --trajectory")
    pos = np.asarray(hdr["approx"], float)
    d = hdr.get("delta_hen_m")
    if d is not None and np.any(d):
        lat, lon, h = ecef_to_geodetic(*pos)
        pos = enu_to_ecef(np.array([d[1], d[2], d[0]]), lat, lon, h)
    return pos


def read_recording(obs_path, nav_paths, position_ecef_m=None, trajectory_csv=None, start_iso=None,
                   duration_s=None, scene=None, mask_deg: float = 5.0, scene_name: str = "") -> Recording:
    """The recording ``obs_path`` over [``start_iso``, + ``duration_s``] with elevations from ``nav_paths``.

    ``scene`` (core/scene Scene, georeferenced): ``Recording.los`` marks the (epoch, satellite) pairs the scene
    leaves in the line of sight of the antenna above ``mask_deg`` (core/visibility/line_of_sight.py); the path
    may then also be in the scene's world frame (t_s,e_m,n_m,u_m), as ``gnss-sim simulate --trajectory`` places
    it.  Errors (ValueError) name the file or option: missing files, a span without epochs, a bad position."""
    if scene is not None and scene.spherical is None:
        raise ValueError(f"{scene_name or 'the scene'}: no spherical_coordinates (geodetic origin): cannot place "
                         "the antenna in it")
    obs_path = Path(obs_path)
    if not obs_path.is_file():
        raise ValueError(f"--obs {obs_path}: no such file")
    nav_paths = [Path(p) for p in (nav_paths or ())]
    if not nav_paths:
        raise ValueError("--nav: give the broadcast navigation file(s) of the recording")
    for p in nav_paths:
        if not p.is_file():
            raise ValueError(f"--nav {p}: no such file")
    lo = parse_start(start_iso, duration_s)
    tlim = None
    if lo is not None or duration_s is not None:
        from georinex.rio import opener  # the header only, to know the first epoch when --start is not given

        if lo is None:
            with opener(obs_path) as f:
                first = parse_obs_header(io.StringIO("".join(f.readline() for _ in range(400))), obs_path)
            lo = first["first_obs"]
            if lo is None:
                raise ValueError(f"{obs_path}: no TIME OF FIRST OBS in the header: give --start with --duration")
            lo = np.datetime64(lo, "ns")
        hi = lo + np.timedelta64(int(round(duration_s * 1e9)), "ns") if duration_s is not None \
            else np.datetime64("2200-01-01", "ns")
        # --duration S covers [start, start + S): the last epoch before the end
        tlim = (lo, hi - np.timedelta64(1, "ns"))
    tab = load_rinex(obs_path, tlim)
    from georinex.rio import opener

    with opener(obs_path) as f:
        hdr = parse_obs_header(f, obs_path)
    if not len(tab.time):
        span = "" if tlim is None else f" between {str(tlim[0])[:19]} and {str(tlim[1])[:19]} GPS"
        raise ValueError(f"--obs {obs_path}: no observation epochs{span}")
    interval = hdr.get("interval_s")
    if not interval or interval <= 0:
        steps = np.diff(tab.time).astype("timedelta64[ns]").astype(np.int64) / 1e9
        interval = float(np.median(steps)) if steps.size else 1.0

    if position_ecef_m is not None and trajectory_csv is not None:
        raise ValueError("give either --position-ecef or --trajectory, not both")
    t0 = tab.time[0]
    if trajectory_csv is not None:
        tr = Trajectory.from_csv(trajectory_csv)
        if tr.frame == "world" and scene is None:
            raise ValueError(f"--trajectory {trajectory_csv}: a world-frame path (e_m,n_m,u_m) needs a scene; "
                             "give t_s,lat_deg,lon_deg,h_m or t_s,x_m,y_m,z_m")
        t_s = (tab.time - t0).astype("timedelta64[ns]").astype(np.int64) / 1e9
        p = tr.position(t_s)
        rx = geodetic_to_ecef_rows(p) if tr.frame == "geodetic" else \
            scene.spherical.world_to_ecef(p) if tr.frame == "world" else p
        outside = (t_s < tr.t_s[0]) | (t_s > tr.t_s[-1])
        rx = np.where(outside[:, None], np.nan, rx)
        if outside.all():
            raise ValueError(f"--trajectory {trajectory_csv}: its times {tr.t_s[0]:g}..{tr.t_s[-1]:g} s (from "
                             f"{str(t0)[:19]} GPS) cover no epoch of --obs {obs_path}")
        antenna = f"path {trajectory_csv} ({int((~outside).sum())} epochs inside it)"
    elif position_ecef_m is not None:
        rx = check_receiver_position(position_ecef_m, "ecef", "option --position-ecef")
        antenna = "static, --position-ecef " + ", ".join(f"{v:.3f}" for v in rx)
    else:
        rx = antenna_from_header(hdr, obs_path)
        check_receiver_position(rx, "ecef", f"{obs_path} APPROX POSITION XYZ")
        antenna = "static, header APPROX POSITION XYZ + ANTENNA: DELTA H/E/N " + ", ".join(f"{v:.3f}" for v in rx)
    ends = gnss_times(tab.time[[0, -1]])
    eph = BroadcastEphemeris.from_files([str(p) for p in nav_paths], start=ends[0] + (-7200.0), end=ends[1] + 7200.0)
    present = np.zeros((len(tab.time), len(tab.sv)), bool)
    for a in tab.values.values():
        present |= np.isfinite(a)
    sat = np.full(present.shape + (3,), np.nan) if scene is not None else None
    el = elevations_deg(eph, tab.time, tab.sv, rx, present, sat)
    if not np.isfinite(el).any():
        raise ValueError(f"--nav {', '.join(map(str, nav_paths))}: no satellite of --obs {obs_path} has a healthy "
                         "broadcast record over the span (wrong day or navigation file?)")
    rec = Recording(tab, hdr, el, float(interval), antenna, str(obs_path))
    if scene is not None:
        from ..visibility.line_of_sight import line_of_sight_epochs

        rx_e = np.broadcast_to(np.asarray(rx, float).reshape(-1, 3), (len(tab.time), 3))
        world = np.full(rx_e.shape, np.nan)
        fin = np.all(np.isfinite(rx_e), axis=1)
        world[fin] = scene.spherical.ecef_to_world(rx_e[fin])
        rec.los = line_of_sight_epochs(scene, world, sat, mask_deg)
        rec.scene, rec.antenna_world_m = scene_name, world
    return rec


def geodetic_to_ecef_rows(llh: np.ndarray) -> np.ndarray:
    """(N, 3) lat_deg, lon_deg, h_m -> (N, 3) ECEF [m]."""
    x, y, z = geodetic_to_ecef(llh[:, 0], llh[:, 1], llh[:, 2])
    return np.stack([x, y, z], axis=-1)
