"""The raycasting scene of a world or mesh file (:func:`load_scene`) and the process's shared scenes: the
visibility nodes of several robots composed in one process load one world once."""
from __future__ import annotations

import weakref
from pathlib import Path

from .options import VisibilityOptions


def load_scene(world_file: str = "", mesh_file: str = "", materials_file: str = "",
               options: VisibilityOptions | None = None, *, shared: bool = False):
    """The raycasting scene from an exported mesh or an SDF world (None when neither is given); ``options``:
    visual or collision geometry, non-static models, strictness (VisibilityOptions; default: their defaults).

    ``shared``: the process's scene of the same files and options if one is still held (the visibility nodes of
    several robots composed in one process share one world: parsed and built once); keyed by each file's path,
    modification time and size (a world edited between two loads is read again; the meshes it includes are not
    part of the key) and the options.  The scene is held only as long as some caller holds it."""
    if not world_file and not mesh_file:
        return None
    if shared:
        key = (_file_key(mesh_file) if mesh_file else None, None if mesh_file else _file_key(world_file),
               None if mesh_file else _file_key(materials_file), _scene_options_key(options, bool(mesh_file)))
        scene = _SHARED_SCENES.get(key)
        if scene is not None:
            SCENE_LOADS["shared"] += 1
            return scene
        scene = load_scene(world_file, mesh_file, materials_file, options)
        _SHARED_SCENES[key] = scene
        return scene
    from ..scene.visibility import Scene  # Open3D: imported with the first scene only

    SCENE_LOADS["loaded"] += 1
    if mesh_file:
        return Scene.load(mesh_file)
    o = options or VisibilityOptions()
    return Scene.from_sdf(world_file, materials_yaml=materials_file or None, use_visuals=o.use_visuals,
                          keep_dynamic=o.keep_dynamic, strict=o.strict_world)


#: scenes of load_scene(shared=True) still held by someone (weak: freed with their last holder)
_SHARED_SCENES: weakref.WeakValueDictionary = weakref.WeakValueDictionary()
#: scenes this process built ("loaded") and handed out again ("shared"): a run with several robots reports them
SCENE_LOADS = {"loaded": 0, "shared": 0}


def _file_key(path: str):
    if not path:
        return None
    p = Path(path).resolve()
    try:
        st = p.stat()
    except OSError:
        return (str(p), None, None)          # the load itself names the missing file
    return (str(p), st.st_mtime_ns, st.st_size)


def _scene_options_key(options: VisibilityOptions | None, mesh: bool):
    """The options that change the loaded scene (the cast options do not: they are the caller's)."""
    if mesh:
        return None
    o = options or VisibilityOptions()
    return (bool(o.use_visuals), bool(o.keep_dynamic), bool(o.strict_world))
