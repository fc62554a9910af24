"""Fleet visibility lifecycle node: every robot's antenna cast in one call per epoch (the fleet layout, graph.py).

The visibility node (nodes/visibility_node.py) for ``fleet_robots`` robots at once: for each
``satellite_states`` epoch it looks up robot k's antenna (``robot<k>/<antenna_frame>``; one robot: the
root's frame, as a one-robot run) in TF at the epoch's stamp, casts all of them in one
``VisibilityOptions.cast`` with (M, 3) antennas (Open3D takes every robot's rays in one call; the static scene
is built once) and publishes each robot's gnss_sim_msgs/Visibility on its own topic (/robot<k>/gnss/visibility),
byte for byte what robot k's own visibility node publishes in the per-robot layouts (test_fleet_layout).

Moving obstacles as the per-robot node takes them: a box on each ``obstacle_frames`` frame (other robots'
``base_link``), looked up once per epoch; robot k's row leaves out its own body (core/visibility/moving_obstacles
``own_body``: the frame under its antenna frame's prefix), the (M, B) ``active`` mask of ``fleet_bodies``; the
``obstacle_models`` boxes (Gazebo poses) are seen alike by every robot (``MovingBoxes.repeat_rows``).  A robot whose
antenna TF lacks at a stamp (TfSource.frame_missing) is left out of that epoch's cast (counted as dropped), the
others are cast; an epoch waits while a robot's TF is only late.  The sky view image is robot 0's.

A fleet receiver node of the same process (the fleet layout of ``gnss-sim run``; its driver, which reads each
robot's antenna, too) is handed each robot's epoch in-process (nodes/in_process.py): the columns its decode of
the message would give (:func:`handed_visibility`, float32 fields rounded alike) with the SatelliteStates cast
(bytes and decode), without the middleware and without encoding or decoding on the way; the Visibility messages
are then published after the receiver's observations (an executor task queued behind them), and only on topics
some other node subscribes to (recorder, users).  In separate processes the receiver takes the messages from the
middleware as before.
"""
from __future__ import annotations

import sys

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import Image
from std_msgs.msg import Header

from gnss_sim_ros2.graph import FLEET_NODE_NAMES, fleet_topic
from gnss_sim_ros2.graph_params import fleet_robot_params
from gnss_sim_ros2.messages.conversions import encode_visibility, states_from_cdr
from gnss_sim_ros2.messages.images import rgb8_image
from gnss_sim_ros2.nodes.common import run_node
from gnss_sim_ros2.nodes.in_process import Offer
from gnss_sim_ros2.nodes.visibility_node import SKY_VIEW_PERIOD_S, VisibilityNode


class FleetVisibilityNode(VisibilityNode):
    def __init__(self, node_name: str | None = None, **kwargs):
        super().__init__(node_name=node_name or FLEET_NODE_NAMES["visibility"], **kwargs)
        self.antenna_frames: list[str] = []   # robot k's antenna frame
        self.pubs: list = []                  # robot k's visibility publisher
        self.own_body_rows = None             # (robots, obstacle frames) bool: frame b is robot k's own body
        self.fleet_obstacle_frames: list[str] = []
        self._head = None                     # (head epoch's bytes, antennas (N, 3), found (N,)) while TF is awaited
        self.offers: list[Offer] = []         # robot k's visibility handed in-process (nodes/in_process.py)
        self._unpublished: list = []          # epochs handed in-process whose messages are not published yet

    def configure(self, p):
        n = p["fleet_robots"]
        for name in ("antenna_position", "sky_mask_csv"):
            if p[name]:
                raise ValueError(f"node {self.get_name()}: parameter '{name}' is a static antenna; the fleet layout "
                                 f"serves robots whose antennas move in TF (use the composed layout for a static one)")
        super().configure(p)
        from gnss_sim_msgs.msg import Visibility

        from gnss_sim_ros2.core.visibility.moving_obstacles import own_body

        # the base class's one visibility topic and sky view: one topic per robot instead, robot 0's sky view
        for pub in (self.pub, self.image_pub):
            self._owned_publishers.remove(pub)
            self.destroy_publisher(pub)
        self.pub = None
        self.image_pub = self.lifecycle_publisher(Image, fleet_topic(0, n, "sky_view"), 2)
        self.antenna_frames = [fleet_robot_params(p, k, "visibility")["antenna_frame"] for k in range(n)]
        self.pubs = [self.lifecycle_publisher(Visibility, fleet_topic(k, n, "visibility"), 100) for k in range(n)]
        self.offers = [Offer(self, pub) for pub in self.pubs]
        self.fleet_obstacle_frames = list(p["obstacle_frames"])
        self.own_body_rows = np.array([[own_body(f, a) for f in self.fleet_obstacle_frames]
                                       for a in self.antenna_frames], dtype=bool).reshape(n, -1)
        self.obstacle_frames = []             # the base class's _obstacles: the models only (fleet_obstacles)
        self._head = None

    def deactivate(self):
        self._publish_due()                  # the epochs handed over, while the publishers are on
        super().deactivate()

    def cleanup(self):
        self._unpublished = []
        for offer in self.offers:
            offer.withdraw()
        self.offers = []
        super().cleanup()
        self.pubs = []

    # ------------------------------------------------------------------
    def _drain(self):
        """Cast every queued epoch once each robot's antenna pose is in TF or missing (TfSource.frame_missing);
        a robot missing at a stamp is left out of that epoch (dropped, counted and logged), the others cast."""
        p = self.params
        n = len(self.antenna_frames)
        while self.queue:
            data, stamp, arrived, decoded = self.queue[0]
            # the head epoch's antennas found so far: a TF message (every robot's player sends them) retries only
            # the robots still waited for, not all N (N players x N lookups per message otherwise)
            if self._head is None or self._head[0] is not data:
                self._head = (data, np.zeros((n, 3)), np.zeros(n, dtype=bool))
            _, antennas, found = self._head
            have = np.ones(n, dtype=bool)
            for k in np.flatnonzero(~found):
                frame = self.antenna_frames[k]
                try:
                    antennas[k] = self.tf.position(p["world_frame"], frame, stamp)
                    found[k] = True
                except LookupError:
                    if not self.tf.frame_missing(frame, stamp, arrived):
                        return            # alive but behind: wait for it
                    have[k] = False
            self.queue.popleft()
            self._head = None
            if not have.all():
                self.dropped += int((~have).sum())
                missing = [f for f, ok in zip(self.antenna_frames, have) if not ok]
                self.get_logger().error(f"no transform {p['world_frame']} -> {', '.join(missing)} in TF within "
                                        f"tf_timeout_s = {p['tf_timeout_s']:g} s at "
                                        f"{stamp.sec + stamp.nanosec * 1e-9:.3f} s: those robots' epoch dropped "
                                        f"({self.dropped} so far)")
            if have.any():
                self.process_fleet(data, np.flatnonzero(have), antennas[have], decoded)

    def fleet_obstacles(self, stamp, robots):
        """The moving boxes at ``stamp`` as seen by the antenna rows of ``robots`` (MovingBoxes (M, B)), or None:
        the obstacle frames' boxes without each robot's own body, then the models' boxes seen by all."""
        from gnss_sim_ros2.core.visibility.moving_obstacles import MovingBoxes

        p = self.params
        base, rot, present = self._frame_poses(self.fleet_obstacle_frames, stamp)
        m = len(robots)
        boxes = None
        if present:
            boxes = MovingBoxes.from_bases(np.broadcast_to(np.array(base), (m, len(base), 3)),
                                           np.broadcast_to(np.array(rot), (m, len(base), 3, 3)),
                                           p["obstacle_box_size_m"], ~self.own_body_rows[np.ix_(robots, present)])
        models = self._obstacles(stamp)     # the base class's with no frames: the models' boxes, one row
        if models is not None:
            models = models.repeat_rows(m)
            boxes = models if boxes is None else boxes.concat(models)
        return boxes

    def process_fleet(self, data: bytes, robots, antennas_world_m, decoded=None):
        """One epoch for the robots ``robots`` at ``antennas_world_m`` (M, 3): one cast, one Visibility each
        (handed in-process first where a receiver of this process takes it, published after its observations);
        ``decoded``: the states' decode handed with them (None: decoded here)."""
        decoded = decoded or states_from_cdr(data)
        (sec, nanosec), _, states, _ = decoded
        stamp = Time(sec=sec, nanosec=nanosec)
        obstacles = self.fleet_obstacles(stamp, robots)
        ecef = self.scene.antenna_ecef(antennas_world_m)
        frame = self.params["world_frame"]
        empty = np.zeros(0, dtype=np.int64)
        v = paths = None
        messages = []                        # (robot, handed in-process, encode_visibility's arguments)
        if len(states):
            state_all, att_all, v = self.options.cast(self.scene, antennas_world_m, states.pos_ecef_m,
                                                      obstacles=obstacles)
            paths = getattr(v, "paths", None)     # (M, N, K) reflected paths (multipath nlos/full/auto)
        for i, k in enumerate(robots):
            if v is None:
                rows = empty
                sv = az = el = state = att = extra = frac = empty
                path_i = None
            else:
                rows = np.flatnonzero(v.el_deg[i] >= 0.0)    # above the horizon
                sv, az, el = states.sv[rows], v.az_deg[i][rows], v.el_deg[i][rows]
                state, att = state_all[i][rows], att_all[i][rows]
                extra, frac = v.extra_path_m[i][rows], v.fraction_blocked[i][rows]
                path_i = paths.take(i) if paths is not None else None
            fields = ((sec, nanosec), frame, antennas_world_m[i], ecef[i], sv, az, el, state, att, extra, frac,
                      path_i, rows)
            takers = self.offers[k].takers() if self.offers else []
            if takers:
                handed = ((sec, nanosec), handed_visibility(*fields), data, decoded)
                for deliver in takers:
                    deliver(handed)
            messages.append((k, bool(takers), fields))
        if self.executor is not None and any(m[1] for m in messages):
            self._unpublished.append(messages)
            self.executor.create_task(self.speaking(self._publish_due))     # behind the receiver's epoch
        else:
            self._publish(messages)
        self.processed += 1
        if self.processed % 10 == 1:
            self._diagnose(len(rows))          # the last robot's satellites above the horizon

    def _publish_due(self):
        while self._unpublished:
            self._publish(self._unpublished.pop(0))

    def _publish(self, messages):
        """The Visibility messages of one epoch (a robot's handed in-process: only if another node subscribes),
        robot 0's sky view."""
        for k, handed, fields in messages:
            if not handed or self.pubs[k].get_subscription_count() > 0:
                self.pubs[k].publish(encode_visibility(*fields))
            if k == 0:
                (sec, nanosec), _, antenna_world_m, _, _, az, el, state = fields[:8]
                self._sky_view(sec, nanosec, antenna_world_m, az, el, state)

    def _sky_view(self, sec, nanosec, antenna_world_m, az, el, state):
        t_s = sec + nanosec * 1e-9
        if t_s - self._last_image_s >= SKY_VIEW_PERIOD_S and self.image_pub.get_subscription_count() > 0:
            self._last_image_s = t_s
            header = Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=self.params["world_frame"])
            self.image_pub.publish(rgb8_image(header, self.sky_view.rgb(antenna_world_m, az, el, state)))


def handed_visibility(stamp, frame_id: str, antenna_world_m, antenna_ecef_m, sv, az_deg, el_deg, state,
                      attenuation_db, extra_path_m, fraction_blocked, paths=None, path_rows=None) -> dict:
    """The columns messages/conversions.decode_visibility gives of encode_visibility(same arguments), without the
    bytes: the message's types (state uint8, fraction_blocked float32: rounded as the message rounds it), the
    reflections of the rows ``path_rows`` of ``paths`` flattened as the message carries them (test_fleet_layout
    holds the two equal)."""
    n = len(sv)
    counts = np.zeros(n, dtype=np.int64)
    refl = {k: np.zeros(0) for k in ("excess_path_m", "gamma_co_re", "gamma_co_im", "gamma_cross_re",
                                     "gamma_cross_im", "arrival_elevation_deg")}
    if paths is not None:
        rows = slice(None) if path_rows is None else path_rows
        excess = np.asarray(paths.excess_m)[rows]
        valid = np.isfinite(excess)
        counts = valid.sum(axis=1).astype(np.int64)
        co, cross = np.asarray(paths.gamma_co)[rows][valid], np.asarray(paths.gamma_cross)[rows][valid]
        refl = {"excess_path_m": excess[valid].astype(np.float64), "gamma_co_re": co.real.astype(np.float64),
                "gamma_co_im": co.imag.astype(np.float64), "gamma_cross_re": cross.real.astype(np.float64),
                "gamma_cross_im": cross.imag.astype(np.float64),
                "arrival_elevation_deg": np.asarray(paths.arrival_el_deg)[rows][valid].astype(np.float64)}
    sec, nanosec = (stamp.sec, stamp.nanosec) if hasattr(stamp, "sec") else stamp
    w, e = (np.asarray(a, dtype=np.float64).reshape(3) for a in (antenna_world_m, antenna_ecef_m))
    cols = {"header.stamp.sec": np.array([sec], dtype=np.int32), "header.stamp.nanosec": np.array([nanosec], np.uint32),
            "header.frame_id": np.array([frame_id])}
    for name, xyz in (("antenna_world_m", w), ("antenna_ecef_m", e)):
        for i, a in enumerate("xyz"):
            cols[f"{name}.{a}"] = xyz[i:i + 1].copy()
    def col(a, dtype):
        return np.asarray(a).astype(dtype, copy=False).reshape(n)
    cols["satellites"] = (np.array([n], dtype=np.int64), {
        "sv": col(sv, str), "azimuth_deg": col(az_deg, np.float64), "elevation_deg": col(el_deg, np.float64),
        "state": col(state, np.uint8), "attenuation_db": col(attenuation_db, np.float64),
        "extra_path_m": col(extra_path_m, np.float64), "fraction_blocked": col(fraction_blocked, np.float32),
        "reflections": (counts, refl)})
    return cols


def main(args=None):
    return run_node(FleetVisibilityNode, args)


if __name__ == "__main__":
    sys.exit(main())
