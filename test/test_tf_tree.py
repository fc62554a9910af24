"""Compact transform buffer: chains, interpolation, errors (compared with direct matrix algebra)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gnss_sim_ros2.tf_tree import TransformError, TransformTree


def _matrix(tr, rot):
    m = np.eye(4)
    m[:3, :3] = rot.as_matrix()
    m[:3, 3] = tr
    return m


def test_chain_matches_matrix_product():
    tree = TransformTree()
    r1 = Rotation.from_euler("z", 30, degrees=True)
    r2 = Rotation.from_euler("xyz", [5, -10, 70], degrees=True)
    tree.set_transform("world", "base_link", 0.0, [10.0, -4.0, 0.2], r1.as_quat())
    tree.set_transform("base_link", "gnss_antenna", 0.0, [0.3, 0.0, 0.5], r2.as_quat(), static=True)
    tr, rot = tree.lookup("world", "gnss_antenna", 0.0)
    m = _matrix([10.0, -4.0, 0.2], r1) @ _matrix([0.3, 0.0, 0.5], r2)
    np.testing.assert_allclose(tr, m[:3, 3], atol=1e-12)
    np.testing.assert_allclose(rot.as_matrix(), m[:3, :3], atol=1e-12)
    # and the inverse direction
    tr_i, rot_i = tree.lookup("gnss_antenna", "world", 0.0)
    mi = np.linalg.inv(m)
    np.testing.assert_allclose(tr_i, mi[:3, 3], atol=1e-12)


def test_interpolation_between_stamps():
    tree = TransformTree()
    tree.set_transform("world", "base_link", 1.0, [0, 0, 0], Rotation.identity().as_quat())
    tree.set_transform("world", "base_link", 2.0, [10, 20, 0], Rotation.from_euler("z", 90, degrees=True).as_quat())
    tr, rot = tree.lookup("world", "base_link", 1.25)
    np.testing.assert_allclose(tr, [2.5, 5.0, 0.0], atol=1e-12)
    assert rot.as_euler("xyz", degrees=True)[2] == pytest.approx(22.5, abs=1e-9)


def test_out_of_buffer_and_unknown_frames_fail_clearly():
    tree = TransformTree()
    tree.set_transform("world", "base_link", 1.0, [0, 0, 0], [0, 0, 0, 1])
    tree.set_transform("world", "base_link", 2.0, [1, 0, 0], [0, 0, 0, 1])
    with pytest.raises(TransformError, match="outside the buffer"):
        tree.lookup("world", "base_link", 3.0)
    with pytest.raises(TransformError, match="'nowhere' does not exist"):
        tree.lookup("world", "nowhere", 1.5)
    tree.set_transform("map", "odom", 0.0, [0, 0, 0], [0, 0, 0, 1], static=True)
    with pytest.raises(TransformError, match="not connected"):
        tree.lookup("odom", "base_link", 1.5)
    with pytest.raises(ValueError, match="invalid quaternion"):
        tree.set_transform("world", "x", 0.0, [0, 0, 0], [0, 0, 0, 0])


def test_position_is_the_lookups_translation_bit_for_bit():
    """TransformTree.position (the visibility nodes' antenna) gives lookup's translation exactly, at samples, between
    them (interpolated) and beyond; across trees (the way back) too; the same errors."""
    rng = np.random.default_rng(3)
    tree = TransformTree(cache_time_s=100.0)
    for k in range(3):
        for t in np.arange(0.0, 2.01, 0.05):
            tree.set_transform("map", f"robot{k}/base_link", float(t), rng.normal(size=3) * 50,
                               Rotation.random(random_state=int(rng.integers(1e9))).as_quat())
        tree.set_transform(f"robot{k}/base_link", f"robot{k}/gnss_antenna", 0.0, rng.normal(size=3),
                           Rotation.random(random_state=k).as_quat(), static=True)
    for t in (0.0, 0.05, 0.123, 1.0, 1.999, None):
        for target, source in (("map", "robot1/gnss_antenna"), ("map", "robot2/base_link"),
                               ("robot0/gnss_antenna", "robot2/gnss_antenna")):
            assert tree.position(target, source, t).tobytes() == tree.lookup(target, source, t)[0].tobytes()
    with pytest.raises(TransformError, match="outside the buffer"):
        tree.position("map", "robot0/gnss_antenna", 3.0)
