"""rosbag2 bags of ``gnss_sim_msgs/msg/Observations`` -> :class:`~gnss_sim_ros2.core.rinex.obs_table.ObsTable`
(read with rosbags, no rclpy)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .rinex.obs_table import EPOCH_MATCH_NS, GPS_EPOCH_NP, ObsTable
from .time import GnssTime


def is_bag(path) -> bool:
    """A rosbag2 folder (metadata.yaml) or a single .mcap/.db3 file."""
    p = Path(path)
    return (p.is_dir() and (p / "metadata.yaml").is_file()) or p.suffix in (".mcap", ".db3")


def bag_typestore():
    """rosbags type store with gnss_sim_msgs registered (same as recorder.typestore(), without rclpy)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    msg_dir = Path(__file__).resolve().parents[2] / "msg_pkg" / "msg"
    if not msg_dir.is_dir():
        from ament_index_python.packages import get_package_share_directory

        msg_dir = Path(get_package_share_directory("gnss_sim_msgs")) / "msg"
    store = get_typestore(Stores.ROS2_KILTED)
    add = {}
    for f in sorted(msg_dir.glob("*.msg")):
        add.update(get_types_from_msg(f.read_text(), f"gnss_sim_msgs/msg/{f.stem}"))
    store.register(add)
    return store


def load_bag(path, tlim=None, topic: str | None = None) -> ObsTable:
    """Every ``gnss_sim_msgs/msg/Observations`` message of a bag (or of ``topic``) as an ObsTable.

    Epoch time: ``gps_week`` + ``gps_tow_s`` (the receiver epoch, GPS time).
    """
    from rosbags.highlevel import AnyReader

    path = Path(path)
    rows: dict[tuple[int, str, str], float] = {}
    freq: dict[tuple[str, str], float] = {}
    times: set[int] = set()
    try:
        reader_cm = AnyReader([path], default_typestore=bag_typestore())
        with reader_cm as reader:
            conns = [c for c in reader.connections if c.msgtype == "gnss_sim_msgs/msg/Observations"
                     and (topic is None or c.topic == topic)]
            if not conns:
                have = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
                raise ValueError(f"{path}: no gnss_sim_msgs/msg/Observations topic"
                                 f"{'' if topic is None else ' ' + topic} in the bag (topics: {', '.join(have)})")
            lo = hi = None
            if tlim is not None:
                lo, hi = (int((np.datetime64(t, "ns") - GPS_EPOCH_NP) / np.timedelta64(1, "ns")) for t in tlim)
            for conn, _, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, conn.msgtype)
                t = GnssTime.from_week_tow(int(msg.gps_week), float(msg.gps_tow_s), "GPS")
                ns = int(t.sec) * 1_000_000_000 + int(round(float(t.frac) * 1e9))
                ns = int(round(ns / 1000.0)) * 1000   # microseconds, like RINEX/georinex labels
                if lo is not None and not (lo - EPOCH_MATCH_NS <= ns <= hi + EPOCH_MATCH_NS):
                    continue
                times.add(ns)
                for o in msg.observations:
                    sv, code = str(o.sv), str(o.code)
                    freq[(sv, code)] = float(o.frequency_hz)
                    for kind, v in (("C", o.pseudorange_m), ("L", o.carrier_phase_cycles), ("D", o.doppler_hz),
                                    ("S", o.cn0_dbhz)):
                        if np.isfinite(v):
                            rows[(ns, sv, kind + code)] = float(v)
    except ValueError:
        raise
    except Exception as exc:  # noqa: BLE001  rosbags raises its own kinds
        raise ValueError(f"{path}: could not read the bag: {exc}") from exc
    t_sorted = np.array(sorted(times), dtype=np.int64)
    svs = np.array(sorted({sv for _, sv, _ in rows}), dtype="<U3")
    ti = {t: i for i, t in enumerate(t_sorted.tolist())}
    si = {s: j for j, s in enumerate(svs.tolist())}
    values: dict[str, np.ndarray] = {}
    for (ns, sv, code), v in rows.items():
        a = values.get(code)
        if a is None:
            a = values[code] = np.full((len(t_sorted), len(svs)), np.nan)
        a[ti[ns], si[sv]] = v
    values = {c: values[c] for c in sorted(values, key=lambda c: (c[1], c[2], "CLDS".index(c[0])))}
    return ObsTable(GPS_EPOCH_NP + t_sorted.astype("timedelta64[ns]"), svs, values, str(path), "bag", None, {}, freq)
