"""Core arrays <-> gnss_sim_msgs (the only place that knows both)."""
from __future__ import annotations

import numpy as np

from gnss_sim_ros2.core.ephemeris.states import SatelliteStates
from gnss_sim_ros2.core.time import GnssTime

_SOURCES = {"broadcast": 0, "sp3": 1, "synthetic": 2}


def states_to_msg(states: SatelliteStates, t: GnssTime, header, iono: dict | None = None):
    """``gnss_sim_msgs/SatelliteStates`` of one epoch ``t`` (``iono``: the navigation header's
    coefficients, {"GPSA": [4], "GPSB": [4], "GAL": [3]})."""
    from geometry_msgs.msg import Point, Vector3
    from gnss_sim_msgs.msg import SatelliteState
    from gnss_sim_msgs.msg import SatelliteStates as Msg

    week, tow = t.week_tow()
    msg = Msg(header=header, gps_week=int(week), gps_tow_s=float(tow))
    if iono and iono.get("GPSA") and iono.get("GPSB"):
        msg.klobuchar_alpha = [float(v) for v in iono["GPSA"]]
        msg.klobuchar_beta = [float(v) for v in iono["GPSB"]]
    if iono and iono.get("GAL"):
        msg.nequick_coefficients = [float(v) for v in iono["GAL"][:3]]
    source = _SOURCES.get(states.source.split("+")[0], 0)
    pos, vel, acc = states.pos_ecef_m, states.vel_ecef_mps, states.acc_ecef_mps2
    out = []
    for i, sv in enumerate(states.sv):
        sv = str(sv)
        out.append(SatelliteState(
            sv=sv, system=ord(sv[0]), prn=int(sv[1:]), glonass_channel=int(states.glo_channel[i]),
            position_ecef_m=Point(x=float(pos[i, 0]), y=float(pos[i, 1]), z=float(pos[i, 2])),
            velocity_ecef_mps=Vector3(x=float(vel[i, 0]), y=float(vel[i, 1]), z=float(vel[i, 2])),
            acceleration_ecef_mps2=Vector3(x=float(acc[i, 0]), y=float(acc[i, 1]), z=float(acc[i, 2])),
            clock_bias_s=float(states.clock_bias_s[i]), clock_drift_sps=float(states.clock_drift_sps[i]),
            relativistic_correction_s=float(states.relativistic_s[i]), group_delay_s=float(states.tgd_s[i]),
            health=int(states.health[i]), issue_of_data=int(states.iode[i]),
            ephemeris_age_s=float(states.age_s[i]), orbit_source=source,
        ))
    msg.states = out
    return msg


def iono_from_msg(msg) -> dict | None:
    """The navigation header's ionosphere coefficients carried by a ``SatelliteStates`` message (the dict
    states_to_msg takes: "GPSA"/"GPSB" Klobuchar, "GAL" NeQuick-G), None when it carries none."""
    iono = {}
    if len(msg.klobuchar_alpha) == 4 and len(msg.klobuchar_beta) == 4:
        iono["GPSA"] = [float(v) for v in msg.klobuchar_alpha]
        iono["GPSB"] = [float(v) for v in msg.klobuchar_beta]
    if len(msg.nequick_coefficients) >= 3:
        iono["GAL"] = [float(v) for v in msg.nequick_coefficients[:3]]
    return iono or None


def states_from_msg(msg) -> tuple[GnssTime, SatelliteStates]:
    """(epoch, SatelliteStates) from ``gnss_sim_msgs/SatelliteStates``."""
    t = GnssTime.from_week_tow(msg.gps_week, msg.gps_tow_s)
    s = msg.states
    n = len(s)
    inv = {v: k for k, v in _SOURCES.items()}
    states = SatelliteStates(
        t=t,
        sv=np.array([x.sv for x in s], dtype="<U3"),
        pos_ecef_m=np.array([[x.position_ecef_m.x, x.position_ecef_m.y, x.position_ecef_m.z] for x in s]).reshape(n, 3),
        vel_ecef_mps=np.array([[x.velocity_ecef_mps.x, x.velocity_ecef_mps.y, x.velocity_ecef_mps.z]
                               for x in s]).reshape(n, 3),
        acc_ecef_mps2=np.array([[x.acceleration_ecef_mps2.x, x.acceleration_ecef_mps2.y, x.acceleration_ecef_mps2.z]
                                for x in s]).reshape(n, 3),
        clock_bias_s=np.array([x.clock_bias_s for x in s], dtype=float),
        clock_drift_sps=np.array([x.clock_drift_sps for x in s], dtype=float),
        relativistic_s=np.array([x.relativistic_correction_s for x in s], dtype=float),
        tgd_s=np.array([x.group_delay_s for x in s], dtype=float),
        health=np.array([x.health for x in s], dtype=np.int64),
        iode=np.array([x.issue_of_data for x in s], dtype=np.int64),
        age_s=np.array([x.ephemeris_age_s for x in s], dtype=float),
        glo_channel=np.array([x.glonass_channel for x in s], dtype=np.int64),
        source=inv.get(s[0].orbit_source, "broadcast") if n else "broadcast",
    )
    return t, states


def reflections_to_msgs(paths, i: int) -> list:
    """``gnss_sim_msgs/ReflectedPath`` list of satellite row ``i`` of ``paths`` (multipath.reflections.ScenePaths
    of one antenna, arrays (N, K)); the valid slots in their order (strongest first), [] without paths."""
    from gnss_sim_msgs.msg import ReflectedPath

    if paths is None:
        return []
    out = []
    for k in np.flatnonzero(np.isfinite(paths.excess_m[i])):
        co, x = complex(paths.gamma_co[i, k]), complex(paths.gamma_cross[i, k])
        out.append(ReflectedPath(excess_path_m=float(paths.excess_m[i, k]), gamma_co_re=co.real, gamma_co_im=co.imag,
                                 gamma_cross_re=x.real, gamma_cross_im=x.imag,
                                 arrival_elevation_deg=float(paths.arrival_el_deg[i, k])))
    return out


def paths_from_msg(vis_by_sv: dict, svs):
    """ScenePaths (N, K) for the satellites ``svs`` (rows) from ``{sv: gnss_sim_msgs/SatelliteVisibility}``
    (K: the most reflections of one satellite; empty slots NaN as the visibility cast leaves them), or None
    when no satellite has a reflection (what the chain takes without multipath)."""
    from gnss_sim_ros2.core.multipath.reflections import ScenePaths

    refl = [vis_by_sv[sv].reflections if sv in vis_by_sv else [] for sv in svs]
    k = max((len(r) for r in refl), default=0)
    if k == 0:
        return None
    out = ScenePaths.empty(1, len(refl), k).take(0)
    for i, rs in enumerate(refl):
        for j, r in enumerate(rs):
            out.excess_m[i, j] = r.excess_path_m
            out.gamma_co[i, j] = complex(r.gamma_co_re, r.gamma_co_im)
            out.gamma_cross[i, j] = complex(r.gamma_cross_re, r.gamma_cross_im)
            out.arrival_el_deg[i, j] = r.arrival_elevation_deg
    return out
