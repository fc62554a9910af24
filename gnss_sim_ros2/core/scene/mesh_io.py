"""Exported scene: a PLY mesh with a material class per triangle, plus a YAML sidecar.

Files
-----
``NAME.ply``: binary little-endian PLY, vertices as ``double x, y, z`` (Gazebo
world frame, metres; double so large worlds keep millimetres), faces as
``list uchar int vertex_indices`` plus ``short material`` (index into the
sidecar's material table).  MeshLab, Blender and trimesh read it (the extra
face property is ignored by viewers that do not know it).

``NAME.scene.yaml`` (sidecar, next to the mesh)::

    format: gnss_sim.scene/1
    mesh: NAME.ply
    frame: Gazebo world frame (ENU at the origin rotated by heading_deg, ...)
    spherical_coordinates: {latitude_deg, longitude_deg, elevation_m, heading_deg, surface_model}  # or null
    materials: [{index: 0, name: opaque, attenuation_db_per_m: null}, {index: 1, name: foliage, ...}]
    source: WORLD.sdf
    triangles: {opaque: 1234, foliage: 560}
    parts: [{name, class, triangles}, ...]
    report: {parts_loaded, triangles, skipped: [{part, reason}], left_out: [...], mesh_files_read, ...}

A mesh without the ``material`` face property (any PLY/OBJ/STL from elsewhere)
loads with every triangle in class 0 of the sidecar table (``opaque`` when
there is no sidecar), unless the sidecar names ``material_index_file`` (a
``.npy`` int array with one class per triangle).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..input_file import not_a_file
from .georeference import SphericalCoordinates
from .loader import load_sdf_world
from .materials import MaterialTable
from .world_mesh import WorldMesh, check_world_extent

SCENE_FORMAT = "gnss_sim.scene/1"
FRAME_DESCRIPTION = ("Gazebo world frame [m]: ENU at the spherical_coordinates origin rotated by heading_deg "
                     "(enu = Rz(heading) world, gz-math convention)")


def sidecar_path(mesh_path) -> Path:
    """``dir/NAME.ply`` -> ``dir/NAME.scene.yaml``."""
    p = Path(mesh_path)
    return p.with_name(p.stem + ".scene.yaml")


def write_ply(path, vertices_m, triangles, material=None) -> None:
    """Binary PLY with double vertices and an optional ``short material`` face property."""
    v = np.ascontiguousarray(vertices_m, dtype="<f8")
    f = np.asarray(triangles, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"write_ply {path}: vertices must be (V, 3) and triangles (T, 3)")
    if len(f) and (f.min() < 0 or f.max() >= len(v)):
        raise ValueError(f"write_ply {path}: triangle index out of range 0..{len(v) - 1}")
    fields = [("n", "u1"), ("idx", "<i4", (3,))]
    if material is not None:
        fields.append(("material", "<i2"))
    rec = np.zeros(len(f), dtype=fields)
    rec["n"] = 3
    rec["idx"] = f
    if material is not None:
        rec["material"] = np.asarray(material, dtype=np.int16)
    header = ["ply", "format binary_little_endian 1.0", "comment gnss_sim scene mesh",
              f"element vertex {len(v)}", "property double x", "property double y", "property double z",
              f"element face {len(f)}", "property list uchar int vertex_indices"]
    if material is not None:
        header.append("property short material")
    header.append("end_header")
    with open(path, "wb") as fh:
        fh.write(("\n".join(header) + "\n").encode("ascii"))
        fh.write(v.tobytes())
        fh.write(rec.tobytes())


_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def _read_own_ply(path: Path):
    """Fast reader for binary little-endian PLY with triangle faces; None if the layout differs."""
    with open(path, "rb") as fh:
        head = b""
        while not head.endswith(b"end_header\n"):
            line = fh.readline()
            if not line:
                raise ValueError(f"{path}: not a PLY file (no end_header)")
            head += line
            if len(head) > 65536:
                raise ValueError(f"{path}: PLY header too long")
        lines = head.decode("ascii", "replace").splitlines()
        if not lines or lines[0].strip() != "ply":
            raise ValueError(f"{path}: not a PLY file")
        if "format binary_little_endian 1.0" not in [ln.strip() for ln in lines]:
            return None
        elements, cur = [], None
        for ln in lines:
            parts = ln.split()
            if not parts:
                continue
            if parts[0] == "element":
                cur = {"name": parts[1], "count": int(parts[2]), "props": []}
                elements.append(cur)
            elif parts[0] == "property" and cur is not None:
                if parts[1] == "list":
                    cur["props"].append(("list", parts[4], parts[2], parts[3]))
                else:
                    cur["props"].append((parts[2], parts[1]))
        data = fh.read()
    offset = 0
    out = {}
    for el in elements:
        dt = []
        for p in el["props"]:
            if p[0] == "list":
                # assume fixed length 3 (triangles); verified below
                dt.append((p[1] + "_n", "<" + _PLY_TYPES[p[2]]))
                dt.append((p[1], "<" + _PLY_TYPES[p[3]], (3,)))
            else:
                if p[1] not in _PLY_TYPES:
                    return None
                dt.append((p[0], "<" + _PLY_TYPES[p[1]]))
        dtype = np.dtype(dt)
        n = el["count"]
        arr = np.frombuffer(data, dtype=dtype, count=n, offset=offset)
        offset += n * dtype.itemsize
        for p in el["props"]:
            if p[0] == "list" and n and not np.all(arr[p[1] + "_n"] == 3):
                return None
        out[el["name"]] = arr
    if "vertex" not in out or "face" not in out:
        return None
    vx = out["vertex"]
    verts = np.stack([vx["x"], vx["y"], vx["z"]], axis=1).astype(np.float64)
    fc = out["face"]
    key = "vertex_indices" if "vertex_indices" in fc.dtype.names else "vertex_index"
    tris = fc[key].astype(np.int64)
    mat = fc["material"].astype(np.int16) if "material" in fc.dtype.names else None
    return verts, tris, mat


def check_mesh_name(mesh_path, where: str) -> Path:
    """``mesh_path`` as a Path when it names a .ply file; ValueError naming ``where`` otherwise."""
    mesh_path = Path(mesh_path)
    if mesh_path.suffix.lower() != ".ply":
        raise ValueError(f"{where}: the scene mesh must be a .ply file (it keeps a class per triangle)")
    return mesh_path


def write_scene(mesh_path, world: WorldMesh) -> Path:
    """Write ``world`` as a PLY plus its sidecar YAML; returns the sidecar path."""
    import yaml

    mesh_path = check_mesh_name(mesh_path, f"--out {mesh_path}")
    mesh_path.parent.mkdir(parents=True, exist_ok=True)
    write_ply(mesh_path, world.vertices_m, world.triangles, world.material)
    side = {
        "format": SCENE_FORMAT,
        "mesh": mesh_path.name,
        "frame": FRAME_DESCRIPTION,
        "spherical_coordinates": world.spherical_coordinates.to_dict() if world.spherical_coordinates else None,
        "materials": world.materials.to_list(),
        "source": str(world.source),
        "triangles": world.class_counts(),
        "parts": world.parts,
        "report": world.report,
    }
    sp = sidecar_path(mesh_path)
    sp.write_text(yaml.safe_dump(side, sort_keys=False))
    return sp


def read_scene(mesh_path) -> WorldMesh:
    """Read a mesh (PLY written by :func:`write_scene`, or any mesh trimesh reads) and its sidecar."""
    import yaml

    mesh_path = Path(mesh_path)
    if (why := not_a_file(mesh_path)) is not None:       # a folder or /dev/null was "not found"
        raise ValueError(f"scene mesh {mesh_path}: {why}")
    sp = sidecar_path(mesh_path)
    side = {}
    if sp.is_file():
        try:
            side = yaml.safe_load(sp.read_text()) or {}
        except yaml.YAMLError as exc:
            raise ValueError(f"{sp}: not valid YAML: {exc}") from exc
        if side.get("format") != SCENE_FORMAT:
            raise ValueError(f"{sp}: format is {side.get('format')!r}, expected {SCENE_FORMAT!r}")
    got = _read_own_ply(mesh_path) if mesh_path.suffix.lower() == ".ply" else None
    if got is None:
        import trimesh

        try:
            m = trimesh.load(str(mesh_path), force="mesh", process=False)
        except Exception as exc:  # noqa: BLE001
            raise ValueError(f"{mesh_path}: cannot read mesh: {type(exc).__name__}: {exc}") from exc
        verts, tris, mat = np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64), None
    else:
        verts, tris, mat = got
    if len(tris) == 0:    # an empty STL read as a scene of nothing: "the scene has no spherical_coordinates"
        empty = " (an empty file)" if mesh_path.stat().st_size == 0 else ""
        raise ValueError(f"scene mesh {mesh_path} holds no triangles{empty}")
    check_world_extent(verts, f"scene mesh {mesh_path}")
    table = MaterialTable.from_list(side["materials"], f"{sp}: materials") if side.get("materials") else MaterialTable()
    if mat is None and side.get("material_index_file"):
        idx_path = mesh_path.parent / side["material_index_file"]
        mat = np.load(idx_path).astype(np.int16)
        if mat.shape != (len(tris),):
            raise ValueError(f"{idx_path}: {mat.shape} material indices for {len(tris)} triangles")
    if mat is None:
        mat = np.zeros(len(tris), dtype=np.int16)
    if len(mat) and (mat.min() < 0 or mat.max() >= len(table.classes)):
        raise ValueError(f"{mesh_path}: material index {int(mat.max())} outside the table of "
                         f"{len(table.classes)} classes in {sp}")
    sph = side.get("spherical_coordinates")
    sph = SphericalCoordinates.from_dict(sph, f"{sp}: spherical_coordinates") if sph else None
    return WorldMesh(verts, tris, mat, table, sph, side.get("parts") or [], side.get("source", str(mesh_path)),
                     side.get("report") or {})


def export_world(sdf_path, out_mesh_path, materials_yaml=None, use_visuals: bool = False, *,
                 keep_dynamic: bool = False, strict: bool = False, seed: int = 0) -> WorldMesh:
    """Read an SDF world and write ``out_mesh_path`` (PLY) plus its sidecar; returns the WorldMesh.

    Keyword options as :func:`~.loader.load_sdf_world`."""
    world = load_sdf_world(sdf_path, materials_yaml=materials_yaml, use_visuals=use_visuals,
                           keep_dynamic=keep_dynamic, strict=strict, seed=seed)
    if len(world.triangles) == 0:
        why = [f"{it['part']}: {it['reason']}" for it in world.report.get("skipped", [])[:5]]
        why += [f"{it['part']}: {it['reason']}" for it in world.report.get("left_out", [])[:5]]
        raise ValueError(f"{sdf_path}: no {'visual' if use_visuals else 'collision'} geometry loaded"
                         + (": " + "; ".join(why) if why else ""))
    write_scene(out_mesh_path, world)
    return world
