"""A measured sky mask: the elevation of the horizon per azimuth at one point, as surveyors and the urban GNSS
literature publish it (a fisheye photo or a theodolite sweep turned into elevation per azimuth).

- :func:`read_sky_mask`: the CSV (header ``azimuth_deg,elevation_deg``, other columns ignored, so the
  ``skyline.csv`` of ``gnss-sim skyplot`` is a mask too; ``#`` comments and blank lines skipped); azimuth in
  [0, 360) from north clockwise, elevation in [-90, 90], one row per azimuth (a repeated azimuth is an error);
  every bad row is a ValueError naming the file and line.
- :class:`SkyMask`: the elevation at any azimuth, linear between the rows and periodic in azimuth (the last
  row joins the first across north).
- :func:`compare_skylines`: a measured mask against the model's skyline (``Scene.horizon_profile``) at the same
  azimuths: the difference model - mask per azimuth sector, the Pearson correlation r over all azimuths and the
  largest misses (the urban GNSS papers compare a 3D model with a measured mask by r and the worst sectors).
- :class:`SkyMaskScene`: the mask as the scene of a static antenna when no 3D model exists: the same
  ``visibility_ecef`` as ``core.scene.visibility.Scene`` (what ``VisibilityOptions.cast`` calls), vectorised,
  no ray cast: a satellite under the mask's elevation at its azimuth is BLOCKED, at or above it VISIBLE.
  Its world frame is ENU at the antenna (``spherical`` at the mask's point), so the offline loop places a
  geodetic or ECEF static antenna in it as in any georeferenced world.  A mask has no surfaces: it gives no
  reflections, no soft edges and no foliage (``visibility_ecef`` refuses ``fresnel_rays`` > 0).
- :func:`mask_scene`: the scene of the visibility parameter ``sky_mask_csv`` at a static antenna, the one
  constructor the visibility node and the offline loop (``gnss-sim simulate``) call, with
  :func:`check_mask_options` refusing the cast options a mask cannot serve (reflections, soft edges).
"""
from __future__ import annotations

import csv
import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import frames
from ..input_file import read_utf8
from ..scene.georeference import SphericalCoordinates
from ..vocabulary import VisibilityState

#: the columns a sky mask CSV must have
MASK_COLUMNS = ("azimuth_deg", "elevation_deg")


@dataclass(frozen=True)
class SkyMask:
    """Elevation of the horizon [deg] at azimuths [deg] (sorted, in [0, 360)); ``source`` names the file."""

    az_deg: np.ndarray
    el_deg: np.ndarray
    source: str = "sky mask"

    def elevation_at(self, az_deg) -> np.ndarray:
        """The mask's elevation [deg] at ``az_deg`` (any shape): linear between rows, periodic over 360 deg."""
        az = np.mod(np.asarray(az_deg, dtype=np.float64), 360.0)
        if len(self.az_deg) == 1:
            return np.full(az.shape, float(self.el_deg[0]))
        return np.interp(az, self.az_deg, self.el_deg, period=360.0)

    def blocked(self, az_deg, el_deg) -> np.ndarray:
        """True where a direction is under the mask (elevation below the mask's at its azimuth)."""
        return np.asarray(el_deg, dtype=np.float64) < self.elevation_at(az_deg)


def read_sky_mask(path) -> SkyMask:
    """Read a sky mask CSV (module docstring); ValueError naming the file and line of a bad row."""
    path = Path(path)
    try:
        text = read_utf8(path, f"sky mask {path}")
    except OSError as exc:
        raise ValueError(f"sky mask {path}: cannot read it ({exc.strerror or exc})") from exc
    rows = [(i, line) for i, line in enumerate(text.splitlines(), start=1)
            if line.strip() and not line.lstrip().startswith("#")]
    if not rows:
        raise ValueError(f"sky mask {path}: empty (a header azimuth_deg,elevation_deg and one row per azimuth)")
    head_no, head = rows[0]
    header = [h.strip() for h in next(csv.reader([head]))]
    missing = [c for c in MASK_COLUMNS if c not in header]
    if missing:
        raise ValueError(f"sky mask {path}:{head_no}: header {','.join(header)!r} lacks {', '.join(missing)} "
                         f"(columns {','.join(MASK_COLUMNS)} needed)")
    ia, ie = header.index("azimuth_deg"), header.index("elevation_deg")
    az, el, lines = [], [], []
    for no, line in rows[1:]:
        cells = next(csv.reader([line]))
        if len(cells) <= max(ia, ie):
            raise ValueError(f"sky mask {path}:{no}: {len(cells)} columns, the header has {len(header)}")
        try:
            a, e = float(cells[ia]), float(cells[ie])
        except ValueError:
            raise ValueError(f"sky mask {path}:{no}: azimuth_deg {cells[ia].strip()!r} and elevation_deg "
                             f"{cells[ie].strip()!r} must be numbers") from None
        if not (np.isfinite(a) and 0.0 <= a < 360.0):
            raise ValueError(f"sky mask {path}:{no}: azimuth_deg {cells[ia].strip()} is outside [0, 360)")
        if not (np.isfinite(e) and -90.0 <= e <= 90.0):
            raise ValueError(f"sky mask {path}:{no}: elevation_deg {cells[ie].strip()} is outside [-90, 90]")
        az.append(a)
        el.append(e)
        lines.append(no)
    if not az:
        raise ValueError(f"sky mask {path}: no row after the header")
    az_a, el_a, lines_a = np.array(az), np.array(el), np.array(lines)
    order = np.argsort(az_a, kind="stable")
    az_a, el_a, lines_a = az_a[order], el_a[order], lines_a[order]
    dup = np.flatnonzero(np.diff(az_a) == 0.0)
    if len(dup):
        i = int(dup[0])
        raise ValueError(f"sky mask {path}:{lines_a[i + 1]}: azimuth_deg {az_a[i]:g} is given twice (also line "
                         f"{lines_a[i]}): one elevation per azimuth")
    return SkyMask(az_a, el_a, str(path))


@dataclass(frozen=True)
class SkylineComparison:
    """A measured mask against the model's skyline at the same azimuths (``diff_deg`` = model - mask)."""

    az_deg: np.ndarray
    model_el_deg: np.ndarray
    mask_el_deg: np.ndarray
    diff_deg: np.ndarray
    #: Pearson correlation of the two skylines over all azimuths (NaN when one of them is flat)
    r: float
    rms_deg: float
    mean_deg: float
    #: one row per sector: (az_from_deg, az_to_deg, mean_diff_deg, rms_diff_deg, miss_deg, miss_az_deg), miss =
    #: the difference of largest magnitude in the sector (signed: > 0 where the model is higher than the mask)
    sectors: list

    def largest_misses(self, n: int = 3) -> list:
        """The ``n`` sectors of largest |miss|, largest first."""
        return sorted(self.sectors, key=lambda s: -abs(s[4]))[:n]


def sector_count(sector_deg: float, where: str = "sector_deg") -> int:
    """How many sectors of ``sector_deg`` make 360 deg; ValueError naming ``where`` unless a whole number."""
    n = 360.0 / sector_deg if np.isfinite(sector_deg) and sector_deg > 0 else 0.0
    if not (n >= 1 and abs(n - round(n)) < 1e-9):
        raise ValueError(f"{where} {sector_deg!r}: must divide 360 deg into whole sectors (e.g. 10, 30, 45)")
    return int(round(n))


def compare_skylines(az_deg, model_el_deg, mask: SkyMask, sector_deg: float = 30.0) -> SkylineComparison:
    """The model's skyline (``az_deg``, ``model_el_deg``, e.g. ``Scene.horizon_profile``) against ``mask``
    interpolated at the same azimuths, per sector of ``sector_deg`` (360 / sector_deg must be whole)."""
    n_sec = sector_count(sector_deg)
    az = np.mod(np.asarray(az_deg, dtype=np.float64), 360.0)
    model = np.asarray(model_el_deg, dtype=np.float64)
    if az.shape != model.shape or az.ndim != 1 or len(az) < 2:
        raise ValueError("compare_skylines: az_deg and model_el_deg must be two 1-D arrays of the same length >= 2")
    ref = mask.elevation_at(az)
    diff = model - ref
    flat = np.std(model) == 0 or np.std(ref) == 0
    r = float("nan") if flat else float(np.corrcoef(model, ref)[0, 1])
    sectors = []
    for k in range(n_sec):
        lo, hi = k * sector_deg, (k + 1) * sector_deg
        sel = np.flatnonzero((az >= lo) & (az < hi))
        if len(sel) == 0:
            continue
        d = diff[sel]
        j = int(np.argmax(np.abs(d)))
        sectors.append((lo, hi, float(np.mean(d)), float(np.sqrt(np.mean(d * d))), float(d[j]), float(az[sel[j]])))
    return SkylineComparison(az, model, ref, diff, r, float(np.sqrt(np.mean(diff * diff))), float(np.mean(diff)),
                             sectors)


class SkyMaskScene:
    """A sky mask as the scene of a static antenna (module docstring): world frame = ENU at ``origin``."""

    #: nothing penetrable in a mask (Scene.has_foliage)
    has_foliage = False

    def __init__(self, mask: SkyMask, origin_geodetic):
        lat, lon, h = (float(v) for v in origin_geodetic)
        self.mask = mask
        self.spherical = SphericalCoordinates(lat, lon, h)

    @classmethod
    def at_ecef(cls, mask: SkyMask, antenna_ecef_m) -> SkyMaskScene:
        """The mask measured at the antenna ``antenna_ecef_m`` (3,)."""
        x, y, z = (float(v) for v in np.asarray(antenna_ecef_m, dtype=np.float64).reshape(3))
        return cls(mask, frames.ecef_to_geodetic(x, y, z))

    def antenna_ecef(self, antenna_world_m) -> np.ndarray:
        return self.spherical.world_to_ecef(antenna_world_m)

    def sky_grid(self, antenna_world_m, az_step_deg: float = 2.0, el_step_deg: float = 1.0, **_unused):
        """Like ``Scene.sky_grid`` (the visibility node's sky view): (az_edges_deg, el_edges_deg, opaque (A, E),
        foliage (A, E)), a cell opaque where its centre is under the mask."""
        if not (az_step_deg > 0 and el_step_deg > 0):
            raise ValueError(f"sky_grid: az_step_deg and el_step_deg must be > 0, got {az_step_deg}, {el_step_deg}")
        az_e = np.arange(0.0, 360.0 + 1e-9, az_step_deg)
        el_e = np.arange(0.0, 90.0 + 1e-9, el_step_deg)
        if el_e[-1] < 90.0:
            el_e = np.append(el_e, 90.0)
        az_c, el_c = np.meshgrid(0.5 * (az_e[:-1] + az_e[1:]), 0.5 * (el_e[:-1] + el_e[1:]), indexing="ij")
        opaque = self.mask.blocked(az_c, el_c)
        return az_e, el_e, opaque, np.zeros_like(opaque)

    def visibility_ecef(self, antenna_world_m, sat_ecef_m, *, mask_deg: float = 0.0, fresnel_rays: int = 0,
                        foliage: str = "path", **_unused):
        """Like ``Scene.visibility_ecef``: a VisibilityResult for satellites (N, 3) or (M, N, 3) seen from the
        antenna(s) (3,) or (M, 3); state -1 below ``mask_deg``, BLOCKED under the sky mask, else VISIBLE."""
        from ..scene.visibility import STATE_BELOW_MASK, VisibilityResult

        if int(fresnel_rays) > 0:
            raise ValueError(f"{self.mask.source}: a sky mask has no edges to diffract over: fresnel_rays must be 0 "
                             f"(got {fresnel_rays})")
        rx = self.antenna_ecef(np.asarray(antenna_world_m, dtype=np.float64))
        sat = np.asarray(sat_ecef_m, dtype=np.float64)
        az, el, _ = frames.az_el_from_ecef(rx if rx.ndim == 1 else rx[:, None, :], sat)
        state = np.where(self.mask.blocked(az, el), int(VisibilityState.BLOCKED), int(VisibilityState.VISIBLE))
        state = np.where(el < mask_deg, STATE_BELOW_MASK, state).astype(np.int8)
        zero = np.zeros(state.shape)
        return VisibilityResult(state=state, attenuation_db=zero, path_in_foliage_m=zero.copy(),
                                extra_path_m=zero.copy(), fraction_blocked=(state == int(VisibilityState.BLOCKED))
                                .astype(float), diffraction_db=zero.copy(), az_deg=az, el_deg=el)


def mask_scene(csv_path, antenna_ecef_m) -> SkyMaskScene:
    """The scene of the visibility parameter ``sky_mask_csv``: the mask ``csv_path`` (read_sky_mask: errors name
    the file and line) measured at the static antenna ``antenna_ecef_m`` (3,)."""
    return SkyMaskScene.at_ecef(read_sky_mask(csv_path), antenna_ecef_m)


def check_mask_options(options, where: str):
    """The cast ``options`` (VisibilityOptions) for a mask scene: multipath ``auto`` (the scene decides) is off, as
    a mask has no walls; ValueError naming ``where`` when they ask for what a mask has not: reflections
    (``multipath`` nlos or full) or soft edges (``fresnel_rays`` > 0)."""
    if options.multipath == "auto":
        options = dataclasses.replace(options, multipath="off")
    if options.multipath != "off" or options.fresnel_rays > 0:
        raise ValueError(f"{where}: a sky mask (parameter 'sky_mask_csv') has no surfaces to reflect from or "
                         f"diffract over, but multipath {options.multipath!r} and fresnel_rays "
                         f"{options.fresnel_rays} (from the preset or the parameters): use preset fast or "
                         f"balanced, or multipath: off and fresnel_rays: 0")
    return options


def static_antenna_ecef(antenna_position, position_type: str, trajectory=None, where: str = "sky_mask_csv"):
    """(trajectory, antenna ECEF (3,)) of a mask scene: ``trajectory`` (core.trajectory.Trajectory) if given, else
    the static ``antenna_position`` in ``position_type`` (llh or ecef: the visibility parameters); ValueError
    naming ``where`` unless that is one static geodetic or ECEF point (a mask is measured at one point)."""
    from ..trajectory import Trajectory

    if trajectory is None and len(antenna_position) and position_type != "world":
        frame = "geodetic" if position_type == "llh" else "ecef"
        trajectory = Trajectory.static(antenna_position, frame, "parameter 'antenna_position'")
    if trajectory is None or not trajectory.is_static or trajectory.frame == "world":
        raise ValueError(f"{where}: a sky mask is measured at one point: give a static antenna (parameter "
                         f"antenna_position with antenna_position_type llh or ecef, or `gnss-sim simulate --position "
                         f"LAT,LON,H | --position-ecef X,Y,Z`), not a path or world coordinates")
    pos = np.asarray(trajectory.pos[0], dtype=np.float64)
    ecef = pos if trajectory.frame == "ecef" else np.array(frames.geodetic_to_ecef(*pos))
    return trajectory, ecef
