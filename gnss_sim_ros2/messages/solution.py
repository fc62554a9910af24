"""The receiver's solution as ROS messages: ``sensor_msgs/NavSatFix``, the ENU velocity
(``geometry_msgs/TwistWithCovarianceStamped``) and ``gnss_sim_msgs/ReceiverStatus`` of a core.solver PvtSolution."""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import TwistWithCovarianceStamped
from sensor_msgs.msg import NavSatFix, NavSatStatus


def navsatfix_service_flags() -> dict[str, int]:
    """{system letter: NavSatStatus.service bit} (QZSS flies GPS signals; NavIC has no bit)."""
    return {"G": NavSatStatus.SERVICE_GPS, "J": NavSatStatus.SERVICE_GPS, "R": NavSatStatus.SERVICE_GLONASS,
            "C": NavSatStatus.SERVICE_COMPASS, "E": NavSatStatus.SERVICE_GALILEO}


def navsatfix_service(systems) -> int:
    """NavSatStatus.service bits of the systems (letters) a fix used."""
    flags = navsatfix_service_flags()
    return int(np.bitwise_or.reduce([flags.get(s, 0) for s in systems] or [0]))


def fix_to_msg(header, sol) -> NavSatFix:
    """``sensor_msgs/NavSatFix`` of a core.solver PvtSolution. position_covariance is the solver's own
    ``cov_enu_m2`` (already scaled by the a-posteriori variance factor, solver.SolverConfig.scale_covariance),
    row-major East, North, Up as the message defines it (sensor_msgs/NavSatFix.msg); no fix: NaN position,
    COVARIANCE_TYPE_UNKNOWN."""
    fix = NavSatFix(header=header)
    fix.status.service = navsatfix_service({s[0] for s in sol.sv_used})
    if sol.is_fix:
        fix.status.status = NavSatStatus.STATUS_FIX
        fix.latitude, fix.longitude, fix.altitude = float(sol.lat_deg), float(sol.lon_deg), float(sol.h_m)
        fix.position_covariance = [float(v) for v in np.asarray(sol.cov_enu_m2, dtype=float).reshape(9)]
        fix.position_covariance_type = NavSatFix.COVARIANCE_TYPE_KNOWN
    else:
        fix.status.status = NavSatStatus.STATUS_NO_FIX
        fix.latitude = fix.longitude = fix.altitude = float("nan")
        fix.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
    return fix


def twist_to_msg(header, vel_enu_mps=None, cov_vel_enu_m2ps2=None) -> TwistWithCovarianceStamped:
    """An ENU velocity [m/s] with its covariance [m^2/s^2] (the linear block, row-major 6 x 6; angular velocity
    unknown: -1 on its diagonal). ``vel_enu_mps`` None: no velocity (-1 in element 0, REP-145, zero twist);
    ``cov_vel_enu_m2ps2`` None: a velocity without covariance (-1 in element 0)."""
    msg = TwistWithCovarianceStamped(header=header)
    if vel_enu_mps is None:
        msg.twist.covariance = [-1.0] + [0.0] * 35
        return msg
    v = np.asarray(vel_enu_mps, dtype=float)
    msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.linear.z = (float(x) for x in v)
    cov = np.zeros((6, 6))
    if cov_vel_enu_m2ps2 is None:
        cov[0, 0] = -1.0
    else:
        cov[:3, :3] = cov_vel_enu_m2ps2
    cov[3, 3] = cov[4, 4] = cov[5, 5] = -1.0
    msg.twist.covariance = [float(x) for x in cov.ravel()]
    return msg


def vel_to_msg(header, sol) -> TwistWithCovarianceStamped:
    """The ENU velocity of a PvtSolution with the solver's covariance; none when it has no velocity fix."""
    v = np.asarray(sol.vel_enu_mps)
    if sol.vel_status == "fix" and np.all(np.isfinite(v)):
        return twist_to_msg(header, v, sol.cov_vel_enu_m2ps2)
    return twist_to_msg(header)


def status_to_msg(header, obs, sol, elevation_mask_deg: float, bands: dict | None = None):
    """``gnss_sim_msgs/ReceiverStatus`` of one epoch: satellites visible (above the mask and not blocked), tracked
    and used, systems used, DOPs, the receiver clock, the solution type and, without a fix, its reason; ``bands``:
    the jamming indicator and AGC per band ({band digit: {"jamming_indicator", "agc_db"}}, ThreatRuntime.status)."""
    from gnss_sim_msgs.msg import ReceiverStatus

    above = obs.sat_el_deg >= elevation_mask_deg
    jam = sorted((bands or {}).items())
    return ReceiverStatus(
        header=header, satellites_visible=int(np.sum(above & (obs.sat_vis_state != 1))),
        satellites_tracked=int(obs.n_tracked_sats), satellites_used=int(sol.n_used),
        systems_used=sorted({s[0] for s in sol.sv_used}), gdop=float(sol.gdop), pdop=float(sol.pdop),
        hdop=float(sol.hdop), vdop=float(sol.vdop), tdop=float(sol.tdop), clock_bias_s=float(obs.clock_bias_s),
        clock_drift_sps=float(obs.clock_drift_sps),
        solution_type=ReceiverStatus.SOLUTION_SINGLE if sol.is_fix else ReceiverStatus.SOLUTION_NONE,
        reason="" if sol.is_fix else sol.reason, jam_bands=[b for b, _ in jam],
        jam_ind=[int(v["jamming_indicator"]) for _, v in jam], agc_db=[float(v["agc_db"]) for _, v in jam])
