"""Benchmark of world loading: triangles, load time and peak memory per world.

Cases (each loaded in a fresh process, so the peak resident memory is its own):
  * a generated city of about 400,000 triangles written as a Gazebo world: 24 building mesh files
    (COLLADA and OBJ, 5,120 triangles each) used by 75 included models (each file read once), 600
    primitive parts (street furniture) and, when ../shared/worlds is present, 40 pine_tree includes
    (open leaf meshes made closed crowns);
  * the same city scaled to about 2,000,000 triangles (375 building instances);
  * a farm exported as one mesh: 100 billboard trees (400,000 open leaf triangles in one mesh node, made
    100 closed crowns) and their trunks;
  * every world of ../shared/worlds/gz-sim (Fuel models from --fuel-cache, else those parts are skipped)
    and a world including every model of ../shared/worlds/models (when present).

Figures printed: triangles, parts, load time (load_sdf_world: the first load in the process, which
includes the lazy imports of trimesh and pycollada, and the best of --repeat), peak RSS of the process
after loading minus before (+MB) and in all (peak MB, the interpreter and imports included).
Targets (issue 15): 400k triangles under 5 s, 2 M under 1 GB.

    .venv/bin/python bench/bench_world_loading.py [--repeat 3] [--fuel-cache DIR]
    .venv/bin/python bench/bench_world_loading.py --robots 4     # N robots' scenes: shared against not

``--robots N``: the city of ~400k triangles as N composed visibility nodes load it (``load_scene``, the
Open3D scene built too), each way in a fresh process: ``shared=True`` (gnss-sim run --robots N: one
scene) against N scenes of their own; load time and +MB.
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import resource
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "worlds"


def _building_mesh(k: int):
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=4, radius=1.0)        # 5,120 triangles
    rng = np.random.default_rng(k)
    m.apply_scale((rng.uniform(8, 20), rng.uniform(8, 20), rng.uniform(10, 40)))
    m.apply_translation((0, 0, m.bounds[1][2]))
    return m


def write_city(folder: Path, instances: int, with_pines: bool) -> Path:
    """A city world in ``folder``: building models in ``folder/models``; returns the world file."""
    import trimesh

    models = folder / "models"
    for k in range(24):
        d = models / f"building_{k}"
        (d / "meshes").mkdir(parents=True, exist_ok=True)
        ext = "dae" if k % 2 == 0 else "obj"
        mesh = _building_mesh(k)
        if ext == "dae":
            (d / "meshes" / f"b.{ext}").write_bytes(trimesh.exchange.dae.export_collada(mesh))
        else:
            mesh.export(d / "meshes" / f"b.{ext}")
        (d / "model.config").write_text(f'<model><name>building_{k}</name><sdf version="1.9">model.sdf</sdf></model>')
        (d / "model.sdf").write_text(f'<sdf version="1.9"><model name="building_{k}"><static>true</static>'
                                     f'<link name="link"><collision name="collision"><geometry><mesh>'
                                     f'<uri>model://building_{k}/meshes/b.{ext}</uri></mesh></geometry></collision>'
                                     f'</link></model></sdf>')
    rng = np.random.default_rng(0)
    parts = ['<model name="ground"><static>true</static><link name="l"><collision name="c"><geometry><plane>'
             '<normal>0 0 1</normal><size>2000 2000</size></plane></geometry></collision></link></model>']
    side = int(np.ceil(np.sqrt(instances)))
    for i in range(instances):
        x, y = (i % side) * 60.0 - 1000.0, (i // side) * 60.0 - 1000.0
        parts.append(f'<include><uri>model://building_{i % 24}</uri><name>b{i}</name>'
                     f'<pose>{x} {y} 0 0 0 {rng.uniform(0, 3.14):.3f}</pose></include>')
    for i in range(600):
        x, y = rng.uniform(-1000, 1000, 2)
        shape = ("<box><size>0.5 0.5 1</size></box>" if i % 2 else
                 "<cylinder><radius>0.1</radius><length>4</length></cylinder>")
        parts.append(f'<model name="f{i}"><static>true</static><pose>{x:.2f} {y:.2f} 0 0 0 0</pose><link name="l">'
                     f'<collision name="c"><geometry>{shape}</geometry></collision></link></model>')
    if with_pines:
        for i in range(40):
            parts.append(f'<include><uri>model://pine_tree</uri><name>pine{i}</name>'
                         f'<pose>{i * 25.0 - 500} 30 0 0 0 0</pose></include>')
    w = folder / "city.sdf"
    w.write_text('<?xml version="1.0"?>\n<sdf version="1.9"><world name="city">'
                 '<spherical_coordinates><latitude_deg>50.0764</latitude_deg><longitude_deg>14.4179</longitude_deg>'
                 '<elevation>250</elevation></spherical_coordinates>' + "\n".join(parts) + "</world></sdf>\n")
    return w


def write_farm(folder: Path, trees: int = 100, quads: int = 2000) -> Path:
    """A farm exported as one mesh (as Clearpath's agriculture world): one GLB whose node "Leaves" holds
    ``trees`` x ``quads`` open leaf cards (billboard crowns of radius 3.3 m, 10 m apart) and "Trunks"."""
    import trimesh

    rng = np.random.default_rng(5)
    verts, faces = [], []
    for k in range(trees):
        centre = np.array([(k % 10) * 10.0, (k // 10) * 10.0, 6.0])
        p = rng.normal(size=(quads, 3))
        p *= (3.0 * rng.random(quads) ** (1 / 3) / np.linalg.norm(p, axis=1))[:, None]
        u, w = rng.normal(size=(2, quads, 3)) * 0.17
        base = len(verts) * 4 * quads
        q = np.stack([p, p + u, p + u + w, p + w], axis=1) + centre
        verts.append(q.reshape(-1, 3))
        i = base + 4 * np.arange(quads)[:, None]
        faces.append(np.vstack([np.c_[i, i + 1, i + 2], np.c_[i, i + 2, i + 3]]))
    trunk = trimesh.creation.cylinder(radius=0.3, height=3.0, sections=16)
    trunks = [trunk.copy().apply_translation(((k % 10) * 10.0, (k // 10) * 10.0, 1.5)) for k in range(trees)]
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.Trimesh(np.vstack(verts), np.vstack(faces), process=False), node_name="Leaves",
                       geom_name="Leaves")
    scene.add_geometry(trimesh.util.concatenate(trunks), node_name="Trunks", geom_name="Trunks")
    scene.export(folder / "farm.glb")
    w = folder / "farm.sdf"
    w.write_text('<sdf version="1.9"><world name="farm"><model name="farm"><static>true</static><link name="l">'
                 '<collision name="c"><geometry><mesh><uri>farm.glb</uri></mesh></geometry></collision></link>'
                 '</model></world></sdf>')
    return w


def _peak_rss_mb() -> float:
    """VmHWM of this process (Linux): its own peak, unlike ru_maxrss, which a spawned child inherits from the
    parent it was forked from."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return float(line.split()[1]) / 1024.0
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _measure(args):
    path, env, repeat = args
    os.environ.update(env)
    from gnss_sim_ros2.core.scene.loader import load_sdf_world

    warnings.simplefilter("ignore")
    rss0 = _peak_rss_mb()
    times = []
    world = None
    for _ in range(repeat):
        world = None
        t0 = time.perf_counter()
        world = load_sdf_world(path)
        times.append(time.perf_counter() - t0)
    rss1 = _peak_rss_mb()
    rep = world.report
    return (len(world.triangles), len(world.parts), times[0], min(times), (rss1 - rss0, rss1), world.class_counts(),
            len(rep["skipped"]), rep["mesh_files_read"])


def _measure_robots(args):
    path, env, robots, shared = args
    os.environ.update(env)
    from gnss_sim_ros2.core.visibility import load_scene

    warnings.simplefilter("ignore")
    import open3d  # noqa: F401 - imported before the first figure: the loads alone are measured
    rss0 = _peak_rss_mb()
    t0 = time.perf_counter()
    scenes = [load_scene(path, shared=shared) for _ in range(robots)]
    t = time.perf_counter() - t0
    rss1 = _peak_rss_mb()
    return t, rss1 - rss0, rss1, len({id(x) for x in scenes})


def run_robots(path, env, robots: int, ctx):
    print(f"{robots} robots' scenes, {path.name}: {'':<10} {'load s':>7} {'+MB':>8} {'peak MB':>8} scenes")
    for shared in (False, True):
        with ctx.Pool(1) as pool:
            t, plus, peak, n = pool.apply(_measure_robots, ((str(path), env, robots, shared),))
        print(f"  {'shared (one scene)' if shared else 'each its own':<34} {t:>7.2f} {plus:>8.0f} {peak:>8.0f} {n}")


def run_case(name, path, env, repeat, pool):
    tri, parts, t0, t, mem, counts, skipped, files = pool.apply(_measure, ((str(path), env, repeat),))
    cls = ", ".join(f"{k} {v}" for k, v in counts.items() if v)
    print(f"{name:<22} {tri:>10,} {parts:>6} {t0:>7.2f} {t:>7.2f} {mem[0]:>8.0f} {mem[1]:>8.0f}  {skipped:>2} skipped, "
          f"{files} mesh files; {cls}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--fuel-cache", metavar="DIR", help="local Fuel cache for the gz-sim worlds' Fuel models "
                                                       "(e.g. the one test_world_gazebo lays out); default: none")
    ap.add_argument("--robots", type=int, default=0, metavar="N",
                    help="only: N robots' scenes of the ~400k city, shared against each its own")
    args = ap.parse_args(argv)
    shared = SHARED.is_dir()
    ctx = mp.get_context("spawn")
    with tempfile.TemporaryDirectory(prefix="gnss_sim_bench_world_") as tmp:
        tmp = Path(tmp)
        models_path = os.pathsep.join([str(tmp / "c400" / "models")] + ([str(SHARED / "models")] if shared else []))
        c400 = write_city(tmp / "c400", 75, shared)
        if args.robots > 0:
            run_robots(c400, {"GZ_SIM_RESOURCE_PATH": models_path}, args.robots, ctx)
            return
        print(f"{'world':<22} {'triangles':>10} {'parts':>6} {'first s':>7} {'best s':>7} {'+MB':>8} {'peak MB':>8}")
        models_2m = os.pathsep.join([str(tmp / "c2m" / "models")] + ([str(SHARED / "models")] if shared else []))
        c2m = write_city(tmp / "c2m", 375, shared)
        (tmp / "farm").mkdir()
        farm = write_farm(tmp / "farm")
        for name, path, env in (("city ~400k", c400, {"GZ_SIM_RESOURCE_PATH": models_path}),
                                ("city ~2M", c2m, {"GZ_SIM_RESOURCE_PATH": models_2m}),
                                ("farm, 100 billboard trees", farm, {})):
            with ctx.Pool(1) as pool:
                run_case(name, path, env, args.repeat, pool)
        if shared:
            own = tmp / "all_models.sdf"
            names = sorted(p.name for p in (SHARED / "models").iterdir() if (p / "model.config").is_file())
            own.write_text('<sdf version="1.9"><world name="all">' + "".join(
                f"<include><uri>model://{n}</uri><pose>{40 * k} 0 0 0 0 0</pose></include>"
                for k, n in enumerate(names)) + "</world></sdf>")
            cases = [("all shared models", own)] + [(p.name, p) for p in sorted((SHARED / "gz-sim").glob("*.sdf"))]
            env = {"GAZEBO_MODEL_PATH": str(SHARED / "models"),
                   "GZ_FUEL_CACHE_PATH": args.fuel_cache or str(tmp / "no_fuel_cache")}
            for name, path in cases:
                with ctx.Pool(1) as pool:
                    run_case(name, path, env, args.repeat, pool)
        else:
            print(f"({SHARED} absent: the shared worlds are not measured)")


if __name__ == "__main__":
    main()
