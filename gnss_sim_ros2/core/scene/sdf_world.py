"""Read an SDF world (Gazebo) into one triangle mesh with a material class per triangle.

No libsdformat is usable from Python here, so the XML is parsed with lxml and
the SDF specification (sdformat.org, SDF 1.7-1.11 "pose frame semantics") is
followed for what matters to line-of-sight:

* ``<world>`` -> ``<model>``, ``<include>``, ``<frame>``; models nest; links hold
  ``<collision>`` (or ``<visual>`` with ``use_visuals=True``) with ``<geometry>``.
* ``<pose relative_to="...">x y z roll pitch yaw</pose>``: radians, or degrees
  with ``degrees="true"`` (SDF 1.9+); ``rotation_format="quat_xyzw"`` (7 values)
  too.  Rotation = Rz(yaw) Ry(pitch) Rx(roll) (fixed axes X, then Y, then Z).
  Defaults: a model/link/nested model/include is relative to its parent model
  frame (the world for top-level models); a ``<frame>`` to its
  ``attached_to``; a collision/visual to its link; a joint to its child link.
  ``relative_to`` may name any sibling frame, ``__model__``, ``world`` (at world
  scope) or a nested ``a::b`` name.
* ``<include>``: ``<uri>`` ``model://NAME[/sub/path]`` is searched in the folders
  of ``GZ_SIM_RESOURCE_PATH``, ``IGN_GAZEBO_RESOURCE_PATH``,
  ``GAZEBO_MODEL_PATH`` (colon separated, in that order) and then the folder of
  the including file; a model folder's ``model.config`` names its SDF file
  (``<sdf version=...>``, highest version wins; else ``model.sdf``).  ``<name>``
  and ``<pose>`` of the include override the model's own.  Relative or
  ``file://`` URIs are resolved against the including file's folder.
* Geometry: box, cylinder, sphere, capsule, ellipsoid, plane (a finite patch of
  ``<size>``), polyline (each ``<polyline>`` extruded from z = 0 to ``<height>``;
  holes are not cut), mesh (OBJ, STL, PLY, DAE through trimesh/pycollada, with
  ``<scale>`` and the COLLADA ``<unit meter=...>``).  Heightmaps are skipped with
  a warning.

Georeference (``<spherical_coordinates>``)
-------------------------------------------
``latitude_deg``, ``longitude_deg``, ``elevation`` (WGS 84 ellipsoidal height
[m]) and ``heading_deg`` place the Gazebo world frame.  Only
``world_frame_orientation`` ENU (the default) is accepted.

Heading convention, as gz-math ``SphericalCoordinates`` implements it (the
ECEF -> LOCAL transform used by gz-sim's NavSat sensor): with
h = heading_deg, ``world_xy = Rz(-h) enu_xy``, i.e. ``enu = Rz(+h) world``.
The world +x axis points h degrees counter-clockwise from east (compass
azimuth 90 - h); heading_deg = 90 makes world +x point north and +y west.
z is up at the origin.  The world frame is a flat (tangent-plane) frame: away
from the origin geodetic up tilts away from world z (about 0.9 deg at 100 km),
which the visibility code accounts for.

Material classes
----------------
Each triangle carries a class from a :class:`MaterialTable`.  A class with
``attenuation_db_per_m = None`` is opaque (blocks the line of sight); a class
with a finite value is a penetrable volume (foliage) whose loss is the path
length inside times that value.  Built-in classes: ``opaque`` and ``foliage``
(:data:`~gnss_sim_ros2.core.constants.FOLIAGE_ATTENUATION_DB_PER_M`).

Assignment, first that applies wins:

1. a materials YAML file (``materials_yaml``)::

       classes:
         foliage: {attenuation_db_per_m: 1.85}
         glass: {attenuation_db_per_m: 6.0}
       rules:                      # fnmatch, case-insensitive, first match wins
         - {pattern: "*hedge*", class: foliage}
         - {pattern: "office::*window*", class: glass}

   Patterns match the scoped name ``model[::nested]::link::collision``.
2. an element in the SDF, in a custom namespace that Gazebo ignores (SDF
   custom elements)::

       <sdf version="1.9" xmlns:gnss_sim="urn:gnss_sim">
         ... <model name="kiosk"><gnss_sim:material>foliage</gnss_sim:material> ...

   allowed in a model, link, collision or visual (innermost wins, inherited by
   everything below).  An attribute ``attenuation_db_per_m`` declares a new
   class on the spot.  Any namespace URI containing ``gnss_sim`` is accepted.
3. CONTRACT default: a model or link whose name contains ``tree``, ``bush``,
   ``hedge``, ``foliage`` or ``vegetation`` (case-insensitive substring, so
   ``street_lamp`` matches too: override it with 1. or 2.) is ``foliage``;
   everything else is ``opaque``.

Errors raise :class:`SdfError` (a ValueError) naming the file, line and element.
"""
from __future__ import annotations

import fnmatch
import math
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from lxml import etree

from .. import frames
from ..constants import FOLIAGE_ATTENUATION_DB_PER_M

#: environment variables searched for ``model://`` URIs, in this order
RESOURCE_PATH_VARS = ("GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "GAZEBO_MODEL_PATH")
#: CONTRACT: substrings of a model or link name that make it foliage by default
FOLIAGE_NAME_KEYWORDS = ("tree", "bush", "hedge", "foliage", "vegetation")
#: namespace URI suggested for the custom material element
GNSS_SIM_SDF_NS = "urn:gnss_sim"

_SPHERE_SUBDIVISIONS = 3      # icosphere: 1280 triangles
_CYLINDER_SECTIONS = 32


class SdfError(ValueError):
    """Malformed or unsupported SDF; the message names file, line and element."""


# --------------------------------------------------------------------------------------------
# georeference
# --------------------------------------------------------------------------------------------
def _rz(angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass
class SphericalCoordinates:
    """Geodetic origin of the Gazebo world frame (see the module docstring for the heading)."""

    latitude_deg: float
    longitude_deg: float
    elevation_m: float = 0.0
    heading_deg: float = 0.0
    surface_model: str = "EARTH_WGS84"

    def rotation_enu0_from_world(self) -> np.ndarray:
        """3x3: ENU at the origin = R @ world (gz-math: enu = Rz(+heading) world)."""
        return _rz(math.radians(self.heading_deg))

    def rotation_world_from_ecef(self) -> np.ndarray:
        """3x3: world vector = R @ ECEF vector."""
        return self.rotation_enu0_from_world().T @ frames.enu_rotation(self.latitude_deg, self.longitude_deg)

    def world_to_ecef(self, pos_world_m) -> np.ndarray:
        """World points [..., 3] -> ECEF [..., 3] (float64)."""
        enu = np.asarray(pos_world_m, dtype=np.float64) @ self.rotation_enu0_from_world().T
        return frames.enu_to_ecef(enu, self.latitude_deg, self.longitude_deg, self.elevation_m)

    def ecef_to_world(self, pos_ecef_m) -> np.ndarray:
        """ECEF points [..., 3] -> world [..., 3] (float64)."""
        enu = frames.ecef_to_enu(pos_ecef_m, self.latitude_deg, self.longitude_deg, self.elevation_m)
        return enu @ self.rotation_enu0_from_world()

    def to_dict(self) -> dict:
        return {"latitude_deg": float(self.latitude_deg), "longitude_deg": float(self.longitude_deg),
                "elevation_m": float(self.elevation_m), "heading_deg": float(self.heading_deg),
                "surface_model": self.surface_model}

    @classmethod
    def from_dict(cls, d: dict, where: str = "spherical_coordinates") -> SphericalCoordinates:
        try:
            return cls(float(d["latitude_deg"]), float(d["longitude_deg"]), float(d.get("elevation_m", 0.0)),
                       float(d.get("heading_deg", 0.0)), str(d.get("surface_model", "EARTH_WGS84")))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{where}: needs numeric latitude_deg, longitude_deg[, elevation_m, heading_deg]: "
                             f"{exc}") from exc


# --------------------------------------------------------------------------------------------
# materials
# --------------------------------------------------------------------------------------------
@dataclass
class MaterialClass:
    """A material class; ``attenuation_db_per_m=None`` means opaque."""

    name: str
    attenuation_db_per_m: float | None = None

    @property
    def opaque(self) -> bool:
        return self.attenuation_db_per_m is None or not math.isfinite(self.attenuation_db_per_m)


@dataclass
class MaterialTable:
    """Material classes (index = position) and name-pattern rules."""

    classes: list[MaterialClass] = field(default_factory=lambda: [
        MaterialClass("opaque", None), MaterialClass("foliage", FOLIAGE_ATTENUATION_DB_PER_M)])
    rules: list[tuple[str, str]] = field(default_factory=list)  # (pattern, class name)

    def index(self, name: str) -> int:
        for i, c in enumerate(self.classes):
            if c.name == name:
                return i
        raise KeyError(name)

    def has(self, name: str) -> bool:
        return any(c.name == name for c in self.classes)

    def declare(self, name: str, attenuation_db_per_m: float | None) -> int:
        if self.has(name):
            i = self.index(name)
            self.classes[i].attenuation_db_per_m = attenuation_db_per_m
            return i
        self.classes.append(MaterialClass(name, attenuation_db_per_m))
        return len(self.classes) - 1

    def match_rules(self, scoped_name: str) -> str | None:
        low = scoped_name.lower()
        for pattern, cls in self.rules:
            if fnmatch.fnmatchcase(low, pattern.lower()):
                return cls
        return None

    def to_list(self) -> list[dict]:
        return [{"index": i, "name": c.name, "attenuation_db_per_m": c.attenuation_db_per_m}
                for i, c in enumerate(self.classes)]

    @classmethod
    def from_list(cls, items, where: str = "materials") -> MaterialTable:
        classes = []
        for k, item in enumerate(items):
            try:
                att = item.get("attenuation_db_per_m")
                classes.append(MaterialClass(str(item["name"]), None if att is None else float(att)))
            except (KeyError, TypeError, ValueError, AttributeError) as exc:
                raise ValueError(f"{where}[{k}]: needs name and attenuation_db_per_m (null = opaque): {exc}") from exc
        return cls(classes=classes)


def _parse_attenuation(value, where: str) -> float | None:
    if value is None or (isinstance(value, str) and value.strip().lower() in ("", "null", "none", "opaque", "inf")):
        return None
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{where}: attenuation_db_per_m must be a number or null, got {value!r}") from exc
    if not v >= 0.0:
        raise ValueError(f"{where}: attenuation_db_per_m must be >= 0, got {v}")
    return None if math.isinf(v) else v


def load_materials_yaml(path) -> MaterialTable:
    """Read a materials YAML file (format in the module docstring) on top of the built-in classes."""
    import yaml

    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except OSError as exc:
        raise ValueError(f"materials file {path}: cannot read: {exc}") from exc
    except yaml.YAMLError as exc:
        raise ValueError(f"materials file {path}: not valid YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise ValueError(f"materials file {path}: top level must be a mapping with 'classes' and/or 'rules'")
    table = MaterialTable()
    classes = data.get("classes") or {}
    if not isinstance(classes, dict):
        raise ValueError(f"materials file {path}: 'classes' must map a class name to {{attenuation_db_per_m: ...}}")
    for name, spec in classes.items():
        where = f"materials file {path}: class {name!r}"
        if not isinstance(spec, dict) or "attenuation_db_per_m" not in spec:
            raise ValueError(f"{where}: needs attenuation_db_per_m (null = opaque)")
        table.declare(str(name), _parse_attenuation(spec["attenuation_db_per_m"], where))
    rules = data.get("rules") or []
    if not isinstance(rules, list):
        raise ValueError(f"materials file {path}: 'rules' must be a list of {{pattern, class}}")
    for k, rule in enumerate(rules):
        if not isinstance(rule, dict) or "pattern" not in rule or "class" not in rule:
            raise ValueError(f"materials file {path}: rules[{k}] needs 'pattern' and 'class'")
        if not table.has(str(rule["class"])):
            raise ValueError(f"materials file {path}: rules[{k}] names unknown class {rule['class']!r} "
                             f"(declare it under 'classes')")
        table.rules.append((str(rule["pattern"]), str(rule["class"])))
    return table


# --------------------------------------------------------------------------------------------
# result
# --------------------------------------------------------------------------------------------
@dataclass
class WorldMesh:
    """Triangles of a world in the Gazebo world frame [m] with a material class per triangle."""

    vertices_m: np.ndarray            # (V, 3) float64, world frame
    triangles: np.ndarray             # (T, 3) int64
    material: np.ndarray              # (T,) int16 index into materials.classes
    materials: MaterialTable
    spherical_coordinates: SphericalCoordinates | None = None
    parts: list[dict] = field(default_factory=list)   # {name, class, triangles}
    source: str = ""

    def class_counts(self) -> dict[str, int]:
        counts = np.bincount(self.material.astype(np.int64), minlength=len(self.materials.classes))
        return {c.name: int(n) for c, n in zip(self.materials.classes, counts)}


# --------------------------------------------------------------------------------------------
# XML helpers
# --------------------------------------------------------------------------------------------
def _where(el, file) -> str:
    line = getattr(el, "sourceline", None)
    name = el.get("name")
    tag = _local(el.tag)
    desc = f"<{tag} name={name!r}>" if name is not None else f"<{tag}>"
    return f"{file}:{line}: {desc}" if line else f"{file}: {desc}"


def _local(tag) -> str:
    if not isinstance(tag, str):
        return ""
    return tag.rsplit("}", 1)[-1]


def _ns(tag) -> str:
    if isinstance(tag, str) and tag.startswith("{"):
        return tag[1:].split("}", 1)[0]
    return ""


def _children(el, tag: str):
    return [c for c in el if isinstance(c.tag, str) and c.tag == tag]


def _child(el, tag: str):
    for c in el:
        if isinstance(c.tag, str) and c.tag == tag:
            return c
    return None


def _floats(el, file, n: int | tuple[int, ...], what: str | None = None) -> list[float]:
    text = (el.text or "").split()
    counts = (n,) if isinstance(n, int) else n
    try:
        vals = [float(t) for t in text]
    except ValueError as exc:
        raise SdfError(f"{_where(el, file)}: {what or _local(el.tag)} must be numbers, got {el.text!r}") from exc
    if len(vals) not in counts:
        raise SdfError(f"{_where(el, file)}: {what or _local(el.tag)} needs {' or '.join(map(str, counts))} "
                       f"numbers, got {len(vals)} ({el.text!r})")
    if not all(math.isfinite(v) for v in vals):
        raise SdfError(f"{_where(el, file)}: non-finite value in {el.text!r}")
    return vals


def _req_child_floats(el, tag, file, n, default=None):
    c = _child(el, tag)
    if c is None:
        if default is not None:
            return list(default)
        raise SdfError(f"{_where(el, file)}: missing <{tag}>")
    return _floats(c, file, n)


def _truthy(text) -> bool:
    return str(text).strip().lower() in ("1", "true")


def _euler_matrix(roll, pitch, yaw) -> np.ndarray:
    """SDF pose rotation: R = Rz(yaw) Ry(pitch) Rx(roll) (sdformat.org, pose spec)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def parse_pose(el, file="<sdf>") -> tuple[np.ndarray, str | None]:
    """``<pose>`` -> (4x4 homogeneous transform, relative_to or None)."""
    if el is None:
        return np.eye(4), None
    T = np.eye(4)
    rel = el.get("relative_to")
    if not (el.text or "").strip():
        return T, rel or None
    fmt = (el.get("rotation_format") or "euler_rpy").strip()
    if fmt == "quat_xyzw":
        x, y, z, qx, qy, qz, qw = _floats(el, file, 7, "pose (quat_xyzw)")
        q = np.array([qw, qx, qy, qz])
        nq = np.linalg.norm(q)
        if nq == 0:
            raise SdfError(f"{_where(el, file)}: zero quaternion")
        w, a, b, c = q / nq
        R = np.array([[1 - 2 * (b * b + c * c), 2 * (a * b - c * w), 2 * (a * c + b * w)],
                      [2 * (a * b + c * w), 1 - 2 * (a * a + c * c), 2 * (b * c - a * w)],
                      [2 * (a * c - b * w), 2 * (b * c + a * w), 1 - 2 * (a * a + b * b)]])
    elif fmt == "euler_rpy":
        x, y, z, r, p, yw = _floats(el, file, 6, "pose")
        if _truthy(el.get("degrees", "false")):
            r, p, yw = math.radians(r), math.radians(p), math.radians(yw)
        R = _euler_matrix(r, p, yw)
    else:
        raise SdfError(f"{_where(el, file)}: unknown rotation_format {fmt!r} (euler_rpy or quat_xyzw)")
    T[:3, :3] = R
    T[:3, 3] = (x, y, z)
    return T, rel or None


# --------------------------------------------------------------------------------------------
# URIs and includes
# --------------------------------------------------------------------------------------------
def resource_dirs(extra: list[Path] | None = None) -> list[Path]:
    """Folders searched for ``model://`` URIs (environment variables, then ``extra``)."""
    out = []
    for var in RESOURCE_PATH_VARS:
        for p in os.environ.get(var, "").split(os.pathsep):
            if p.strip():
                out.append(Path(p.strip()))
    out.extend(extra or [])
    return out


def resolve_uri(uri: str, base_dir: Path, el=None, file="<sdf>", search_extra: list[Path] | None = None) -> Path:
    """Resolve a ``model://``, ``file://``, absolute or relative URI to an existing path."""
    uri = (uri or "").strip()
    where = _where(el, file) if el is not None else str(file)
    if not uri:
        raise SdfError(f"{where}: empty <uri>")
    if uri.startswith("model://"):
        rest = uri[len("model://"):]
        dirs = resource_dirs([base_dir] + list(search_extra or []))
        for d in dirs:
            cand = d / rest
            if cand.exists():
                return cand
        raise SdfError(f"{where}: cannot find {uri!r}: searched {[str(d) for d in dirs]} "
                       f"(set GZ_SIM_RESOURCE_PATH to the folder that holds the model)")
    if uri.startswith(("http://", "https://")):
        raise SdfError(f"{where}: network URI {uri!r} is not supported: download the model (e.g. from Gazebo "
                       f"Fuel) and put its folder on GZ_SIM_RESOURCE_PATH")
    if uri.startswith("file://"):
        uri = uri[len("file://"):]
    if "://" in uri:
        raise SdfError(f"{where}: unknown URI scheme in {uri!r} (model://, file:// or a path)")
    p = Path(uri)
    if not p.is_absolute():
        p = base_dir / p
    if not p.exists():
        raise SdfError(f"{where}: file {uri!r} not found (resolved to {p})")
    return p


def _version_key(v: str):
    try:
        return tuple(int(x) for x in v.split("."))
    except ValueError:
        return (0,)


def model_sdf_path(model_dir: Path, el=None, file="<sdf>") -> Path:
    """The SDF file of a model folder: from ``model.config`` (highest ``<sdf version>``) or ``model.sdf``."""
    where = _where(el, file) if el is not None else str(file)
    if model_dir.is_file():
        return model_dir
    cfg = model_dir / "model.config"
    if cfg.is_file():
        try:
            root = etree.parse(str(cfg)).getroot()
        except etree.XMLSyntaxError as exc:
            raise SdfError(f"{cfg}: malformed model.config: {exc}") from exc
        entries = [(s.get("version", "0"), (s.text or "").strip()) for s in root.iter("sdf") if (s.text or "").strip()]
        if entries:
            entries.sort(key=lambda e: _version_key(e[0]))
            p = model_dir / entries[-1][1]
            if not p.is_file():
                raise SdfError(f"{cfg}: names SDF file {entries[-1][1]!r} which does not exist")
            return p
    p = model_dir / "model.sdf"
    if p.is_file():
        return p
    raise SdfError(f"{where}: model folder {model_dir} has neither model.config with <sdf> nor model.sdf")


def _parse_xml(path: Path):
    parser = etree.XMLParser(remove_comments=True, remove_pis=True)
    try:
        return etree.parse(str(path), parser).getroot()
    except etree.XMLSyntaxError as exc:
        raise SdfError(f"{path}: malformed SDF/XML: {exc}") from exc
    except OSError as exc:
        raise SdfError(f"{path}: cannot read: {exc}") from exc


# --------------------------------------------------------------------------------------------
# geometry -> trimesh
# --------------------------------------------------------------------------------------------
def _triangulate_polygon(pts: np.ndarray) -> np.ndarray:
    """Ear clipping of a simple polygon (K, 2) -> (K-2, 3) indices, counter-clockwise triangles."""
    n = len(pts)
    area2 = np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
    idx = list(range(n)) if area2 > 0 else list(range(n))[::-1]
    tris = []

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    guard = 0
    while len(idx) > 3 and guard < 10 * n * n:
        guard += 1
        m = len(idx)
        for k in range(m):
            i0, i1, i2 = idx[(k - 1) % m], idx[k], idx[(k + 1) % m]
            a, b, c = pts[i0], pts[i1], pts[i2]
            if cross(a, b, c) <= 1e-12:
                continue
            inside = False
            for j in idx:
                if j in (i0, i1, i2):
                    continue
                p = pts[j]
                if cross(a, b, p) >= 0 and cross(b, c, p) >= 0 and cross(c, a, p) >= 0:
                    inside = True
                    break
            if not inside:
                tris.append((i0, i1, i2))
                idx.pop(k)
                break
        else:
            break  # degenerate polygon: stop clipping
    if len(idx) == 3:
        tris.append(tuple(idx))
    return np.array(tris, dtype=np.int64).reshape(-1, 3)


def _extrude_polygon(pts: np.ndarray, height: float):
    import trimesh

    pts = np.asarray(pts, dtype=np.float64)
    if len(pts) > 2 and np.allclose(pts[0], pts[-1]):
        pts = pts[:-1]
    area2 = np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1])
    if area2 < 0:
        pts = pts[::-1]
    n = len(pts)
    tri = _triangulate_polygon(pts)
    verts = np.vstack([np.c_[pts, np.zeros(n)], np.c_[pts, np.full(n, height)]])
    faces = [tri[:, ::-1], tri + n]
    i = np.arange(n)
    j = (i + 1) % n
    faces.append(np.c_[i, j, j + n])
    faces.append(np.c_[i, j + n, i + n])
    return trimesh.Trimesh(verts, np.vstack(faces), process=False)


def _plane_mesh(normal, size):
    import trimesh

    nrm = np.asarray(normal, dtype=np.float64)
    nn = np.linalg.norm(nrm)
    nrm = nrm / nn
    helper = np.array([1.0, 0.0, 0.0]) if abs(nrm[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    # gz: plane local x/y are the z-to-normal rotation of world x/y; for the default normal (0 0 1) x=x, y=y
    if np.allclose(nrm, [0, 0, 1]):
        ex, ey = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    else:
        ex = np.cross(helper, nrm)
        ex /= np.linalg.norm(ex)
        ey = np.cross(nrm, ex)
    hx, hy = size[0] / 2.0, size[1] / 2.0
    v = np.array([-hx * ex - hy * ey, hx * ex - hy * ey, hx * ex + hy * ey, -hx * ex + hy * ey])
    return trimesh.Trimesh(v, np.array([[0, 1, 2], [0, 2, 3]]), process=False)


def _dae_unit_m(path: Path) -> float:
    try:
        root = etree.parse(str(path)).getroot()
    except etree.XMLSyntaxError:
        return 1.0
    for el in root.iter():
        if _local(el.tag) == "unit" and el.get("meter"):
            try:
                return float(el.get("meter"))
            except ValueError:
                return 1.0
    return 1.0


def load_mesh_file(path: Path, el=None, file="<sdf>"):
    """A mesh file (OBJ, STL, PLY, DAE, GLB...) as one trimesh.Trimesh in metres."""
    import trimesh

    where = _where(el, file) if el is not None else str(path)
    if not path.is_file():
        raise SdfError(f"{where}: mesh file {path} not found")
    try:
        m = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds
        raise SdfError(f"{where}: cannot load mesh {path}: {type(exc).__name__}: {exc}") from exc
    if not isinstance(m, trimesh.Trimesh) or len(m.faces) == 0:
        raise SdfError(f"{where}: mesh {path} holds no triangles")
    if path.suffix.lower() == ".dae":
        unit = _dae_unit_m(path)
        if unit != 1.0:
            m.apply_scale(unit)
    return m


def geometry_mesh(geom_el, file: Path, base_dir: Path):
    """``<geometry>`` -> list of trimesh.Trimesh in the collision/visual frame (empty if skipped)."""
    import trimesh

    shapes = [c for c in geom_el if isinstance(c.tag, str) and not _ns(c.tag)]
    if not shapes:
        raise SdfError(f"{_where(geom_el, file)}: <geometry> holds no shape")
    out = []
    for s in shapes:
        kind = s.tag
        if kind == "box":
            size = _req_child_floats(s, "size", file, 3, default=(1, 1, 1))
            if min(size) <= 0:
                raise SdfError(f"{_where(s, file)}: box <size> must be positive, got {size}")
            out.append(trimesh.creation.box(extents=size))
        elif kind == "sphere":
            (r,) = _req_child_floats(s, "radius", file, 1, default=(1,))
            m = trimesh.creation.icosphere(subdivisions=_SPHERE_SUBDIVISIONS, radius=r)
            out.append(m)
        elif kind == "cylinder":
            (r,) = _req_child_floats(s, "radius", file, 1, default=(1,))
            (ln,) = _req_child_floats(s, "length", file, 1, default=(1,))
            out.append(trimesh.creation.cylinder(radius=r, height=ln, sections=_CYLINDER_SECTIONS))
        elif kind == "capsule":
            (r,) = _req_child_floats(s, "radius", file, 1, default=(0.5,))
            (ln,) = _req_child_floats(s, "length", file, 1, default=(1,))
            out.append(trimesh.creation.capsule(height=ln, radius=r, count=[_CYLINDER_SECTIONS, _CYLINDER_SECTIONS]))
        elif kind == "ellipsoid":
            radii = _req_child_floats(s, "radii", file, 3, default=(1, 1, 1))
            m = trimesh.creation.icosphere(subdivisions=_SPHERE_SUBDIVISIONS, radius=1.0)
            m.apply_scale(radii)
            out.append(m)
        elif kind == "plane":
            nrm = _req_child_floats(s, "normal", file, 3, default=(0, 0, 1))
            size = _req_child_floats(s, "size", file, 2, default=(1, 1))
            if np.linalg.norm(nrm) == 0 or min(size) <= 0:
                raise SdfError(f"{_where(s, file)}: plane needs a non-zero <normal> and positive <size>")
            out.append(_plane_mesh(nrm, size))
        elif kind == "polyline":
            (h,) = _req_child_floats(s, "height", file, 1, default=(1,))
            pts = np.array([_floats(p, file, 2, "polyline <point>") for p in _children(s, "point")])
            if len(pts) < 3:
                raise SdfError(f"{_where(s, file)}: polyline needs at least 3 <point>")
            out.append(_extrude_polygon(pts, h))
        elif kind == "mesh":
            uri_el = _child(s, "uri")
            if uri_el is None:
                raise SdfError(f"{_where(s, file)}: <mesh> without <uri>")
            path = resolve_uri(uri_el.text, base_dir, uri_el, file)
            m = load_mesh_file(path, uri_el, file)
            if _child(s, "submesh") is not None:
                warnings.warn(f"{_where(s, file)}: <submesh> is not supported, the whole mesh is used", stacklevel=2)
            scale = _req_child_floats(s, "scale", file, 3, default=(1, 1, 1))
            if scale != [1, 1, 1]:
                m.apply_transform(np.diag(list(scale) + [1.0]))
            out.append(m)
        elif kind in ("heightmap", "image", "empty"):
            if kind != "empty":
                warnings.warn(f"{_where(s, file)}: <{kind}> geometry is not supported and is skipped", stacklevel=2)
        else:
            raise SdfError(f"{_where(s, file)}: unknown geometry <{kind}>")
    return out


# --------------------------------------------------------------------------------------------
# frame graph
# --------------------------------------------------------------------------------------------
class _Scope:
    """Frames of one model (or the world): name -> (kind, element, file, pose element)."""

    def __init__(self, el, file: Path, is_world: bool, loader: _Loader):
        self.el = el
        self.file = file
        self.is_world = is_world
        self.loader = loader
        self.frames: dict[str, tuple] = {}
        self.cache: dict[str, np.ndarray] = {}
        self.subscopes: dict[str, _Scope] = {}
        kinds = ("model", "include", "frame") if is_world else ("link", "model", "include", "frame", "joint")
        for c in el:
            if not isinstance(c.tag, str) or c.tag not in kinds:
                continue
            if c.tag == "include":
                model_el, mfile, name, pose_el = loader.load_include(c, file)
                entry = ("model", model_el, mfile, pose_el)
            else:
                name = c.get("name")
                if not name:
                    raise SdfError(f"{_where(c, file)}: <{c.tag}> without a name attribute")
                entry = (c.tag, c, file, _child(c, "pose"))
            if name in self.frames:
                raise SdfError(f"{_where(c, file)}: duplicate name {name!r} in {_where(el, file)}")
            self.frames[name] = entry

    def subscope(self, name: str) -> _Scope:
        if name not in self.subscopes:
            kind, el, mfile, _ = self.frames[name]
            self.subscopes[name] = _Scope(el, mfile, False, self.loader)
        return self.subscopes[name]

    def resolve(self, name: str | None, stack=()) -> np.ndarray:
        """Pose of frame ``name`` in this scope's frame (the model frame, or the world)."""
        if name in (None, "", "__model__") or (self.is_world and name == "world"):
            return np.eye(4)
        if name in self.cache:
            return self.cache[name]
        if name in stack:
            raise SdfError(f"{_where(self.el, self.file)}: cycle in relative_to/attached_to: "
                           f"{' -> '.join(stack + (name,))}")
        if "::" in name and name.split("::", 1)[0] in self.frames:
            head, rest = name.split("::", 1)
            if self.frames[head][0] != "model":
                raise SdfError(f"{_where(self.el, self.file)}: {name!r}: {head!r} is not a nested model")
            T = self.resolve(head, stack) @ self.subscope(head).resolve(rest)
            self.cache[name] = T
            return T
        if name not in self.frames:
            raise SdfError(f"{_where(self.el, self.file)}: relative_to/attached_to names unknown frame {name!r} "
                           f"(known: {sorted(self.frames) + ['__model__']})")
        kind, el, file, pose_el = self.frames[name]
        P, rel = parse_pose(pose_el, file)
        if rel is None:
            if kind == "frame":
                rel = el.get("attached_to") or None
            elif kind == "joint":
                child = _child(el, "child")
                rel = (child.text or "").strip() if child is not None else None
        T = self.resolve(rel, stack + (name,)) @ P
        self.cache[name] = T
        return T


class _Loader:
    def __init__(self, table: MaterialTable, use_visuals: bool, user_rules: bool):
        self.table = table
        self.use_visuals = use_visuals
        self.user_rules = user_rules
        self.verts: list[np.ndarray] = []
        self.tris: list[np.ndarray] = []
        self.mats: list[np.ndarray] = []
        self.parts: list[dict] = []
        self.n_verts = 0
        self.include_depth = 0

    def load_include(self, inc_el, file: Path):
        uri_el = _child(inc_el, "uri")
        if uri_el is None:
            raise SdfError(f"{_where(inc_el, file)}: <include> without <uri>")
        target = resolve_uri(uri_el.text, file.parent, uri_el, file)
        sdf_path = model_sdf_path(target, uri_el, file) if target.is_dir() else target
        root = _parse_xml(sdf_path)
        model = root if _local(root.tag) == "model" else _child(root, "model")
        if model is None:
            raise SdfError(f"{sdf_path}: included from {_where(inc_el, file)} holds no <model>")
        name_el = _child(inc_el, "name")
        name = (name_el.text or "").strip() if name_el is not None else model.get("name")
        if not name:
            raise SdfError(f"{_where(inc_el, file)}: included model has no name")
        pose_el = _child(inc_el, "pose")
        if pose_el is None:
            pose_el = _child(model, "pose")
        # material tag on the include itself is carried to the model
        for c in inc_el:
            if _is_material_tag(c):
                model.insert(0, c)
        return model, sdf_path, name, pose_el

    def material_for(self, scoped: str, chain: list[tuple], names_for_default: list[str]) -> int:
        if self.user_rules:
            cls = self.table.match_rules(scoped)
            if cls is not None:
                return self.table.index(cls)
        for el, file in reversed(chain):       # innermost explicit tag wins
            for c in el:
                if _is_material_tag(c):
                    name = (c.text or "").strip()
                    if not name:
                        raise SdfError(f"{_where(c, file)}: empty material element")
                    att = c.get("attenuation_db_per_m")
                    if att is not None:
                        return self.table.declare(name, _parse_attenuation(att, _where(c, file)))
                    if not self.table.has(name):
                        raise SdfError(f"{_where(c, file)}: unknown material class {name!r} (known: "
                                       f"{[k.name for k in self.table.classes]}; add attenuation_db_per_m=... "
                                       f"to declare it)")
                    return self.table.index(name)
        low = [n.lower() for n in names_for_default]
        if any(k in n for n in low for k in FOLIAGE_NAME_KEYWORDS):
            return self.table.index("foliage")
        return self.table.index("opaque")

    def add(self, mesh, T: np.ndarray, mat: int, scoped: str):
        v = np.asarray(mesh.vertices, dtype=np.float64) @ T[:3, :3].T + T[:3, 3]
        f = np.asarray(mesh.faces, dtype=np.int64)
        if len(f) == 0:
            return
        if np.linalg.det(T[:3, :3]) < 0:
            f = f[:, ::-1]
        self.verts.append(v)
        self.tris.append(f + self.n_verts)
        self.mats.append(np.full(len(f), mat, dtype=np.int16))
        self.n_verts += len(v)
        cls = self.table.classes[mat]
        if not cls.opaque and not mesh.is_watertight:
            warnings.warn(f"{scoped}: {cls.name} geometry is not a closed mesh; path lengths inside it will be "
                          f"wrong", stacklevel=2)
        self.parts.append({"name": scoped, "class": cls.name, "triangles": int(len(f))})

    def walk_model(self, scope: _Scope, T_world_model: np.ndarray, prefix: str, chain: list, names: list):
        file = scope.file
        for name, (kind, cel, cfile, _) in scope.frames.items():
            if kind == "model":
                sub = scope.subscope(name)
                T = T_world_model @ scope.resolve(name)
                self.walk_model(sub, T, f"{prefix}::{name}", chain + [(cel, cfile)], names + [name])
            elif kind == "link":
                T_link = T_world_model @ scope.resolve(name)
                tag = "visual" if self.use_visuals else "collision"
                for g in _children(cel, tag):
                    gname = g.get("name") or tag
                    P, rel = parse_pose(_child(g, "pose"), file)
                    if rel is None or rel == name:
                        T = T_link @ P
                    else:
                        T = T_world_model @ scope.resolve(rel) @ P
                    geom = _child(g, "geometry")
                    if geom is None:
                        raise SdfError(f"{_where(g, file)}: <{tag}> without <geometry>")
                    scoped = f"{prefix}::{name}::{gname}"
                    mat = self.material_for(scoped, chain + [(cel, file), (g, file)], names + [name])
                    for m in geometry_mesh(geom, file, file.parent):
                        self.add(m, T, mat, scoped)


def _is_material_tag(c) -> bool:
    return isinstance(c.tag, str) and _local(c.tag) in ("material", "gnss_material") and (
        "gnss_sim" in _ns(c.tag).lower() or (not _ns(c.tag) and c.tag == "gnss_material"))


def _parse_spherical(world, file) -> SphericalCoordinates | None:
    sc = _child(world, "spherical_coordinates")
    if sc is None:
        return None
    orient = _child(sc, "world_frame_orientation")
    if orient is not None and (orient.text or "").strip().upper() not in ("", "ENU"):
        raise SdfError(f"{_where(orient, file)}: world_frame_orientation {orient.text.strip()!r} is not supported "
                       f"(only ENU)")
    surf = _child(sc, "surface_model")
    surface = (surf.text or "EARTH_WGS84").strip() if surf is not None else "EARTH_WGS84"
    if surface != "EARTH_WGS84":
        raise SdfError(f"{_where(surf, file)}: surface_model {surface!r} is not supported (only EARTH_WGS84)")

    def val(tag, default=0.0):
        c = _child(sc, tag)
        return _floats(c, file, 1)[0] if c is not None else default

    lat = val("latitude_deg")
    if not -90.0 <= lat <= 90.0:
        raise SdfError(f"{_where(sc, file)}: latitude_deg {lat} outside [-90, 90]")
    return SphericalCoordinates(lat, val("longitude_deg"), val("elevation"), val("heading_deg"), surface)


def load_sdf_world(sdf_path, materials_yaml=None, use_visuals: bool = False,
                   materials: MaterialTable | None = None) -> WorldMesh:
    """Read an SDF world (or a single-model SDF file) into a :class:`WorldMesh` in the world frame.

    ``materials_yaml``: optional YAML of classes and name rules; ``use_visuals``: take ``<visual>``
    geometry instead of ``<collision>``.
    """
    sdf_path = Path(sdf_path)
    if materials is not None:
        table, user_rules = materials, bool(materials.rules)
    elif materials_yaml is not None:
        table, user_rules = load_materials_yaml(materials_yaml), True
    else:
        table, user_rules = MaterialTable(), False
    root = _parse_xml(sdf_path)
    if _local(root.tag) != "sdf":
        raise SdfError(f"{_where(root, sdf_path)}: root element must be <sdf>, got <{_local(root.tag)}>")
    loader = _Loader(table, use_visuals, user_rules)
    world = _child(root, "world")
    sph = None
    if world is not None:
        sph = _parse_spherical(world, sdf_path)
        scope = _Scope(world, sdf_path, True, loader)
        for name, (kind, el, file, _) in scope.frames.items():
            if kind != "model":
                continue
            T = scope.resolve(name)
            loader.walk_model(scope.subscope(name), T, name, [(el, file)], [name])
    else:
        model = _child(root, "model")
        if model is None:
            raise SdfError(f"{_where(root, sdf_path)}: holds neither <world> nor <model>")
        name = model.get("name") or "model"
        T, _ = parse_pose(_child(model, "pose"), sdf_path)
        loader.walk_model(_Scope(model, sdf_path, False, loader), T, name, [(model, sdf_path)], [name])
    if loader.verts:
        verts = np.vstack(loader.verts)
        tris = np.vstack(loader.tris)
        mats = np.concatenate(loader.mats)
    else:
        verts, tris, mats = np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int16)
    return WorldMesh(verts, tris, mats, table, sph, loader.parts, str(sdf_path))
