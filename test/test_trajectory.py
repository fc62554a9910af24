"""Paths from CSV/waypoints: interpolation, frames by header, errors naming file and line."""
from __future__ import annotations

import numpy as np
import pytest

from gnss_sim_ros2.core.trajectory import Trajectory, demo_trajectory


def test_csv_frames_and_interpolation(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("t_s,e_m,n_m,u_m\n0,0,0,0\n10,10,0,0\n# comment\n20,10,20,2\n")
    tr = Trajectory.from_csv(f)
    assert tr.frame == "world"
    np.testing.assert_allclose(tr.position(5.0), [5, 0, 0])
    np.testing.assert_allclose(tr.position(15.0), [10, 10, 1])
    np.testing.assert_allclose(tr.position([-1.0, 99.0]), [[0, 0, 0], [10, 20, 2]])
    assert tr.yaw(5.0) == pytest.approx(0.0) and tr.yaw(15.0) == pytest.approx(90.0)
    g = tmp_path / "g.csv"
    g.write_text("t_s,lat_deg,lon_deg,h_m\n0,50,14,250\n")
    assert Trajectory.from_csv(g).frame == "geodetic"


def test_loop_wraps_time():
    tr = Trajectory.from_waypoints([0, 0, 0, 0, 10, 10, 0, 0], loop=True)
    np.testing.assert_allclose(tr.position(13.0), [3, 0, 0])


@pytest.mark.parametrize("text, message", [
    ("t,e,n,u\n0,0,0,0\n", ":1: header must be"),
    ("t_s,e_m,n_m,u_m\n0,0,0,0\n1,2,x,0\n", ":3: expected 4 numbers"),
    ("t_s,e_m,n_m,u_m\n5,0,0,0\n4,0,0,0\n", "times must increase"),
    ("t_s,e_m,n_m,u_m\n", "no points"),
])
def test_bad_csv_names_file_and_line(tmp_path, text, message):
    f = tmp_path / "bad.csv"
    f.write_text(text)
    with pytest.raises(ValueError, match=message) as info:
        Trajectory.from_csv(f)
    assert str(f) in str(info.value)


def test_demo_path_is_slow_and_continuous():
    tr = demo_trajectory()
    t = np.arange(0, tr.duration_s, 0.5)
    speed = np.linalg.norm(np.diff(tr.position(t), axis=0), axis=1) / 0.5
    assert speed.max() < 2.0  # a walking-pace robot
