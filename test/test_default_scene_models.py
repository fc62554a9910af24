"""With default settings the scene decides what is modelled (issue 27): near walls the reflection model
(multipath auto) runs; the land-mobile-satellite layer is the user's choice about the world (lms_environment, default
off; auto: from the share of the sky the walls block); an open field pays nothing for either and writes what a run
with both off writes."""
from __future__ import annotations

import numpy as np
from multipath_scenes import canyon_scene

from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.multipath import scene_paths
from gnss_sim_ros2.core.receiver import lms_channel
from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
from gnss_sim_ros2.core.trajectory import Trajectory

LAT = 22.2982
DURATION_S = 30.0


def test_the_defaults_are_auto():
    cfg = load_config()
    # off: what a 3D model lacks is not in its geometry (lms_channel.py: the demo courtyard blocks more of the sky
    # than the Hong Kong drive the layer was fitted on)
    assert cfg.node("receiver")["lms_environment"] == "off"
    assert cfg.node("receiver")["preset"] == "balanced" and cfg.node("visibility")["multipath"] in ("", "auto")


def _run(tmp_path, scene, name, **params):
    """30 s along the canyon's axis (x = 2 m: between the walls, or on the open ground), every parameter at its
    default unless ``params`` changes it; (RINEX lines without the run's date, fix.csv text)."""
    t = np.arange(0.0, DURATION_S + 1.0)
    path = Trajectory(t, np.stack([np.full_like(t, 2.0), t - 15.0, np.full_like(t, 1.5)], axis=1), "world")
    setup = setup_from_config(load_config(), tmp_path / name, path, scene=scene, duration_s=DURATION_S,
                              interval_s=1.0, progress=False)
    if params:
        setup = setup.with_params(**params)
    res = run_simulation(setup)
    assert res.epochs == 31 and res.fixes > 25
    lines = [line for line in res.obs_path.read_text().splitlines() if "PGM / RUN BY / DATE" not in line]
    return lines, res.fix_path.read_text()


def _count_calls(monkeypatch):
    """Counters of the LMS layer's random draws and of the reflection model's path searches."""
    calls = {"lms_draws": 0, "path_search": 0}
    draws, find = lms_channel.LmsChannel._draws, scene_paths.find_paths

    def counted_draws(self, svs):
        calls["lms_draws"] += len(svs)
        return draws(self, svs)

    def counted_find(*a, **k):
        calls["path_search"] += 1
        return find(*a, **k)

    monkeypatch.setattr(lms_channel.LmsChannel, "_draws", counted_draws)
    monkeypatch.setattr(scene_paths, "find_paths", counted_find)
    return calls


def test_an_open_field_pays_nothing_and_writes_what_off_writes(tmp_path, monkeypatch):
    scene = canyon_scene(walls=False, latitude_deg=LAT)
    off = _run(tmp_path, scene, "off", multipath="off", lms_environment="off")
    calls = _count_calls(monkeypatch)
    defaults = _run(tmp_path, scene, "defaults", lms_environment="auto")
    assert calls == {"lms_draws": 0, "path_search": 0}
    assert defaults[0] == off[0] and defaults[1] == off[1]


def test_a_street_canyon_gets_the_reflections_by_default_and_the_layer_with_auto(tmp_path, monkeypatch):
    scene = canyon_scene(latitude_deg=LAT)
    off = _run(tmp_path, scene, "off", multipath="off", lms_environment="off")
    calls = _count_calls(monkeypatch)
    defaults = _run(tmp_path, scene, "defaults")
    assert calls["lms_draws"] == 0 and calls["path_search"] > 0
    assert defaults[0] != off[0]
    # the layer on its own changes the observations too (reflections the same in both)
    with_lms = _run(tmp_path, scene, "lms_auto", lms_environment="auto")
    assert calls["lms_draws"] > 0
    assert with_lms[0] != defaults[0]

