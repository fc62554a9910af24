"""The planner's RTK indicator against the simulator's own RTK (issue 30): `gnss-sim run --rtk` along the demo path
(175 s: open ground, the gate, the yard, under tree_1, under the ledge; rover, base station and RTKLIB rtkrcv;
multipath off as issue 17's acceptance run) against core/planning path_quality at the same antenna positions and
times, per epoch, with the skill over the base rate (core/planning/skill.py).  Figures in docs/PLANNING.md."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

from gnss_sim_ros2.core.demo import DEMO_START
from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
from gnss_sim_ros2.core.planning.quality import PlanInputs, path_quality
from gnss_sim_ros2.core.planning.ranging import budget_from_profile, tracked_systems
from gnss_sim_ros2.core.planning.skill import skill
from gnss_sim_ros2.core.planning.sky import plan_sky
from gnss_sim_ros2.core.scene.demo_world import demo_world_path
from gnss_sim_ros2.core.time import GnssTime
from gnss_sim_ros2.core.trajectory import antenna_path, demo_trajectory
from gnss_sim_ros2.core.visibility import VisibilityOptions, load_scene
from gnss_sim_ros2.parameters import defaults

DURATION_S = 175          # the demo path's end


def test_rtk_indicator_against_the_rtk_node(tmp_path):
    from test_rtk_engine import rtkrcv_and_faketime

    if not rtkrcv_and_faketime():
        pytest.skip("RTKLIB rtkrcv and libfaketime are not installed (apt-get install rtklib faketime)")
    pytest.importorskip("rclpy", reason="rclpy is not installed (run make test)")
    cfg = tmp_path / "no_reflections.yaml"
    cfg.write_text(yaml.safe_dump({"gnss_sim_visibility": {"ros__parameters": {"multipath": "off"}}}))
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "gnss_sim_ros2.cli", "run", "--out", str(out), "--quiet", "--rtk",
                        "--duration", str(DURATION_S), "--config", str(cfg)], capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    s = json.loads((out / "summary.json").read_text())
    n = s["epochs"]
    fixed = np.zeros(n, bool)                                  # the rtk node's fix, per epoch (none: not fixed)
    for row in (out / s["rtk_timeline"]).read_text().splitlines()[1:]:
        t_s, quality, _ = row.split(",")
        k = int(round(float(t_s)))
        if 0 <= k < n:
            fixed[k] = quality == "fixed"
    # the planner at the run's antenna (trajectory player: the demo path, antenna_offset_m) and times
    p = defaults()
    t = np.arange(n, dtype=float)
    ant = antenna_path(demo_trajectory(), p.node("trajectory")["antenna_offset_m"]).position(t)
    start = GnssTime.from_iso(DEMO_START, scale="GPS")
    profile = p.node("receiver")["profile"]
    systems = tracked_systems(profile, p.node("ephemeris")["systems"])
    provider, _ = open_ephemeris("synthetic", start, n + 60.0, systems)
    sky = plan_sky(provider, GnssTime.stack([start + float(x) for x in t]), systems)
    scene = load_scene(str(demo_world_path()), "", "", VisibilityOptions())
    fields = path_quality(scene, VisibilityOptions(mask_deg=p.node("visibility")["elevation_mask_deg"]), ant,
                          sky.pos_ecef_m, sky.system, PlanInputs(sky.pos_ecef_m, sky.system,
                                                                 budget_from_profile(profile, systems)))
    sc = skill(fields["rtk"], fixed)
    print("RTK indicator vs the rtk node: " + ", ".join(f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}"
                                                          for k, v in sc.items()))
    # measured 2026-12-03 (600 s run, its first 175 s): predicted 0.29, fixed 0.74, accuracy 0.54 against a base
    # rate of 0.74, HSS 0.24, false-alarm ratio 0: the rule is conservative (RTKLIB holds its fix through the gate
    # and under the tree with fewer satellites than the rule asks). Margins below the figures.
    assert n == DURATION_S + 1
    assert sc["false_alarm_ratio"] <= 0.05                 # where the planner promises RTK, the rtk node is fixed
    assert sc["hss"] >= 0.1
    assert fields["rtk"][:30].all() and fixed[5:30].all()  # open ground: both agree
