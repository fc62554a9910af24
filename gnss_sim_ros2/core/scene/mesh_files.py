"""Mesh files (COLLADA, OBJ, STL, PLY, glTF/GLB) as named submeshes in metres, each file read once.

A file is read into a list of :class:`SubMesh`: one per mesh node of the file's scene, with the node
transforms applied and the names that say what it is (node, geometry, material and texture file
names: the foliage classification reads them).  ``<submesh><name>`` picks submeshes by node or
geometry name (exact first, then case-insensitive, as gz-common's ``Mesh::SubMeshByName`` is exact
and exporters vary the case); ``<center>true`` moves the picked submesh's bounding-box centre to the
origin (gz-common ``SubMesh::Center``).

COLLADA is read with pycollada (the scene's node tree, ``<unit meter>`` applied, node names kept, a
skinned mesh in its bind pose);
the other formats with trimesh (its scene graph gives the node transforms and names).
:class:`MeshCache` keeps each file's submeshes, keyed by the resolved path, so a world that uses one
mesh in 400 places reads it once.  Triangles with a NaN or infinite vertex, a vertex index out of range or
zero area are dropped with one warning naming the file and the count (one such triangle would otherwise
leave the whole ray-casting scene unable to block a ray); the rest of the file is kept.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .sdf_xml import SdfError


@dataclass
class SubMesh:
    """Triangles of one mesh node in the file's frame [m]."""

    name: str                      # node name (else geometry name)
    vertices_m: np.ndarray         # (V, 3) float64
    faces: np.ndarray              # (F, 3) int64
    names: list[str] = field(default_factory=list)  # node, geometry, material and texture names


def _collada_submeshes(path: Path) -> list[SubMesh]:
    import collada
    from collada import common

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            dae = collada.Collada(str(path), ignore=[common.DaeUnsupportedError, common.DaeBrokenRefError,
                                                     common.DaeIncompleteError])
    except Exception as exc:  # noqa: BLE001 - pycollada raises many kinds
        raise SdfError(f"COLLADA file {path}: cannot read: {type(exc).__name__}: {exc}") from exc
    unit = float(dae.assetInfo.unitmeter or 1.0) if dae.assetInfo is not None else 1.0
    textures = {}
    for m in dae.materials:
        names = [m.name or "", m.id or ""]
        eff = m.effect
        for prop in ("diffuse", "emission", "ambient", "specular", "transparent"):
            val = getattr(eff, prop, None) if eff is not None else None
            sampler = getattr(val, "sampler", None)
            img = getattr(getattr(sampler, "surface", None), "image", None)
            if img is not None and getattr(img, "path", None):
                names.append(Path(img.path).name)
        textures[m.id] = [n for n in names if n]
    out: list[SubMesh] = []
    scene = dae.scene
    if scene is None:
        return out

    def walk(node, T, node_name):
        from collada.scene import ControllerNode, GeometryNode, Node, NodeNode

        if isinstance(node, NodeNode):
            node = node.node
        if isinstance(node, Node):
            T = T @ np.asarray(node.matrix, dtype=np.float64)
            name = node.name or node.id or node_name
            for c in node.children:
                walk(c, T, name)
        elif isinstance(node, (GeometryNode, ControllerNode)):
            if isinstance(node, ControllerNode):       # a skinned mesh (a person): its bind pose
                geom = getattr(node.controller, "geometry", None)
                bind = getattr(node.controller, "bind_shape_matrix", None)
                if geom is None:
                    return
                if bind is not None:
                    T = T @ np.asarray(bind, dtype=np.float64).reshape(4, 4)
            else:
                geom = node.geometry
            mats = {m.symbol: m.target for m in node.materials}
            verts, faces, names = [], [], [node_name or "", geom.name or "", geom.id or ""]
            n = 0
            for prim in geom.primitives:
                tri = _collada_triangles(prim)
                if tri is None:
                    continue
                v, f = tri
                verts.append(v)
                faces.append(f + n)
                n += len(v)
                target = mats.get(prim.material)
                if target is not None:
                    names += textures.get(target.id, [target.name or ""])
            if not faces:
                return
            v = np.vstack(verts)
            v = v @ T[:3, :3].T + T[:3, 3]
            f = np.vstack(faces)
            if np.linalg.det(T[:3, :3]) < 0:
                f = f[:, ::-1]
            out.append(SubMesh(node_name or geom.name or geom.id or f"mesh{len(out)}", v * unit, f,
                               [x for x in dict.fromkeys(names) if x]))

    for node in scene.nodes:
        walk(node, np.eye(4), "")
    return out


def _collada_triangles(prim):
    from collada.polygons import Polygons
    from collada.polylist import Polylist
    from collada.triangleset import TriangleSet

    if isinstance(prim, (Polylist, Polygons)):
        prim = prim.triangleset()
    if not isinstance(prim, TriangleSet) or prim.vertex is None or prim.vertex_index is None:
        return None
    v = np.asarray(prim.vertex, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(prim.vertex_index, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        return None
    return v, f


def _trimesh_submeshes(path: Path) -> list[SubMesh]:
    import trimesh

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(str(path), process=False)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds
        raise SdfError(f"mesh file {path}: cannot read: {type(exc).__name__}: {exc}") from exc
    out = []
    if isinstance(loaded, trimesh.Trimesh):
        items = [(path.stem, np.eye(4), loaded, path.stem)]
    elif isinstance(loaded, trimesh.Scene):
        items = []
        for node in loaded.graph.nodes_geometry:
            T, gname = loaded.graph[node]
            items.append((node, np.asarray(T), loaded.geometry[gname], gname))
    else:
        items = []
    for node, T, g, gname in items:
        if not isinstance(g, trimesh.Trimesh) or len(g.faces) == 0:
            continue
        v = np.asarray(g.vertices, np.float64) @ T[:3, :3].T + T[:3, 3]
        f = np.asarray(g.faces, np.int64)
        if np.linalg.det(T[:3, :3]) < 0:
            f = f[:, ::-1]
        names = [str(node), str(gname)]
        mat = getattr(getattr(g, "visual", None), "material", None)
        if mat is not None and getattr(mat, "name", None):
            names.append(str(mat.name))
        out.append(SubMesh(str(node), v, f, list(dict.fromkeys(names))))
    return out


#: a triangle whose doubled area is below this fraction of its longest edge squared is degenerate (zero area:
#: a point or a line; it blocks nothing and some ray casters misbehave on it)
DEGENERATE_REL_AREA = 1e-12


class DroppedTrianglesWarning(UserWarning):
    """Triangles of a mesh file were dropped (NaN/infinite vertex, bad index, zero area): the message names the file."""


def bad_triangles(vertices_m: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, int, int, int]:
    """(mask of the triangles to drop, how many have a non-finite vertex, a vertex index out of range, zero area)."""
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    v = np.asarray(vertices_m, dtype=np.float64).reshape(-1, 3)
    bad_index = np.any((f < 0) | (f >= len(v)), axis=1)
    tri = v[np.where(bad_index[:, None], 0, f)] if len(v) else np.zeros((len(f), 3, 3))
    non_finite = ~bad_index & ~np.all(np.isfinite(tri), axis=(1, 2))
    ok = ~(bad_index | non_finite)
    with np.errstate(invalid="ignore", over="ignore"):
        e1, e2, e3 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], tri[:, 2] - tri[:, 1]
        area2 = np.linalg.norm(np.cross(e1, e2), axis=1)
        longest2 = np.max(np.stack([np.einsum("ij,ij->i", e, e) for e in (e1, e2, e3)]), axis=0)
    degenerate = ok & ((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
                       | (area2 <= DEGENERATE_REL_AREA * longest2))
    return bad_index | non_finite | degenerate, int(non_finite.sum()), int(bad_index.sum()), int(degenerate.sum())


def drop_bad_triangles(subs: list[SubMesh], path: Path) -> tuple[list[SubMesh], dict | None]:
    """``subs`` without their NaN/infinite, badly indexed and zero-area triangles, and what was dropped
    ({file, triangles, of, non_finite, bad_index, degenerate}) or None; one warning naming the file when a
    triangle with a NaN/infinite vertex or a bad index went (geometry the file meant to hold)."""
    out, counts, total = [], [0, 0, 0], 0
    for s in subs:
        drop, nf, bi, dg = bad_triangles(s.vertices_m, s.faces)
        total += len(drop)
        counts = [counts[0] + nf, counts[1] + bi, counts[2] + dg]
        if drop.any():
            # the kept triangles' vertices only: a NaN vertex left in the array would still spoil the scene's
            # bounds (RayScene centres the scene on them)
            f = np.asarray(s.faces, dtype=np.int64)[~drop]
            used, f = np.unique(f, return_inverse=True)
            s = SubMesh(s.name, np.asarray(s.vertices_m)[used], f.reshape(-1, 3), s.names)
        if len(s.faces):
            out.append(s)
    n = sum(counts)
    if n == 0:
        return subs, None
    why = ", ".join(f"{k} {w}" for k, w in zip(counts, ("with a NaN/infinite vertex", "with a vertex index out of "
                                                         "range", "degenerate (zero area)")) if k)
    info = {"file": str(path), "triangles": n, "of": total, "non_finite": counts[0], "bad_index": counts[1],
            "degenerate": counts[2]}
    if counts[0] or counts[1]:   # zero-area triangles alone lose nothing (no ray hits them): counted, not warned
        warnings.warn(f"mesh file {path}: dropped {n} of {total} triangles ({why}); the rest of the file is kept",
                      DroppedTrianglesWarning, stacklevel=2)
    return out, info


def read_mesh_file(path: Path) -> list[SubMesh]:
    """Submeshes of a mesh file (module docstring), as the file holds them; SdfError when unreadable or empty."""
    path = Path(path)
    if not path.is_file():
        raise SdfError(f"mesh file {path} not found")
    subs = _collada_submeshes(path) if path.suffix.lower() == ".dae" else _trimesh_submeshes(path)
    if not subs:
        raise SdfError(f"mesh file {path} holds no triangles")
    return subs


def pick_submesh(subs: list[SubMesh], name: str, center: bool, path: Path) -> list[SubMesh]:
    """The submesh(es) named ``name`` (node or geometry name), centred if asked."""
    hits = [s for s in subs if name == s.name or name in s.names]
    if not hits:
        low = name.lower()
        hits = [s for s in subs if low == s.name.lower() or low in (n.lower() for n in s.names)]
    if not hits:
        raise SdfError(f"mesh file {path}: no submesh named {name!r} (has {[s.name for s in subs]})")
    if center:
        out = []
        for s in hits:
            c = 0.5 * (s.vertices_m.min(axis=0) + s.vertices_m.max(axis=0))
            out.append(SubMesh(s.name, s.vertices_m - c, s.faces, s.names))
        hits = out
    return hits


class MeshCache:
    """Submeshes of each mesh file, read once per resolved path, without the triangles that cannot be cast
    against (``dropped``: one entry per file that had some, :func:`drop_bad_triangles`)."""

    def __init__(self):
        self._files: dict[str, list[SubMesh]] = {}
        self.dropped: list[dict] = []
        self.reads = 0
        self.hits = 0

    def get(self, path: Path) -> list[SubMesh]:
        key = str(Path(path).resolve())
        subs = self._files.get(key)
        if subs is None:
            subs, dropped = drop_bad_triangles(read_mesh_file(Path(path)), Path(path))
            if dropped is not None:
                self.dropped.append(dropped)
            if not subs:
                raise SdfError(f"mesh file {path} holds no valid triangles (every one has a NaN/infinite vertex, "
                               f"a bad index or zero area)")
            self._files[key] = subs
            self.reads += 1
        else:
            self.hits += 1
        return subs
