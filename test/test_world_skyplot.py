"""The sky plot draws what the casts found: open sky under an overhang stays open."""
from __future__ import annotations

import math

import numpy as np

from gnss_sim_ros2.core.scene.loader import load_sdf_world
from gnss_sim_ros2.core.scene.visibility import STATE_BLOCKED, STATE_VISIBLE, Scene


def _gantry_scene(tmp_path) -> Scene:
    # a beam 10 m north of the antenna, 6-8 m up, 40 m wide: blocks elevations atan(5.5/10.5)..atan(7.5/9.5)
    w = tmp_path / "gantry.sdf"
    w.write_text('<sdf version="1.9"><world name="w"><model name="gantry"><static>true</static>'
                 '<pose>0 10 7 0 0 0</pose><link name="beam"><collision name="c"><geometry><box>'
                 '<size>40 1 2</size></box></geometry></collision></link></model></world></sdf>')
    return Scene(load_sdf_world(w))


def test_sky_grid_keeps_the_gap_under_an_overhang(tmp_path):
    scene = _gantry_scene(tmp_path)
    ant = np.array([0.0, 0.0, 1.0])
    az_e, el_e, opaque, foliage = scene.sky_grid(ant, az_step_deg=2.0, el_step_deg=1.0)
    assert opaque.shape == (180, 90) and not foliage.any()
    north = opaque[0]                                  # azimuth cell 0-2 deg
    el_c = 0.5 * (el_e[:-1] + el_e[1:])
    lo, hi = math.degrees(math.atan2(5.0, 10.5)), math.degrees(math.atan2(7.0, 9.5))
    np.testing.assert_array_equal(north[(el_c > lo + 1) & (el_c < hi - 1)], True)
    assert not north[el_c < lo - 1].any() and not north[el_c > hi + 1].any()   # open below and above the beam
    # the satellites' states agree with the drawn cells, where the skyline would call the gap blocked
    r = scene.visibility(ant, az_deg=[1.0, 1.0, 1.0], el_deg=[10.5, 30.5, 60.5])
    assert list(r.state) == [STATE_VISIBLE, STATE_BLOCKED, STATE_VISIBLE]
    for e, s in zip((10.5, 30.5, 60.5), r.state):
        assert north[int(e)] == (s == STATE_BLOCKED)
    _, skyline = scene.horizon_profile(ant, az_step_deg=2.0)
    assert skyline[0] > 35.0                           # the old drawing shades 10.5 deg as blocked


def test_skyplot_png_from_the_casts(tmp_path):
    from gnss_sim_ros2.core.skyplot import plot_skyplot

    scene = _gantry_scene(tmp_path)
    from PIL import Image

    shaded = []
    for sky in (None, scene.sky_grid(np.array([0.0, 0.0, 1.0]))):
        png = tmp_path / "sky.png"
        plot_skyplot(png, ["G01", "G02"], [1.0, 1.0], [10.5, 30.5], ["visible", "blocked"], sky=sky)
        rgb = np.asarray(Image.open(png).convert("RGB")).astype(int)
        grey = (np.ptp(rgb, axis=2) < 12) & (rgb[..., 0] > 90) & (rgb[..., 0] < 200)
        shaded.append(int(grey.sum()))
    # the beam's band (about 25 deg of elevation over 25 deg of azimuth) adds grey pixels
    assert shaded[1] > shaded[0] + 500
