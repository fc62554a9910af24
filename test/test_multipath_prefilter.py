"""Facets.may_reach, the bounding-sphere filter of the image-method candidates (reflections.py), drops only
candidates the exact test rejects: the paths found with it are those found without it, bit for bit."""
from __future__ import annotations

import numpy as np
from multipath_scenes import canyon_scene

from gnss_sim_ros2.core.multipath import reflections
from gnss_sim_ros2.core.multipath.scene_paths import facets_of
from gnss_sim_ros2.core.scene.demo_world import demo_world_path
from gnss_sim_ros2.core.visibility import load_scene


def _directions(m, rng):
    """(m, 48, 3) unit directions above the horizon, a grid jittered per antenna."""
    az, el = np.meshgrid(np.radians(np.arange(0.0, 360.0, 30.0)), np.radians([8.0, 25.0, 45.0, 75.0]))
    az = az.ravel()[None, :] + rng.uniform(0, 0.5, (m, az.size))
    el = el.ravel()[None, :] + rng.uniform(0, 0.1, (m, el.size))
    return np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=-1)


def _paths(scene, facets, ant, dirs):
    return reflections.find_paths(scene, facets, ant, dirs, max_range_m=100.0, max_paths=3, bounces=2)


def test_filter_keeps_every_path(monkeypatch):
    rng = np.random.default_rng(11)
    for scene, ant in ((canyon_scene(latitude_deg=22.3), np.c_[rng.uniform(-8, 8, 40), rng.uniform(-150, 150, 40),
                                                                  rng.uniform(1, 6, 40)]),
                       (load_scene(str(demo_world_path()), ""), np.c_[rng.uniform(-30, 30, 40),
                                                                     rng.uniform(-30, 30, 40), np.full(40, 1.5)])):
        facets = facets_of(scene)
        dirs = _directions(len(ant), rng)
        with_filter = _paths(scene, facets, ant, dirs)
        monkeypatch.setattr(reflections.Facets, "may_reach",
                            lambda self, fi, origin, u: np.ones((len(u), len(fi)), dtype=bool))
        without = _paths(scene, facets, ant, dirs)
        monkeypatch.undo()
        assert np.isfinite(with_filter.excess_m).sum() > 50          # single and double bounces found
        for f in ("excess_m", "gamma_co", "gamma_cross", "arrival_el_deg"):
            assert getattr(with_filter, f).tobytes() == getattr(without, f).tobytes(), f
        assert with_filter.rays_cast == without.rays_cast


def test_filter_drops_rays_that_miss_the_sphere_and_keeps_those_through_the_triangle():
    facets = facets_of(canyon_scene(latitude_deg=22.3))
    rng = np.random.default_rng(2)
    fi = rng.integers(0, len(facets), 200)
    origin = facets.centroid[fi] + facets.normal[fi] * (facets.radius[fi] + rng.uniform(1, 50, 200))[:, None]
    # rays towards a point of each triangle (barycentric inside) and rays pointing away from it
    s, t = rng.uniform(0, 1, (2, 200))
    s, t = np.where(s + t > 1, 1 - s, s), np.where(s + t > 1, 1 - t, t)
    target = facets.v0[fi] + s[:, None] * facets.e1[fi] + t[:, None] * facets.e2[fi]
    toward = (target - origin) / np.linalg.norm(target - origin, axis=1)[:, None]
    keep = facets.may_reach(fi, origin, np.r_[toward, -toward])
    assert keep[np.arange(200), np.arange(200)].all()
    assert not keep[200 + np.arange(200), np.arange(200)].any()


def test_near_through_the_kd_tree_equals_the_scan_of_every_facet(monkeypatch):
    facets = facets_of(load_scene(str(demo_world_path()), ""))
    rng = np.random.default_rng(4)
    ant = np.c_[rng.uniform(-80, 80, 30), rng.uniform(-80, 80, 30), rng.uniform(0.5, 20, 30)]
    scan = [facets.near(a, r) for a in ant for r in (15.0, 60.0, 100.0)]
    monkeypatch.setattr(reflections, "TREE_MIN_FACETS", 0)
    tree = [facets.near(a, r) for a in ant for r in (15.0, 60.0, 100.0)]
    assert facets._tree is not None and sum(len(x) for x in scan) > 1000
    assert all(np.array_equal(x, y) for x, y in zip(scan, tree))
