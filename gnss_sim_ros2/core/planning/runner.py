"""Running a plan's blocks of cells: in this process, or on a Dask cluster (the client the caller connected,
``commands/plan.py`` through core/sweep's cluster helpers).  A worker loads the scene once from its
description (``SceneSpec``: the files, not the Open3D scene, travel) and keeps it for the next blocks."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .quality import FIELDS, PlanInputs, cell_blocks, quality_block

#: scenes this process loaded for plan blocks, by their description
_SCENES: dict = {}


@dataclass(frozen=True)
class SceneSpec:
    """Where the scene of a plan comes from: a world (SDF), a mesh, or a sky mask at a geodetic point."""

    world: str = ""
    mesh: str = ""
    materials: str = ""
    strict_world: bool = True
    keep_dynamic: bool = False
    sky_mask: str = ""
    origin_llh: tuple = ()

    def load(self):
        scene = _SCENES.get(self)
        if scene is None:
            if self.sky_mask:
                from ..visibility.sky_mask import SkyMaskScene, read_sky_mask

                scene = SkyMaskScene(read_sky_mask(self.sky_mask), self.origin_llh)
            else:
                from ..visibility import VisibilityOptions, load_scene

                scene = load_scene(self.world, self.mesh, self.materials,
                                   VisibilityOptions(strict_world=self.strict_world,
                                                     keep_dynamic=self.keep_dynamic))
            _SCENES.clear()                   # one scene per process at a time
            _SCENES[self] = scene
        return scene


def _block(spec: SceneSpec, vis, ant, inp: PlanInputs):
    stats: dict = {}
    t0 = time.perf_counter()
    out = quality_block(spec.load(), vis, ant, inp, stats)
    stats["wall_s"] = time.perf_counter() - t0
    return out, stats


def run_blocks(spec: SceneSpec, vis, antenna_world_m, inp: PlanInputs, client=None, log=None):
    """(fields {name: (C, T)}, stats {rays, cast_s, wall_s, blocks}) over every cell of ``antenna_world_m``."""
    ant = np.asarray(antenna_world_m, float)
    n_t, n_s = inp.sat_pos_ecef_m.shape[:2]
    blocks = cell_blocks(len(ant), n_t, n_s, inp.max_rays)
    out = {k: np.zeros((len(ant), n_t), dt) for k, dt in FIELDS.items()}
    total = {"rays": 0, "cast_s": 0.0, "blocks": len(blocks)}

    def take(sl, res):
        vals, st = res
        for k in FIELDS:
            out[k][sl] = vals[k]
        total["rays"] += st.get("rays", 0)
        total["cast_s"] += st.get("cast_s", 0.0)

    t0 = time.perf_counter()
    if client is None:
        for i, sl in enumerate(blocks):
            take(sl, _block(spec, vis, ant[sl], inp))
            if log is not None:
                log(f"block {i + 1}/{len(blocks)}: {sl.stop} of {len(ant)} cells, "
                    f"{time.perf_counter() - t0:.1f} s")
    else:
        from distributed import as_completed

        inp_f = client.scatter(inp, broadcast=True)
        futs = {client.submit(_block, spec, vis, ant[sl], inp_f, pure=False): sl for sl in blocks}
        for n, fut in enumerate(as_completed(futs), start=1):
            take(futs[fut], fut.result())
            if log is not None:
                log(f"block {n}/{len(blocks)} done, {time.perf_counter() - t0:.1f} s")
    total["wall_s"] = time.perf_counter() - t0
    return out, total
