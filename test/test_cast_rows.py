"""Batched casts over repeated antenna rows (the planner's cells x time steps) against each row's own cast.

The planner's line-of-sight states must be those the simulator casts for one antenna and epoch (issue 30), so a
batch whose rows repeat antennas (per-antenna work done once per run of equal rows, the directions rotated for all
satellites and the cast ones kept) must hand Open3D the same float32 rays, bit for bit, as each row cast alone;
``azimuth=False`` (the planner reads only the elevations) must change nothing but ``az_deg``.
"""
from __future__ import annotations

import numpy as np
from test_scene_visibility import H0, LAT0, LON0, box_model, wall_scene, world_sdf

from gnss_sim_ros2.core import frames
from gnss_sim_ros2.core.scene.visibility import Scene
from gnss_sim_ros2.core.visibility import VisibilityOptions


def _spy_rays(scene):
    """Record the float32 ray buffers the scene hands Open3D."""
    seen = []
    real = scene.rays.occluded_buffer

    def spy(rays, **kw):
        seen.append(np.array(rays))
        return real(rays, **kw)

    scene.rays.occluded_buffer = spy
    return seen


def _rows_and_sats(n_steps=4, n_sats=12):
    """Antennas 3 km apart (the vertical tilts), each repeated once per step; satellites per step, some below
    the 10 deg mask (a ragged cast)."""
    ants = np.array([[0.0, 0.0, 1.5], [3000.0, -2000.0, 1.5], [25.0, 0.0, 1.5]])
    rng = np.random.default_rng(3)
    az = rng.uniform(0.0, 360.0, (n_steps, n_sats))
    el = rng.uniform(-5.0, 89.0, (n_steps, n_sats))
    enu = 2.0e7 * frames.enu_unit_from_az_el(az, el)
    sat = np.asarray(frames.enu_to_ecef(enu, LAT0, LON0, H0))
    rows_ant = np.repeat(ants, n_steps, axis=0)                                   # row = antenna * T + step
    rows_sat = np.broadcast_to(sat[None], (len(ants),) + sat.shape).reshape(-1, n_sats, 3)
    return rows_ant, rows_sat


def test_repeated_rows_cast_as_each_row_alone(tmp_path):
    scene = wall_scene(tmp_path, 20.0, 15.0)
    seen = _spy_rays(scene)
    ant, sat = _rows_and_sats()
    batch = scene.visibility_ecef(ant, sat, mask_deg=10.0, azimuth=False)
    batch_rays = seen[-1]
    assert batch.az_deg is None
    assert 0 < np.count_nonzero(batch.state == -1) < batch.state.size            # ragged: some below the mask
    assert np.count_nonzero(batch.state == 1) > 0                                # the wall blocks some
    at = 0
    for i in range(len(ant)):
        one = scene.visibility_ecef(ant[i], sat[i], mask_deg=10.0)
        k = np.count_nonzero(one.state >= 0)
        assert one.state.tobytes() == batch.state[i].tobytes()
        assert one.el_deg.tobytes() == batch.el_deg[i].tobytes()
        assert seen[-1].tobytes() == batch_rays[at:at + k].tobytes()             # the same float32 rays
        at += k
    assert at == len(batch_rays)
    full = scene.visibility_ecef(ant, sat, mask_deg=10.0)
    assert full.state.tobytes() == batch.state.tobytes() and full.az_deg.shape == full.state.shape


def test_cast_keeps_the_azimuth_where_the_reflections_need_it(tmp_path):
    scene = wall_scene(tmp_path, 20.0, 15.0)
    ant, sat = _rows_and_sats(n_steps=2, n_sats=6)
    _, _, bare = VisibilityOptions(mask_deg=10.0).cast(scene, ant, sat, azimuth=False)
    assert bare.az_deg is None
    _, _, refl = VisibilityOptions(mask_deg=10.0, multipath="nlos").cast(scene, ant, sat, azimuth=False)
    assert refl.az_deg is not None and np.all(np.isfinite(refl.az_deg))


def test_single_antenna_result_keeps_no_azimuth_row(tmp_path):
    scene = Scene.from_sdf(world_sdf(tmp_path, box_model("b", (40.0, 0.0, 5.0), (2.0, 2.0, 10.0))))
    ant, sat = _rows_and_sats(n_steps=1, n_sats=5)
    r = scene.visibility_ecef(ant[0], sat[0], mask_deg=10.0, azimuth=False)
    assert r.az_deg is None and r.state.shape == (5,)



def test_rotation_paths_and_kept_antenna_terms_hand_the_same_rays(tmp_path, monkeypatch):
    """The nine rotation products in one call (few rays) or in place per component (many), and the per-antenna
    terms kept from the previous cast or computed afresh: the same float32 rays and the same results."""
    from gnss_sim_ros2.core.scene import visibility as vis

    scene = wall_scene(tmp_path, 20.0, 15.0)
    seen = _spy_rays(scene)
    ant, sat = _rows_and_sats()
    cases = [(ant, sat), (ant[0], sat[0]), (ant[:3], sat[0]), (ant[::4], sat[::4])]

    def run():
        out = []
        for a, s in cases:
            for mask in (10.0, -90.0):                   # ragged and every satellite cast
                r = scene.visibility_ecef(a, s, mask_deg=mask)
                out.append((seen[-1].tobytes(), r.state.tobytes(), r.el_deg.tobytes(), r.az_deg.tobytes()))
        return out

    monkeypatch.setattr(vis, "FUSED_ROTATION_MAX", 0)
    in_place = run()
    monkeypatch.setattr(vis, "FUSED_ROTATION_MAX", 1 << 30)
    fused = run()
    assert fused == in_place
    fresh = []
    for a, s in cases:                                   # no terms kept from the previous cast
        for mask in (10.0, -90.0):
            scene.__dict__.pop("_terms", None)
            r = scene.visibility_ecef(a, s, mask_deg=mask)
            fresh.append((seen[-1].tobytes(), r.state.tobytes(), r.el_deg.tobytes(), r.az_deg.tobytes()))
    assert fresh == fused
