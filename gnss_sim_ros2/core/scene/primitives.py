"""SDF shape geometry as triangle meshes (trimesh), in the frame of the collision/visual.

Shapes follow the SDF specification (sdformat.org, geometry.sdf, SDF 1.11) and gz-common's
MeshManager for where each is centred: box, sphere, cylinder (axis z, centred), cone (axis z, base at
-length/2, apex at +length/2), capsule (cylinder of ``length`` plus two half spheres), ellipsoid
(``radii``), plane (a finite patch of ``size`` normal to ``normal``), polylines (the ``<polyline>``
elements of one geometry extruded from z = 0 to ``<height>``, inner ones cut as holes, caps by
mapbox-earcut) and heightmap (a grid of ``size`` centred at ``pos``, row 0 of the image at +y as
gz-common's ImageHeightmap with flipY; an 8-bit or 16-bit image gives its first channel over the
type's maximum times ``size`` z; a single-band float raster (a DEM GeoTIFF that Pillow opens) gives
heights in metres above its lowest sample, placed with ``size`` x/y, which is then required).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .sdf_xml import SdfError, child, child_floats, children, floats, where

SPHERE_SUBDIVISIONS = 3      # icosphere: 1280 triangles
CYLINDER_SECTIONS = 32
#: heightmaps larger than this many samples per side are subsampled (a 4097^2 DEM would be 33 M triangles)
HEIGHTMAP_MAX_SAMPLES = 513


def _trimesh():
    import trimesh

    return trimesh


def box(s, file):
    size = child_floats(s, "size", file, 3, default=(1, 1, 1))
    if min(size) <= 0:
        raise SdfError(f"{where(s, file)}: box <size> must be positive, got {size}")
    return _trimesh().creation.box(extents=size)


def sphere(s, file):
    (r,) = child_floats(s, "radius", file, 1, default=(1,))
    _positive(s, file, radius=r)
    return _trimesh().creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=r)


def cylinder(s, file):
    (r,) = child_floats(s, "radius", file, 1, default=(1,))
    (ln,) = child_floats(s, "length", file, 1, default=(1,))
    _positive(s, file, radius=r, length=ln)
    return _trimesh().creation.cylinder(radius=r, height=ln, sections=CYLINDER_SECTIONS)


def cone(s, file):
    (r,) = child_floats(s, "radius", file, 1, default=(1,))
    (ln,) = child_floats(s, "length", file, 1, default=(1,))
    _positive(s, file, radius=r, length=ln)
    m = _trimesh().creation.cone(radius=r, height=ln, sections=CYLINDER_SECTIONS)
    m.apply_translation((0.0, 0.0, -ln / 2.0))        # trimesh: base at z = 0; gz: centred
    return m


def capsule(s, file):
    (r,) = child_floats(s, "radius", file, 1, default=(0.5,))
    (ln,) = child_floats(s, "length", file, 1, default=(1,))
    _positive(s, file, radius=r)
    return _trimesh().creation.capsule(height=ln, radius=r, count=[CYLINDER_SECTIONS, CYLINDER_SECTIONS])


def ellipsoid(s, file):
    radii = child_floats(s, "radii", file, 3, default=(1, 1, 1))
    _positive(s, file, radii=min(radii))
    m = _trimesh().creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=1.0)
    m.apply_scale(radii)
    return m


def plane(s, file):
    nrm = np.asarray(child_floats(s, "normal", file, 3, default=(0, 0, 1)), dtype=np.float64)
    size = child_floats(s, "size", file, 2, default=(1, 1))
    if np.linalg.norm(nrm) == 0 or min(size) <= 0:
        raise SdfError(f"{where(s, file)}: plane needs a non-zero <normal> and positive <size>")
    nrm = nrm / np.linalg.norm(nrm)
    if np.allclose(nrm, [0, 0, 1]):
        ex, ey = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    else:
        helper = np.array([1.0, 0.0, 0.0]) if abs(nrm[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        ex = np.cross(helper, nrm)
        ex /= np.linalg.norm(ex)
        ey = np.cross(nrm, ex)
    hx, hy = size[0] / 2.0, size[1] / 2.0
    v = np.array([-hx * ex - hy * ey, hx * ex - hy * ey, hx * ex + hy * ey, -hx * ex + hy * ey])
    return _trimesh().Trimesh(v, np.array([[0, 1, 2], [0, 2, 3]]), process=False)


def polylines(els, file):
    """The ``<polyline>`` elements of one ``<geometry>`` as one closed extruded solid (gz-common
    ``CreateExtrudedPolyline``): a polyline inside another is a hole (even-odd nesting), caps by earcut;
    extruded from z = 0 to the first polyline's ``<height>``."""
    h = child_floats(els[0], "height", file, 1, default=(1,))[0]
    _positive(els[0], file, height=h)
    loops = []
    for el in els:
        pts = np.array([floats(p, file, 2, "polyline <point>") for p in children(el, "point")], dtype=np.float64)
        if len(pts) > 2 and np.allclose(pts[0], pts[-1]):
            pts = pts[:-1]
        if len(pts) < 3 or abs(_area2(pts)) < 1e-12:
            raise SdfError(f"{where(el, file)}: polyline needs at least 3 <point> enclosing an area")
        loops.append(pts)
    inside = [[j for j in range(len(loops)) if j != i and _point_in(loops[i][0], loops[j])] for i in range(len(loops))]
    verts, faces, n = [], [], 0
    for i, outer in enumerate(loops):
        if len(inside[i]) % 2:
            continue                                               # a hole: cut from its parent below
        holes = [loops[k] for k in range(len(loops)) if len(inside[k]) == len(inside[i]) + 1 and i in inside[k]]
        rings = [outer if _area2(outer) > 0 else outer[::-1]] + [hl if _area2(hl) < 0 else hl[::-1] for hl in holes]
        v, f = _prism(rings, h)
        verts.append(v)
        faces.append(f + n)
        n += len(v)
    return _trimesh().Trimesh(np.vstack(verts), np.vstack(faces), process=False)


def _area2(pts) -> float:
    return float(np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1]))


def _point_in(p, poly) -> bool:
    """Even-odd rule (ray to +x)."""
    x, y = poly[:, 0], poly[:, 1]
    x2, y2 = np.roll(x, -1), np.roll(y, -1)
    cross = (y > p[1]) != (y2 > p[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = x + (p[1] - y) * (x2 - x) / (y2 - y)
    return bool(np.count_nonzero(cross & (p[0] < xi)) % 2)


def _prism(rings, height: float):
    """Rings (outer counter-clockwise, holes clockwise) extruded from z = 0 to ``height``."""
    import mapbox_earcut

    pts = np.vstack(rings)
    ends = np.cumsum([len(r) for r in rings]).astype(np.uint32)
    tri = np.asarray(mapbox_earcut.triangulate_float64(pts, ends), dtype=np.int64).reshape(-1, 3)
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    ccw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) > 0
    tri = np.where(ccw[:, None], tri, tri[:, ::-1])
    n = len(pts)
    verts = np.vstack([np.c_[pts, np.zeros(n)], np.c_[pts, np.full(n, height)]])
    faces = [tri[:, ::-1], tri + n]
    start = 0
    for r in rings:
        i = np.arange(start, start + len(r))
        j = np.roll(i, -1)
        faces.append(np.c_[i, j, j + n])
        faces.append(np.c_[i, j + n, i + n])
        start += len(r)
    return verts, np.vstack(faces)


def _positive(s, file, **values):
    for k, v in values.items():
        if not v > 0:
            raise SdfError(f"{where(s, file)}: {k} must be positive, got {v}")


def heightmap_grid(heights_m: np.ndarray, size_xy, pos):
    """Triangles of a height grid (rows = image rows, row 0 at +y) of ``size_xy`` centred at ``pos``."""
    h = np.asarray(heights_m, dtype=np.float64)[::-1]            # row 0 of the image at +y
    ny, nx = h.shape
    xs = np.linspace(-size_xy[0] / 2.0, size_xy[0] / 2.0, nx) + pos[0]
    ys = np.linspace(-size_xy[1] / 2.0, size_xy[1] / 2.0, ny) + pos[1]
    X, Y = np.meshgrid(xs, ys)
    verts = np.c_[X.ravel(), Y.ravel(), h.ravel() + pos[2]]
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = np.vstack([np.c_[a, b, c], np.c_[a, c, d]])
    return _trimesh().Trimesh(verts, faces, process=False)


def heightmap(s, file, resolve):
    """``<heightmap>`` -> grid mesh; ``resolve(uri_el)`` gives the image path."""
    from PIL import Image

    uri_el = child(s, "uri")
    if uri_el is None:
        raise SdfError(f"{where(s, file)}: <heightmap> without <uri>")
    path = Path(resolve(uri_el))
    try:
        img = Image.open(path)
        img.load()
    except Exception as exc:  # noqa: BLE001 - Pillow raises many kinds for unknown rasters
        raise SdfError(f"{where(uri_el, file)}: heightmap {path.name}: raster format not supported (Pillow cannot "
                       f"read it: {type(exc).__name__}: {exc}); convert it to a 16-bit PNG") from exc
    pos = child_floats(s, "pos", file, 3, default=(0, 0, 0))
    size_el = child(s, "size")
    if img.mode in ("F", "I", "I;16", "I;16B", "I;16L") and path.suffix.lower() not in (".png",):
        if size_el is None:
            raise SdfError(f"{where(s, file)}: DEM {path.name}: the georeferenced extent is not read; give <size>")
        vals = np.asarray(img, dtype=np.float64)
        vals = np.where(np.isfinite(vals) & (vals > -1e4), vals, np.nan)
        if not np.isfinite(vals).any():
            raise SdfError(f"{where(s, file)}: DEM {path.name} holds no valid height")
        heights = np.nan_to_num(vals - np.nanmin(vals), nan=0.0)
        size = floats(size_el, file, 3)
    else:
        size = child_floats(s, "size", file, 3, default=(1, 1, 1))
        if img.mode in ("I;16", "I;16B", "I;16L", "I"):
            arr, full = np.asarray(img, dtype=np.float64), 65535.0
        elif img.mode in ("L", "LA", "RGB", "RGBA"):
            arr, full = np.asarray(img.getchannel(0), dtype=np.float64), 255.0   # gz-common: the first channel
        else:
            arr, full = np.asarray(img.convert("L"), dtype=np.float64), 255.0
        heights = arr / full * size[2]
    if min(size[:2]) <= 0:
        raise SdfError(f"{where(s, file)}: heightmap <size> x and y must be positive, got {size}")
    step = max(1, int(np.ceil(max(heights.shape) / HEIGHTMAP_MAX_SAMPLES)))
    if step > 1:
        heights = heights[::step, ::step]
    return heightmap_grid(heights, size[:2], pos)
