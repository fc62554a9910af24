"""TF messages of the trajectory player: one ``geometry_msgs/TransformStamped`` (a translation and a yaw), and the
``tf2_msgs/TFMessage`` carrying several."""
from __future__ import annotations

import math

from geometry_msgs.msg import TransformStamped


def transform_to_msg(parent: str, child: str, stamp, xyz_m, yaw_deg: float = 0.0) -> TransformStamped:
    """``child`` in ``parent`` at ``stamp`` (builtin_interfaces/Time): translation xyz_m [m], rotation yaw_deg
    about z (counter-clockwise, REP-103)."""
    tf = TransformStamped()
    tf.header.stamp = stamp
    tf.header.frame_id = parent
    tf.child_frame_id = child
    tf.transform.translation.x, tf.transform.translation.y, tf.transform.translation.z = (float(v) for v in xyz_m)
    half = math.radians(yaw_deg) / 2.0
    tf.transform.rotation.z = math.sin(half)
    tf.transform.rotation.w = math.cos(half)
    return tf


def tf_message(transforms):
    """The /tf or /tf_static message of ``transforms``."""
    from tf2_msgs.msg import TFMessage

    return TFMessage(transforms=list(transforms))
