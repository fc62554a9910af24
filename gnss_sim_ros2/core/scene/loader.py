"""Read an SDF world (Gazebo) into one triangle mesh with a material class per triangle.

No libsdformat is usable from Python here, so the XML is read with lxml (leniently, as sdformat:
:mod:`.sdf_xml`) and the SDF specification (sdformat.org, SDF 1.7-1.11 "pose frame semantics") is
followed for what matters to line-of-sight:

* ``<world>`` -> ``<model>``, ``<include>``, ``<frame>``, ``<population>``; models nest; links hold
  ``<collision>`` (or ``<visual>`` with ``use_visuals=True``) with ``<geometry>``.
* ``<pose relative_to="...">x y z roll pitch yaw</pose>``: radians, or degrees with
  ``degrees="true"`` (SDF 1.9+); ``rotation_format="quat_xyzw"`` (7 values) too.  Rotation =
  Rz(yaw) Ry(pitch) Rx(roll).  Defaults: a model/link/nested model/include is relative to its parent
  model frame (the world for top-level models); a ``<frame>`` to its ``attached_to``; a
  collision/visual to its link; a joint to its child link.  ``relative_to`` may name any sibling
  frame, ``__model__``, ``world`` (at world scope) or a nested ``a::b`` name.
* A saved world's ``<state>`` places its top-level models (their ``<pose>`` there, world frame).
* ``<include>``: the URI is resolved as Gazebo does (:mod:`.uris`: ``model://``, Fuel from the local
  cache, ``file://``, ``package://``); ``<name>``, ``<pose>`` and ``<static>`` of the include override
  the model's own.  An include without geometry (``model://sun``, a ``<light>``) is left out quietly.
* Geometry: :mod:`.primitives` (box, sphere, cylinder, cone, capsule, ellipsoid, plane, polyline,
  heightmap) and meshes (:mod:`.mesh_files`: COLLADA, OBJ, STL, PLY, glTF/GLB, ``<scale>``,
  ``<submesh>`` with ``<center>``), each file read once.
* Only static geometry is an obstacle, by SDFormat's rule (sdformat.org ``model.sdf`` ``<static>``;
  libsdformat ``Model::Static``): a model is static when its ``<static>`` (or its include's) is true or it
  is inside a static model; a nested model keeps its own ``<static>`` otherwise.  The links of a model that
  is not static move in Gazebo (a robot, a box that falls) and are left out unless ``keep_dynamic``; its
  nested models are still walked, so a ``<model>`` without links of its own that wraps an ``<include>`` of
  a static model (the AWS RoboMaker worlds, the Hong Kong city world) keeps that model.  ``<actor>`` is
  left out (animated), and ``<road>`` (a flat visual in Gazebo).
* Partial worlds: a part that cannot be loaded (a missing mesh, an unresolved ``model://``, an uncached
  Fuel model, an unknown geometry) is recorded in the scene report (:mod:`.scene_report`); with
  ``strict=True`` (every front end's default, parameter ``strict_world``) the load then fails with one
  :class:`~.scene_report.PartialWorldError` naming the world, the part and why; without, each is skipped
  with one warning naming it and why.

Material classes: :mod:`.materials`; open foliage meshes become closed crowns: :mod:`.foliage`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .foliage import crown_volumes, is_closed
from .georeference import spherical_from_sdf
from .materials import MaterialTable, load_materials_yaml, parse_attenuation
from .mesh_files import MeshCache, SubMesh, pick_submesh
from .population import population_offsets
from .primitives import box, capsule, cone, cylinder, ellipsoid, heightmap, plane, polylines, sphere
from .scene_report import SceneReport
from .sdf_xml import SdfError, child, child_floats, children, local, ns, parse_pose, parse_xml, text, truthy, where
from .uris import UriResolver, model_sdf_path
from .world_mesh import WorldMesh, check_world_extent

_SHAPES = {"box": box, "sphere": sphere, "cylinder": cylinder, "cone": cone, "capsule": capsule,
           "ellipsoid": ellipsoid, "plane": plane}


def is_material_tag(c) -> bool:
    return isinstance(c.tag, str) and local(c.tag) in ("material", "gnss_material") and (
        "gnss_sim" in ns(c.tag).lower() or (not ns(c.tag) and c.tag == "gnss_material"))


def _script_name(g) -> str:
    """``<material><script><name>`` of a visual (an OGRE material name such as ``PineTree/Branch``)."""
    mat = child(g, "material")
    script = child(mat, "script") if mat is not None else None
    return text(child(script, "name")) if script is not None else ""


class _Scope:
    """Frames of one model (or the world): name -> (kind, element, file, pose element, static)."""

    def __init__(self, el, file: Path, is_world: bool, loader: _Loader, static: bool, prefix: str = ""):
        self.el = el
        self.file = file
        self.is_world = is_world
        self.loader = loader
        self.static = static
        self.frames: dict[str, tuple] = {}
        self.cache: dict[str, np.ndarray] = {}
        self.subscopes: dict[str, _Scope] = {}
        kinds = ("model", "include", "frame") if is_world else ("link", "model", "include", "frame", "joint")
        for c in el:
            if not isinstance(c.tag, str) or c.tag not in kinds:
                continue
            if c.tag == "include":
                got = loader.load_include(c, file, prefix)
                if got is None:
                    continue
                model_el, mfile, name, pose_el, inc_static = got
                entry = ("model", model_el, mfile, pose_el, static or inc_static)
            else:
                name = c.get("name")
                if not name:
                    raise SdfError(f"{where(c, file)}: <{c.tag}> without a name attribute")
                st = (static or truthy(text(child(c, "static"), "false"))) if c.tag == "model" else static
                entry = (c.tag, c, file, child(c, "pose"), st)
            if name in self.frames:
                raise SdfError(f"{where(c, file)}: duplicate name {name!r} in {where(el, file)}")
            self.frames[name] = entry

    def subscope(self, name: str, prefix: str) -> _Scope:
        if name not in self.subscopes:
            kind, el, mfile, _, st = self.frames[name]
            self.subscopes[name] = _Scope(el, mfile, False, self.loader, st, prefix)
        return self.subscopes[name]

    def resolve(self, name: str | None, stack=()) -> np.ndarray:
        """Pose of frame ``name`` in this scope's frame (the model frame, or the world)."""
        if name in (None, "", "__model__") or (self.is_world and name == "world"):
            return np.eye(4)
        if name in self.cache:
            return self.cache[name]
        if name in stack:
            raise SdfError(f"{where(self.el, self.file)}: cycle in relative_to/attached_to: "
                           f"{' -> '.join(stack + (name,))}")
        if "::" in name and name.split("::", 1)[0] in self.frames:
            head, rest = name.split("::", 1)
            if self.frames[head][0] != "model":
                raise SdfError(f"{where(self.el, self.file)}: {name!r}: {head!r} is not a nested model")
            T = self.resolve(head, stack) @ self.subscope(head, head).resolve(rest)
            self.cache[name] = T
            return T
        if name not in self.frames:
            raise SdfError(f"{where(self.el, self.file)}: relative_to/attached_to names unknown frame {name!r} "
                           f"(known: {sorted(self.frames) + ['__model__']})")
        kind, el, file, pose_el, _ = self.frames[name]
        P, rel = parse_pose(pose_el, file)
        if rel is None:
            if kind == "frame":
                rel = el.get("attached_to") or None
            elif kind == "joint":
                c = child(el, "child")
                rel = text(c) or None
        T = self.resolve(rel, stack + (name,)) @ P
        self.cache[name] = T
        return T


class _Loader:
    def __init__(self, table: MaterialTable, use_visuals: bool, user_rules: bool, world_dir: Path,
                 keep_dynamic: bool, strict: bool, seed: int):
        self.table = table
        self.use_visuals = use_visuals
        self.user_rules = user_rules
        self.keep_dynamic = keep_dynamic
        self.seed = seed
        self.uris = UriResolver(world_dir)
        self.meshes = MeshCache()
        self.report = SceneReport(strict=strict)
        self.verts: list[np.ndarray] = []
        self.tris: list[np.ndarray] = []
        self.mats: list[np.ndarray] = []
        self.parts: list[dict] = []
        self.n_verts = 0

    # ------------------------------------------------------------------ includes
    def load_include(self, inc_el, file: Path, prefix: str):
        """(model element, its file, name, pose element, static) or None when skipped / geometry-free."""
        uri_el = child(inc_el, "uri")
        name_el = child(inc_el, "name")
        label = f"{prefix + '::' if prefix else ''}{text(name_el) or text(uri_el) or '<include>'}"
        if uri_el is None:
            self.report.skip(f"{label} ({where(inc_el, file)})", "<include> without <uri>")
            return None
        try:
            target = self.uris.resolve(uri_el.text, file.parent, uri_el, file)
            sdf_path = model_sdf_path(target, uri_el, file) if target.is_dir() else target
            root = parse_xml(sdf_path)
        except SdfError as exc:
            self.report.skip_error(label, exc)
            return None
        model = root if local(root.tag) == "model" else child(root, "model")
        if model is None:
            kinds = sorted({local(c.tag) for c in root if isinstance(c.tag, str)})
            if kinds and set(kinds) <= {"light", "actor"}:
                what = "an animated <actor>" if "actor" in kinds else "a <light>"
                self.report.leave_out(label, f"{text(uri_el)} holds {what}, no static geometry")
            else:
                self.report.skip(label, f"{sdf_path}: included from {where(inc_el, file)} holds no <model> "
                                        f"(has {kinds})")
            return None
        name = text(name_el) or model.get("name")
        if not name:
            self.report.skip(label, f"{where(inc_el, file)}: included model has no name")
            return None
        pose_el = child(inc_el, "pose")
        if pose_el is None:
            pose_el = child(model, "pose")
        st_el = child(inc_el, "static")
        static = truthy(text(st_el)) if st_el is not None else truthy(text(child(model, "static"), "false"))
        for c in inc_el:                     # material tag on the include itself is carried to the model
            if is_material_tag(c):
                model.insert(0, c)
        return model, sdf_path, name, pose_el, static

    # ------------------------------------------------------------------ materials
    def material_for(self, scoped: str, chain: list[tuple], names_innermost_first: list[str],
                     surface: bool = False) -> int:
        """Class index of a part (rules of .materials); a ground surface (plane, heightmap) is opaque unless a
        rule or an element says otherwise: a "grass" field is ground, not a crown."""
        if self.user_rules:
            cls = self.table.match_rules(scoped)
            if cls is not None:
                return self.table.index(cls)
        for el, file in reversed(chain):       # innermost explicit tag wins
            for c in el:
                if is_material_tag(c):
                    name = (c.text or "").strip()
                    if not name:
                        raise SdfError(f"{where(c, file)}: empty material element")
                    att = c.get("attenuation_db_per_m")
                    if att is not None:
                        return self.table.declare(name, parse_attenuation(att, where(c, file)))
                    if not self.table.has(name):
                        raise SdfError(f"{where(c, file)}: unknown material class {name!r} (known: "
                                       f"{[k.name for k in self.table.classes]}; add attenuation_db_per_m=... "
                                       f"to declare it)")
                    return self.table.index(name)
        if surface:
            return self.table.index("opaque")
        return self.table.default_for_names(names_innermost_first)

    # ------------------------------------------------------------------ output
    def add(self, v: np.ndarray, f: np.ndarray, T: np.ndarray, mat: int, scoped: str):
        v = np.asarray(v, dtype=np.float64) @ T[:3, :3].T + T[:3, 3]
        f = np.asarray(f, dtype=np.int64)
        if len(f) == 0:
            return
        if np.linalg.det(T[:3, :3]) < 0:
            f = f[:, ::-1]
        cls = self.table.classes[mat]
        part = {"name": scoped, "class": cls.name, "triangles": int(len(f))}
        if not cls.opaque and not is_closed(v, f):
            crowns = crown_volumes(v, f)
            if not crowns:
                self.report.skip(scoped, f"{cls.name} mesh is flat (no volume to attenuate through)")
                return
            part.update(crown_volumes=len(crowns), source_triangles=int(len(f)),
                        triangles=int(sum(len(cf) for _, cf in crowns)))
            for cv, cf in crowns[:-1]:
                self._append(cv, cf, mat)
            v, f = crowns[-1]
        self._append(v, f, mat)
        self.parts.append(part)
        self.report.parts_loaded += 1

    def _append(self, v, f, mat):
        self.verts.append(v)
        self.tris.append(f + self.n_verts)
        self.mats.append(np.full(len(f), mat, dtype=np.int16))
        self.n_verts += len(v)

    # ------------------------------------------------------------------ geometry
    def geometry(self, geom_el, file: Path) -> list[tuple[str, np.ndarray, np.ndarray, list[str], bool]]:
        """``<geometry>`` -> [(submesh label, vertices, faces, names, ground surface)] in the collision/visual
        frame."""
        shapes = [c for c in geom_el if isinstance(c.tag, str) and not ns(c.tag)]
        if not shapes:
            raise SdfError(f"{where(geom_el, file)}: <geometry> holds no shape")
        out = []
        polys = [s for s in shapes if s.tag == "polyline"]
        if polys:                                      # all polylines of a geometry make one solid (holes)
            m = polylines(polys, file)
            out.append(("", np.asarray(m.vertices), np.asarray(m.faces), [], False))
        for s in shapes:
            kind = s.tag
            if kind == "polyline":
                continue
            if kind in _SHAPES:
                m = _SHAPES[kind](s, file)
                out.append(("", np.asarray(m.vertices), np.asarray(m.faces), [], kind == "plane"))
            elif kind == "mesh":
                out.extend(self.mesh(s, file))
            elif kind == "heightmap":
                m = heightmap(s, file, lambda el: self.uris.resolve(el.text, file.parent, el, file))
                out.append(("", np.asarray(m.vertices), np.asarray(m.faces), [], True))
            elif kind == "empty":
                continue
            else:
                raise SdfError(f"{where(s, file)}: geometry <{kind}> is not supported")
        return out

    def mesh(self, s, file: Path):
        uri_el = child(s, "uri")
        if uri_el is None:
            raise SdfError(f"{where(s, file)}: <mesh> without <uri>")
        path = self.uris.resolve(uri_el.text, file.parent, uri_el, file)
        try:
            subs: list[SubMesh] = self.meshes.get(path)
        except SdfError as exc:
            raise SdfError(f"{where(uri_el, file)}: {exc}") from exc
        sub_el = child(s, "submesh")
        if sub_el is not None and text(child(sub_el, "name")):
            subs = pick_submesh(subs, text(child(sub_el, "name")), truthy(text(child(sub_el, "center"), "false")),
                                path)
        scale = child_floats(s, "scale", file, 3, default=(1, 1, 1))
        if min(abs(x) for x in scale) == 0:
            raise SdfError(f"{where(s, file)}: mesh <scale> must be non-zero, got {scale}")
        S = np.asarray(scale, dtype=np.float64)
        flip = np.prod(np.sign(S)) < 0
        out = []
        for sm in subs:
            f = sm.faces[:, ::-1] if flip else sm.faces
            out.append((sm.name if len(subs) > 1 else "", sm.vertices_m * S, f, sm.names, False))
        return out

    # ------------------------------------------------------------------ walking
    def walk_model(self, scope: _Scope, T_world_model: np.ndarray, prefix: str, chain: list, names: list):
        """The links of a model (static, or ``keep_dynamic``) and its nested models, each by its own ``<static>``
        (SDFormat: a nested model keeps its own; a static model makes its nested content static): a model
        without links of its own that wraps static models moves nothing."""
        file = scope.file
        dynamic = not scope.static and not self.keep_dynamic
        if dynamic and any(e[0] == "link" for e in scope.frames.values()):
            self.report.leave_out(prefix, "not static (it moves in Gazebo); keep_dynamic keeps it")
        for name, (kind, cel, cfile, _, _st) in scope.frames.items():
            scoped_name = f"{prefix}::{name}"
            try:
                if kind == "model":
                    sub = scope.subscope(name, scoped_name)
                    T = T_world_model @ scope.resolve(name)
                    self.walk_model(sub, T, scoped_name, chain + [(cel, cfile)], [name] + names)
                elif kind == "link" and not dynamic:
                    self.walk_link(scope, name, cel, file, T_world_model, prefix, chain, names)
            except SdfError as exc:
                self.report.skip_error(scoped_name, exc)

    def walk_link(self, scope, name, cel, file, T_world_model, prefix, chain, names):
        T_link = T_world_model @ scope.resolve(name)
        tag = "visual" if self.use_visuals else "collision"
        for g in children(cel, tag):
            gname = g.get("name") or tag
            scoped = f"{prefix}::{name}::{gname}"
            try:
                P, rel = parse_pose(child(g, "pose"), file)
                T = T_link @ P if rel is None or rel == name else T_world_model @ scope.resolve(rel) @ P
                geom = child(g, "geometry")
                if geom is None:
                    raise SdfError(f"{where(g, file)}: <{tag}> without <geometry>")
                script = _script_name(g)
                items = self.geometry(geom, file)
            except SdfError as exc:
                self.report.skip_error(scoped, exc)
                continue
            for label, v, f, sub_names, surface in items:
                part = f"{scoped}::{label}" if label else scoped
                inner = list(sub_names) + ([script] if script else []) + [gname, name] + names
                mat = self.material_for(part, chain + [(cel, file), (g, file)], inner, surface)
                self.add(v, f, T, mat, part)

    def world(self, world_el, file: Path):
        scope = _Scope(world_el, file, True, self, static=False)
        self.apply_state(scope, world_el, file)
        for name, (kind, el, mfile, _, _st) in scope.frames.items():
            if kind != "model":
                continue
            try:
                T = scope.resolve(name)
                self.walk_model(scope.subscope(name, name), T, name, [(el, mfile)], [name])
            except SdfError as exc:
                self.report.skip_error(name, exc)
        for c in world_el:
            if not isinstance(c.tag, str):
                continue
            if c.tag == "population":
                self.population(c, file)
            elif c.tag == "actor":
                self.report.leave_out(c.get("name") or "<actor>", "an animated <actor>, no static geometry")
            elif c.tag == "road":
                self.report.leave_out(f"<road name={c.get('name')!r}>", "a flat road surface (a visual only in "
                                                                        "Gazebo), no obstacle")

    def apply_state(self, scope: _Scope, world_el, file: Path):
        """A saved world's ``<state>``: its top-level ``<model><pose>`` (world frame) replace the models' poses,
        as Gazebo places them when it loads the world (the last ``<state>`` wins)."""
        for state in children(world_el, "state"):
            for m in children(state, "model"):
                name, pose_el = m.get("name"), child(m, "pose")
                if pose_el is None or name not in scope.frames:
                    continue
                kind, el, mfile, _, st = scope.frames[name]
                if kind == "model":
                    scope.frames[name] = (kind, el, file, pose_el, st)

    def population(self, pop_el, file: Path):
        pname = pop_el.get("name") or "population"
        try:
            holder = _Scope(pop_el, file, True, self, static=False, prefix=pname)
            models = [(n, e) for n, e in holder.frames.items() if e[0] == "model"]
            if len(models) != 1:
                raise SdfError(f"{where(pop_el, file)}: a <population> needs exactly one <model> or <include>, "
                               f"has {len(models)}")
            mname, (_, mel, mfile, mpose_el, _) = models[0]
            T_pop, _ = parse_pose(child(pop_el, "pose"), file)
            T_model, _ = parse_pose(mpose_el, mfile)
            offsets = population_offsets(pop_el, file, self.seed)
        except SdfError as exc:
            self.report.skip_error(pname, exc)
            return
        # copies are static obstacles: a population places scenery (trees, cans) where Gazebo spawns it
        for k, off in enumerate(offsets):
            T_off = np.eye(4)
            T_off[:3, 3] = off
            T = T_pop @ T_off @ T_model
            T[:3, 3] = (T_pop @ np.r_[off, 1.0])[:3]
            inst = f"{pname}::{mname}_{k}"
            try:
                sub = _Scope(mel, mfile, False, self, True, inst)
                self.walk_model(sub, T, inst, [(pop_el, file), (mel, mfile)], [mname, pname])
            except SdfError as exc:
                self.report.skip_error(inst, exc)

    def result(self, sph, source: str) -> WorldMesh:
        if self.verts:
            verts = np.vstack(self.verts)
            tris = np.vstack(self.tris)
            mats = np.concatenate(self.mats)
        else:
            verts, tris, mats = np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int16)
        self.report.dropped = list(self.meshes.dropped)
        self.report.raise_if_partial(source)
        check_world_extent(verts, f"world {source}")
        self.report.warn_left_out_dynamic()
        self.report.mesh_files_read = self.meshes.reads
        self.report.mesh_cache_hits = self.meshes.hits
        world = WorldMesh(verts, tris, mats, self.table, sph, self.parts, source)
        world.report = self.report.to_dict(world.class_counts())
        return world


def load_sdf_world(sdf_path, materials_yaml=None, use_visuals: bool = False,
                   materials: MaterialTable | None = None, *, keep_dynamic: bool = False, strict: bool = False,
                   seed: int = 0) -> WorldMesh:
    """Read an SDF world (or a single-model SDF file) into a :class:`WorldMesh` in the world frame.

    ``materials_yaml``: optional YAML of classes and name rules; ``use_visuals``: take ``<visual>``
    geometry instead of ``<collision>``; ``keep_dynamic``: keep non-static models; ``strict``: a part
    that cannot be loaded makes the load fail (:class:`~.scene_report.PartialWorldError`) instead of a
    skip; ``seed``: of random populations.
    """
    sdf_path = Path(sdf_path)
    if materials is not None:
        table, user_rules = materials, bool(materials.rules)
    elif materials_yaml is not None:
        table, user_rules = load_materials_yaml(materials_yaml), True
    else:
        table, user_rules = MaterialTable(), False
    root = parse_xml(sdf_path)
    if local(root.tag) != "sdf":
        raise SdfError(f"{where(root, sdf_path)}: root element must be <sdf>, got <{local(root.tag)}>")
    loader = _Loader(table, use_visuals, user_rules, sdf_path.parent, keep_dynamic, strict, seed)
    world = child(root, "world")
    sph = None
    if world is not None:
        sph = spherical_from_sdf(world, sdf_path)
        loader.world(world, sdf_path)
    else:
        model = child(root, "model")
        if model is None:
            raise SdfError(f"{where(root, sdf_path)}: holds neither <world> nor <model>")
        name = model.get("name") or "model"
        T, _ = parse_pose(child(model, "pose"), sdf_path)
        # a single model file is loaded as the obstacle it describes, static or not
        loader.walk_model(_Scope(model, sdf_path, False, loader, True, name), T, name, [(model, sdf_path)], [name])
    return loader.result(sph, str(sdf_path))
