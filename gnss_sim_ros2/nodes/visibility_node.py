"""Visibility lifecycle node: which satellites the scene hides or weakens at the antenna.

configure: loads the scene (an exported mesh, or an SDF world exported on the
fly; the demo courtyard by default) and builds the Open3D raycasting scene;
active: for each ``satellite_states`` epoch, waits until TF has the antenna
pose (antenna_frame in world_frame) at that epoch's stamp, then casts one
batch of rays and publishes ``visibility`` (same stamp) and, once per second
of ROS time, ``sky_view`` (sensor_msgs/Image, a polar sky plot for RViz);
diagnostics count the epochs processed and dropped (no TF in time).
With ``antenna_position`` the antenna stands still there (a base station):
no TF lookup. Moving obstacles (core/visibility/moving_obstacles.py): a box on each
``obstacle_frames`` frame looked up in TF at the epoch's stamp (the robot's own body, under the
antenna frame's prefix, left out; a frame TF lacks at the stamp blocks nothing that epoch and is
counted), and on each ``obstacle_models`` model at its pose from ``obstacle_pose_topic``
(tf2_msgs/TFMessage, as ros_gz_bridge gives Gazebo's dynamic poses). Messages travel as CDR
bytes read and written from arrays (gnss_sim_ros2/messages/cdr.py): ``satellite_states`` is a
raw subscription and the visibility is published serialised.
"""
from __future__ import annotations

import collections
import sys
import time

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.clock import Clock, ClockType
from sensor_msgs.msg import Image
from std_msgs.msg import Header

from gnss_sim_ros2.core.scene.sky_view import SkyView
from gnss_sim_ros2.messages.conversions import encode_visibility, stamp_of, states_from_cdr
from gnss_sim_ros2.messages.diagnostics import diagnostic_array, diagnostic_status
from gnss_sim_ros2.messages.images import rgb8_image
from gnss_sim_ros2.nodes.common import GnssSimNode, run_node
from gnss_sim_ros2.nodes.in_process import Taker, subscription_switch
from gnss_sim_ros2.nodes.tf_source import TfSource
from gnss_sim_ros2.tf_tree import TransformTree

#: the sky view image is rendered at most this often (ROS time) [s]
SKY_VIEW_PERIOD_S = 5.0


class VisibilityNode(GnssSimNode):
    PARAMS_KEY = "visibility"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.scene = None             # core.scene.visibility.Scene (configure .. cleanup)
        self.options = None           # core.visibility.VisibilityOptions
        self.tf = None
        self.fixed_world_m = None     # antenna_position in the world frame, or None: the antenna from TF
        self.pub = self.image_pub = self.diag_pub = None
        self.queue: collections.deque = collections.deque()
        self._states_taker = None     # the satellite_states taken in-process or over the middleware (activate)
        self.processed = 0
        self.dropped = 0
        self._last_image_s = -1e9
        self.sky_view = None          # core.scene.sky_view.SkyView of the scene (configure .. cleanup)
        self.obstacle_frames: list = []   # TF frames carrying an obstacle box (own body left out)
        self.model_poses = None       # tf_tree.TransformTree of the obstacle_models' poses, or None
        self.obstacles_missing = 0    # obstacle frames TF lacked at an epoch's stamp

    def configure(self, p):
        from gnss_sim_ros2.core.scene.demo_world import demo_world_path
        from gnss_sim_ros2.core.visibility import VisibilityOptions, load_scene
        from gnss_sim_ros2.core.visibility.world_offset import is_zero, offset_note, shifted_scene

        try:
            self.options = VisibilityOptions.from_params(p)
            if p["sky_mask_csv"]:       # a measured mask at the static antenna, as `gnss-sim simulate` builds it
                self.scene = self._sky_mask_scene(p)
            else:
                world = p["world_file"] if p["world_file"] or p["mesh_file"] else str(demo_world_path())
                self.scene = load_scene(world, p["mesh_file"], p["materials_file"], self.options, shared=True)
            self.scene = shifted_scene(self.scene, p["world_offset_enu_m"])
        except ValueError as exc:
            raise ValueError(f"node {self.get_name()}: {exc}") from None
        if self.scene.spherical is None:
            raise ValueError(f"node {self.get_name()}: the world has no spherical_coordinates: it cannot be placed "
                             f"on the Earth (parameter world_file/mesh_file)")
        if not is_zero(p["world_offset_enu_m"]):
            self.get_logger().warning(offset_note(p["world_offset_enu_m"]))
        self.fixed_world_m = self._fixed_antenna(p) if p["antenna_position"] else None
        # the geodesy every epoch uses (pymap3d, imported where first used: about 10 ms) paid now, not in the
        # first epoch's latency
        self.scene.antenna_ecef(np.zeros(3))
        self.processed = self.dropped = 0
        self._last_image_s = -1e9
        self.sky_view = SkyView(self.scene)
        from gnss_sim_ros2.core.visibility.moving_obstacles import own_body

        self.obstacle_frames = [f for f in p["obstacle_frames"] if not own_body(f, p["antenna_frame"])]
        # the models' poses: interpolated between the two around a stamp, the nearest held beyond the first or last
        self.model_poses = TransformTree(cache_time_s=30.0, tolerance_s=np.inf) if p["obstacle_models"] else None
        self.obstacles_missing = 0
        from gnss_sim_msgs.msg import Visibility

        self.pub = self.lifecycle_publisher(Visibility, "visibility", 100)
        self.image_pub = self.lifecycle_publisher(Image, "sky_view", 2)
        self.diag_pub = self.lifecycle_publisher(DiagnosticArray, "/diagnostics", 10)
        # an epoch waiting for its pose is cast as soon as the pose comes (not at the drain timer's next tick)
        self.tf = TfSource(self, on_update=self.speaking(self._drain), timeout_s=p["tf_timeout_s"])

    def _sky_mask_scene(self, p):
        """The scene of parameter sky_mask_csv at the static antenna_position (core/visibility/sky_mask.py)."""
        from gnss_sim_ros2.core.visibility.sky_mask import check_mask_options, mask_scene, static_antenna_ecef

        where = "parameter 'sky_mask_csv'"
        self.options = check_mask_options(self.options, where)
        _, ecef = static_antenna_ecef(p["antenna_position"], p["antenna_position_type"], None, where)
        return mask_scene(p["sky_mask_csv"], ecef)

    def _fixed_antenna(self, p) -> np.ndarray:
        """The static antenna of parameter antenna_position in the world frame."""
        from gnss_sim_ros2.core.frames import check_receiver_position, geodetic_to_ecef

        pos, kind = p["antenna_position"], p["antenna_position_type"]
        if kind == "world":
            world = np.array(pos, dtype=float)
        else:
            ecef = np.array(geodetic_to_ecef(*pos) if kind == "llh" else pos, dtype=float)
            world = self.scene.spherical.ecef_to_world(ecef)
        if kind == "world":        # llh and ecef were checked by the parameter table: the same rule
            check_receiver_position(self.scene.antenna_ecef(world), "ecef",
                                    f"node {self.get_name()}: parameter 'antenna_position' = {pos!r} ({kind})")
        if np.hypot(world[0], world[1]) > 100e3:
            raise ValueError(f"node {self.get_name()}: parameter 'antenna_position' = {pos!r} ({kind}) is "
                             f"{np.hypot(world[0], world[1]) / 1e3:.0f} km from the world's origin; the world frame "
                             f"is a tangent plane, good to 100 km")
        return world

    def activate(self):
        from gnss_sim_msgs.msg import SatelliteStates

        # the states handed by an ephemeris node of this process (nodes/in_process.py), else from the middleware
        over_middleware = subscription_switch(
            lambda: self.active_subscription(SatelliteStates, "satellite_states", self._on_states, 100, raw=True),
            self.drop_active)
        self._states_taker = Taker(self, "satellite_states", self.speaking(lambda handed: self._on_states(*handed)),
                                   over_middleware)
        if self.model_poses is not None:
            from tf2_msgs.msg import TFMessage

            self.active_subscription(TFMessage, self.params["obstacle_pose_topic"], self._on_model_poses, 100)
        # a steady-clock timer: a simulated clock stands still while an epoch waits for its TF
        self.active_timer(0.005, self._drain, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def deactivate(self):
        if self._states_taker is not None:
            self._states_taker.close()
            self._states_taker = None
        self.queue.clear()

    def cleanup(self):
        self.pub = self.image_pub = self.diag_pub = None
        self.model_poses = None
        if self.tf is not None:
            self.tf.close()
            self.tf = None
        self.scene = self.options = None
        self.sky_view = None

    # ------------------------------------------------------------------
    def _on_states(self, data: bytes, decoded=None):
        """A SatelliteStates message (its bytes), with its decode when handed in-process (else decoded when cast)."""
        sec, nanosec = stamp_of(data)
        self.queue.append((data, Time(sec=sec, nanosec=nanosec), time.monotonic(), decoded))
        self._drain()

    def _drain(self):
        """Cast every queued epoch whose antenna pose TF has; one whose frame is missing (TfSource.frame_missing:
        TF reached the epoch without it for tf_timeout_s, or no /tf publisher for tf_timeout_s; a source that is
        alive but behind is waited for) is dropped; later ones wait behind it, so waits never add up."""
        p = self.params
        while self.queue:
            data, stamp, arrived, decoded = self.queue[0]
            if self.fixed_world_m is not None:
                self.queue.popleft()
                self.process(data, self.fixed_world_m, decoded)
                continue
            try:
                tr = self.tf.position(p["world_frame"], p["antenna_frame"], stamp)
            except LookupError:
                if self.tf.frame_missing(p["antenna_frame"], stamp, arrived):
                    self.queue.popleft()
                    self.dropped += 1
                    t_s = stamp.sec + stamp.nanosec * 1e-9
                    self.get_logger().error(f"no transform {p['world_frame']} -> {p['antenna_frame']} in TF within "
                                            f"tf_timeout_s = {p['tf_timeout_s']:g} s at {t_s:.3f} s (TF reached the "
                                            f"epoch without it, or nothing publishes /tf): epoch dropped "
                                            f"({self.dropped} so far)")
                    continue   # the epochs behind it have been waiting meanwhile: their own clocks run on
                return
            self.queue.popleft()
            self.process(data, np.asarray(tr), decoded)

    def _on_model_poses(self, msg):
        """Gazebo's model poses (tf2_msgs/TFMessage: child_frame_id = model name, pose in world_frame)."""
        models = self.params["obstacle_models"]
        for tf in msg.transforms:
            if tf.child_frame_id in models:
                tr, q = tf.transform.translation, tf.transform.rotation
                self.model_poses.set_transform(self.params["world_frame"], tf.child_frame_id,
                                               tf.header.stamp.sec + tf.header.stamp.nanosec * 1e-9,
                                               (tr.x, tr.y, tr.z), (q.x, q.y, q.z, q.w))

    def _frame_poses(self, frames, stamp):
        """(origins (B, 3) list, rotation matrices list, indices into ``frames``) of the obstacle ``frames`` TF
        has at ``stamp`` in world_frame; a frame it lacks blocks nothing this epoch and is counted
        (obstacles_missing), without waiting for it."""
        base, rot, present = [], [], []
        for b, frame in enumerate(frames):
            try:
                tr, r = self.tf.lookup(self.params["world_frame"], frame, stamp)
            except LookupError:
                self.obstacles_missing += 1
                continue
            base.append(np.asarray(tr, dtype=float))
            rot.append(r.as_matrix())
            present.append(b)
        return base, rot, present

    def _obstacles(self, stamp):
        """The moving boxes at ``stamp`` (core.visibility.moving_obstacles.MovingBoxes, one antenna row), or None."""
        if not self.obstacle_frames and self.model_poses is None:
            return None
        from gnss_sim_ros2.core.visibility.moving_obstacles import MovingBoxes

        p = self.params
        base, rot, present = self._frame_poses(self.obstacle_frames, stamp)
        size = [p["obstacle_box_size_m"]] * len(present)
        if self.model_poses is not None:
            known = self.model_poses.frames()
            for model in p["obstacle_models"]:
                if model in known:                  # a model whose pose has not come yet blocks nothing
                    pos, r = self.model_poses.lookup(p["world_frame"], model, stamp.sec + stamp.nanosec * 1e-9)
                    base.append(pos)
                    rot.append(r.as_matrix())
                    size.append(p["obstacle_model_size_m"])
        if not base:
            return None
        return MovingBoxes.from_bases(np.array(base)[None], np.array(rot)[None], np.array(size)[None])

    def process(self, data: bytes, antenna_world_m, decoded=None):
        """One epoch: the serialised SatelliteStates in (``decoded``: their decode, None: decoded here), the
        serialised Visibility published."""
        (sec, nanosec), _, states, _ = decoded or states_from_cdr(data)
        obstacles = self._obstacles(Time(sec=sec, nanosec=nanosec))
        ecef = self.scene.antenna_ecef(antenna_world_m)
        rows = np.zeros(0, dtype=np.int64)
        sv = az = el = state = att = extra = frac = rows
        paths = None
        if len(states):
            state, att, v = self.options.cast(self.scene, antenna_world_m, states.pos_ecef_m, obstacles=obstacles)
            rows = np.flatnonzero(v.el_deg >= 0.0)     # above the horizon
            paths = getattr(v, "paths", None)          # reflected paths (multipath nlos/full), as the offline chain
            sv, az, el = states.sv[rows], v.az_deg[rows], v.el_deg[rows]
            state, att = state[rows], att[rows]
            extra, frac = v.extra_path_m[rows], v.fraction_blocked[rows]
        self.pub.publish(encode_visibility((sec, nanosec), self.params["world_frame"], antenna_world_m, ecef, sv, az,
                                           el, state, att, extra, frac, paths, rows))
        self.processed += 1
        t_s = sec + nanosec * 1e-9
        if t_s - self._last_image_s >= SKY_VIEW_PERIOD_S and self.image_pub.get_subscription_count() > 0:
            self._last_image_s = t_s
            header = Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=self.params["world_frame"])
            self.image_pub.publish(rgb8_image(header, self.sky_view.rgb(antenna_world_m, az, el, state)))
        if self.processed % 10 == 1:
            self._diagnose(len(rows))

    def _diagnose(self, n: int):
        status = diagnostic_status(f"{self.get_name()}: visibility",
                                   f"{self.processed} epochs, {self.dropped} dropped (no TF)",
                                   {"satellites_above_horizon": n, "epochs_processed": self.processed,
                                    "epochs_dropped": self.dropped,
                                    "obstacle_frames_missing": self.obstacles_missing}, warn=bool(self.dropped))
        self.diag_pub.publish(diagnostic_array(self.get_clock().now().to_msg(), status))


def main(args=None):
    return run_node(VisibilityNode, args)


if __name__ == "__main__":
    sys.exit(main())
