"""rtkrcv's solutions as ROS messages (nodes/rtk_node.py): ``sensor_msgs/NavSatFix`` with the RTKLIB quality as
its status, the ENU velocity, the moving baseline's heading as ``sensor_msgs/Imu`` and the node's
``diagnostic_msgs/DiagnosticStatus``."""
from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from sensor_msgs.msg import Imu, NavSatFix

from gnss_sim_ros2.core.rtk.solution import Q_FIX, Q_FLOAT, QUALITY_NAMES, RtkBaseline, RtkSolution
from gnss_sim_ros2.messages.solution import twist_to_msg


def rtk_fix_to_msg(header, sol: RtkSolution, service: int) -> NavSatFix:
    """NavSatFix of one rtkrcv solution: status from its quality, ENU covariance (row-major) from its std."""
    fix = NavSatFix(header=header)
    fix.status.status = int(sol.status)
    fix.status.service = int(service)
    fix.latitude, fix.longitude, fix.altitude = float(sol.lat_deg), float(sol.lon_deg), float(sol.h_m)
    fix.position_covariance = [float(v) for v in np.asarray(sol.cov_enu_m2).ravel()]
    fix.position_covariance_type = NavSatFix.COVARIANCE_TYPE_KNOWN
    return fix


def rtk_vel_to_msg(header, sol: RtkSolution):
    """ENU velocity with its covariance; rtkrcv wrote no velocity covariance (dynamics off): -1 in element 0."""
    cov = np.asarray(sol.cov_vel_enu_m2ps2, dtype=float)
    return twist_to_msg(header, sol.vel_enu_mps, cov if np.any(cov) else None)


def heading_to_msg(header, b: RtkBaseline) -> Imu:
    """The baseline's yaw as an Imu orientation (ENU, counter-clockwise from east: 90 deg - heading)."""
    msg = Imu(header=header)
    yaw = np.radians(90.0 - b.heading_deg)
    msg.orientation.z, msg.orientation.w = float(np.sin(yaw / 2)), float(np.cos(yaw / 2))
    cov = np.zeros(9)
    cov[0] = cov[4] = 1e6                                 # roll, pitch: not measured
    cov[8] = float(np.radians(b.heading_sd_deg) ** 2)
    msg.orientation_covariance = [float(x) for x in cov]
    msg.angular_velocity_covariance = [-1.0] + [0.0] * 8
    msg.linear_acceleration_covariance = [-1.0] + [0.0] * 8
    return msg


def rtk_status_to_msg(name: str, sol: RtkSolution | RtkBaseline | None, stamp, running: bool, counts: dict,
                      bytes_in: dict, rover_epochs_without_base: int) -> DiagnosticStatus:
    """The rtk node's status: the last solution (None: none yet; ``stamp`` its builtin_interfaces/Time) with
    quality, ratio, satellites, age of the base data (and the heading of a baseline), epochs per quality
    (``counts``), bytes received per stream and rover epochs sent without their base epoch."""
    if sol is None:
        level, text = DiagnosticStatus.WARN, "no solution yet"
    else:
        level = DiagnosticStatus.OK if sol.q in (Q_FIX, Q_FLOAT) else DiagnosticStatus.WARN
        text = f"{sol.quality}, ratio {sol.ratio:.1f}, {sol.ns} satellites, age {sol.age_s:.1f} s"
        if isinstance(sol, RtkBaseline):
            text += f", heading {sol.heading_deg:.2f} +- {sol.heading_sd_deg:.2f} deg"
    values = {"running": str(running).lower(), "quality": sol.quality if sol else "none",
              "stamp": f"{stamp.sec}.{stamp.nanosec:09d}" if stamp is not None else "",
              "ratio": f"{sol.ratio:.1f}" if sol else "", "satellites": str(sol.ns) if sol else "",
              "age_s": f"{sol.age_s:.2f}" if sol else "",
              **({"heading_deg": f"{sol.heading_deg:.3f}", "heading_sd_deg": f"{sol.heading_sd_deg:.3f}",
                  "baseline_m": f"{sol.length_m:.4f}"} if isinstance(sol, RtkBaseline) else {}),
              **{f"epochs_{QUALITY_NAMES[q]}": str(n) for q, n in counts.items() if n},
              "rover_bytes": str(bytes_in["rover"]), "base_bytes": str(bytes_in["base"]),
              "rover_epochs_without_base": str(rover_epochs_without_base)}
    return DiagnosticStatus(level=level, name=name, message=text, hardware_id="rtkrcv",
                            values=[KeyValue(key=k, value=v) for k, v in values.items()])
