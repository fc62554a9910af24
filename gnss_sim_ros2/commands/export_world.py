"""``gnss-sim export-world WORLD.sdf --out MESH.ply [--materials FILE.yaml] [--visuals] [--allow-partial]
[--keep-dynamic]``.

Reads a Gazebo SDF world (collision geometry, or visuals with ``--visuals``) as Gazebo loads it (URIs
from the resource paths and the local Fuel cache), assigns a material class to every triangle
(opaque / foliage / user classes) and writes a PLY mesh plus its ``.scene.yaml`` sidecar (geodetic
origin, material table, scene report): see gnss_sim_ros2/core/scene/mesh_io.py.  A part that cannot be
loaded (a ``model://`` not found, a missing mesh) is an error naming the world, the part and why, as in
every command that loads a world (parameter ``strict_world``); ``--allow-partial`` skips it with a warning
and lists it in the scene report.  ``--strict`` (the default) is accepted for old scripts.
"""
from __future__ import annotations

import sys
import warnings

from gnss_sim_ros2.core.scene.scene_report import ALLOW_PARTIAL_HELP


def add_arguments(parser):
    parser.add_argument("world", metavar="WORLD.sdf", help="SDF world file")
    parser.add_argument("--out", required=True, metavar="MESH.ply",
                        help="output mesh (PLY); sidecar written beside (both renamed into place when complete)")
    parser.add_argument("--materials", metavar="FILE.yaml", help="material classes and name rules (fnmatch)")
    parser.add_argument("--visuals", action="store_true", help="use <visual> instead of <collision> geometry")
    parser.add_argument("--allow-partial", action="store_true", help=ALLOW_PARTIAL_HELP)
    parser.add_argument("--strict", action="store_true",
                        help="a part that cannot be loaded is an error: the default (kept for old scripts)")
    parser.add_argument("--keep-dynamic", action="store_true",
                        help="keep non-static models (robots, movable objects) as obstacles")
    parser.add_argument("--seed", type=int, default=0, help="seed of random <population> placement (default 0)")


def run(args) -> int:
    from gnss_sim_ros2.core.output_folder import check_unnamed_output, staged_files
    from gnss_sim_ros2.core.scene.mesh_files import DroppedTrianglesWarning
    from gnss_sim_ros2.core.scene.mesh_io import SCENE_FORMAT, check_mesh_name, export_world, sidecar_path
    from gnss_sim_ros2.core.scene.scene_report import LeftOutWarning, SceneWarning, report_lines
    from gnss_sim_ros2.parameters import SHARED_KEY, param

    try:
        if args.strict and args.allow_partial:
            raise ValueError("options --strict and --allow-partial contradict each other: give one of them")
        check_mesh_name(args.out, f"option --out {args.out}")     # before the world is loaded (and '/' too)
        param(SHARED_KEY, "seed").check(args.seed, "option --seed")    # a seed as every seed: 0..2**63-1
        # the mesh and its sidecar written beside, renamed when both are complete; never over an input
        with warnings.catch_warnings(), staged_files([("--out", args.out), ("--out (sidecar)", sidecar_path(args.out))],
                                                     inputs=[args.world, args.materials]) as temp:
            # the sidecar beside replaces only a sidecar (a user's file of that name is refused)
            check_unnamed_output(sidecar_path(args.out), "--out", f"format: {SCENE_FORMAT}")
            # each skip, left-out model and dropped triangle is listed once in the scene report below
            for category in (SceneWarning, LeftOutWarning, DroppedTrianglesWarning):
                warnings.simplefilter("ignore", category)
            world = export_world(args.world, temp[args.out], materials_yaml=args.materials, use_visuals=args.visuals,
                                 keep_dynamic=args.keep_dynamic, strict=strict_world(args), seed=args.seed)
    except ValueError as exc:
        print(f"gnss-sim export-world: error: {exc}", file=sys.stderr)
        return 2
    counts = ", ".join(f"{k} {v}" for k, v in world.class_counts().items())
    print(f"{args.out}: {len(world.triangles)} triangles ({counts}) from {len(world.parts)} parts")
    for line in report_lines(world.report):
        print(line)
    sph = world.spherical_coordinates
    if sph is None:
        print("warning: the world has no <spherical_coordinates>: satellites cannot be placed in it",
              file=sys.stderr)
    else:
        print(f"origin lat {sph.latitude_deg:.7f} lon {sph.longitude_deg:.7f} h {sph.elevation_m:.2f} m "
              f"heading {sph.heading_deg:g} deg")
    print(f"sidecar: {sidecar_path(args.out)}")
    return 0


def strict_world(args) -> bool:
    """Parameter strict_world of a command's ``--allow-partial`` (the parameter table's default without it)."""
    from gnss_sim_ros2.parameters import params_of

    if getattr(args, "allow_partial", False):
        return False
    return bool(next(p.default for p in params_of("visibility") if p.name == "strict_world"))
