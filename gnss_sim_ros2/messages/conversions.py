"""Core arrays <-> gnss_sim_msgs: satellite states, visibility and observations, as message objects and as the
CDR bytes that travel (cdr.py). The receiver's solution messages: solution.py; rtkrcv's: rtk.py."""
from __future__ import annotations

import numpy as np

from gnss_sim_ros2.core.ephemeris.states import SatelliteStates
from gnss_sim_ros2.core.memo import BoundedCache
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


def observations_to_msg(header, t: GnssTime, obs):
    """``gnss_sim_msgs/Observations`` of one epoch: one SignalObservation per signal of ``obs``
    (core.receiver EpochObservations); encode_observations writes its bytes."""
    from gnss_sim_msgs.msg import Observations, SignalObservation

    week, tow = t.week_tow()
    msg = Observations(header=header, gps_week=int(week), gps_tow_s=float(tow),
                       receiver_clock_offset_s=float(obs.clock_bias_s))
    msg.observations = [SignalObservation(
        sv=str(obs.sv[j]), code=str(obs.code[j]), frequency_hz=float(obs.frequency_hz[j]),
        pseudorange_m=float(obs.pseudorange_m[j]), carrier_phase_cycles=float(obs.carrier_phase_cyc[j]),
        doppler_hz=float(obs.doppler_hz[j]), cn0_dbhz=float(obs.cn0_dbhz[j]),
        lock_time_s=float(obs.lock_time_s[j]), lli=int(obs.lli[j]), loss_of_lock=bool(obs.lli[j] & 1),
        half_cycle_ambiguity=bool(obs.lli[j] & 2)) for j in range(len(obs.sv))]
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


# ---------------------------------------------------------------------------------------------------------
# The same conversions straight between core arrays and the CDR bytes that travel (gnss_sim_ros2/messages/cdr.py):
# no message object per satellite. Each gives what its message twin above gives (test/test_cdr_codec.py).

def stamp_of(data: bytes) -> tuple[int, int]:
    """(sec, nanosec) of the header.stamp of a serialised message that starts with a std_msgs/Header."""
    from gnss_sim_ros2.messages.cdr import CdrError

    if len(data) < 12 or data[:2] != b"\x00\x01":
        raise CdrError("not little-endian CDR")
    return int.from_bytes(data[4:8], "little", signed=True), int.from_bytes(data[8:12], "little")


def _header(stamp, frame_id: str) -> dict:
    sec, nanosec = (stamp.sec, stamp.nanosec) if hasattr(stamp, "sec") else stamp
    return {"header.stamp.sec": sec, "header.stamp.nanosec": nanosec, "header.frame_id": frame_id}


def encode_states(states: SatelliteStates, t: GnssTime, stamp, frame_id: str, iono: dict | None = None) -> bytes:
    """The CDR bytes of states_to_msg(states, t, Header(stamp, frame_id), iono)."""
    from gnss_sim_ros2.messages.cdr import STATES_CODEC

    week, tow = t.week_tow()
    sv = np.asarray(states.sv).tolist()
    n = len(sv)
    pos, vel, acc = (np.asarray(a, dtype=float).reshape(n, 3) for a in
                     (states.pos_ecef_m, states.vel_ecef_mps, states.acc_ecef_mps2))
    cols = {
        "sv": np.asarray(states.sv), "system": np.array([ord(s[0]) for s in sv], dtype=np.int64),
        "prn": np.array([int(s[1:]) for s in sv], dtype=np.int64),
        "glonass_channel": np.asarray(states.glo_channel, dtype=np.int64),
        "clock_bias_s": states.clock_bias_s, "clock_drift_sps": states.clock_drift_sps,
        "relativistic_correction_s": states.relativistic_s, "group_delay_s": states.tgd_s,
        "health": np.asarray(states.health, dtype=np.int64), "issue_of_data": np.asarray(states.iode, dtype=np.int64),
        "ephemeris_age_s": states.age_s, "orbit_source": np.full(n, _SOURCES.get(states.source.split("+")[0], 0)),
    }
    for name, a in (("position_ecef_m", pos), ("velocity_ecef_mps", vel), ("acceleration_ecef_mps2", acc)):
        cols[f"{name}.x"], cols[f"{name}.y"], cols[f"{name}.z"] = a[:, 0], a[:, 1], a[:, 2]
    both = bool(iono and iono.get("GPSA") and iono.get("GPSB"))
    gal = list(iono["GAL"][:3]) if iono and iono.get("GAL") else []
    return STATES_CODEC.encode({
        **_header(stamp, frame_id), "gps_week": int(week), "gps_tow_s": float(tow), "states": ([n], cols),
        "klobuchar_alpha": [float(v) for v in iono["GPSA"]] if both else [],
        "klobuchar_beta": [float(v) for v in iono["GPSB"]] if both else [],
        "nequick_coefficients": [float(v) for v in gal]})


def states_as_decoded(states: SatelliteStates, t: GnssTime, stamp, iono: dict | None = None):
    """What decode_states(encode_states(states, t, stamp, frame, iono)) gives, without the bytes: the ephemeris node
    hands it with the message to the nodes of its process (nodes/in_process.py), which then skip the decode
    (test_messages holds the two equal, bit for bit)."""
    sec, nanosec = (stamp.sec, stamp.nanosec) if hasattr(stamp, "sec") else stamp
    week, tow = t.week_tow()
    t_msg = GnssTime.from_week_tow(int(week), float(tow))
    n = len(states.sv)

    def rows(a, dtype):
        return np.array(a, dtype=dtype).reshape(n)

    source = states.source.split("+")[0] if n else "broadcast"
    states_msg = SatelliteStates(
        t=t_msg, sv=np.asarray(states.sv).astype("<U3"),
        pos_ecef_m=np.array(states.pos_ecef_m, dtype=float).reshape(n, 3),
        vel_ecef_mps=np.array(states.vel_ecef_mps, dtype=float).reshape(n, 3),
        acc_ecef_mps2=np.array(states.acc_ecef_mps2, dtype=float).reshape(n, 3),
        clock_bias_s=rows(states.clock_bias_s, float), clock_drift_sps=rows(states.clock_drift_sps, float),
        relativistic_s=rows(states.relativistic_s, float), tgd_s=rows(states.tgd_s, float),
        health=rows(states.health, np.int64), iode=rows(states.iode, np.int64), age_s=rows(states.age_s, float),
        glo_channel=rows(states.glo_channel, np.int64), source=source if source in _SOURCES else "broadcast")
    out = {}
    if iono and iono.get("GPSA") and iono.get("GPSB") and len(iono["GPSA"]) == 4 and len(iono["GPSB"]) == 4:
        out["GPSA"], out["GPSB"] = [float(v) for v in iono["GPSA"]], [float(v) for v in iono["GPSB"]]
    if iono and iono.get("GAL") and len(iono["GAL"]) >= 3:
        out["GAL"] = [float(v) for v in iono["GAL"][:3]]
    return (int(sec), int(nanosec)), t_msg, states_msg, out or None


def decode_states(data: bytes) -> tuple[tuple[int, int], GnssTime, SatelliteStates, dict | None]:
    """(stamp (sec, nanosec), epoch, SatelliteStates, iono) of serialised gnss_sim_msgs/SatelliteStates: what
    states_from_msg and iono_from_msg give of the message. Raises cdr.CdrError on bytes it does not read."""
    from gnss_sim_ros2.messages.cdr import STATES_CODEC

    c = STATES_CODEC.decode(data)
    t = GnssTime.from_week_tow(int(c["gps_week"][0]), float(c["gps_tow_s"][0]))
    n_, s = c["states"]
    n = int(n_[0])
    inv = {v: k for k, v in _SOURCES.items()}

    def xyz(name):
        return np.stack([s[f"{name}.x"], s[f"{name}.y"], s[f"{name}.z"]], axis=1).astype(float).reshape(n, 3)

    states = SatelliteStates(
        t=t, sv=s["sv"].astype("<U3"), pos_ecef_m=xyz("position_ecef_m"), vel_ecef_mps=xyz("velocity_ecef_mps"),
        acc_ecef_mps2=xyz("acceleration_ecef_mps2"), clock_bias_s=s["clock_bias_s"].astype(float),
        clock_drift_sps=s["clock_drift_sps"].astype(float), relativistic_s=s["relativistic_correction_s"].astype(float),
        tgd_s=s["group_delay_s"].astype(float), health=s["health"].astype(np.int64),
        iode=s["issue_of_data"].astype(np.int64), age_s=s["ephemeris_age_s"].astype(float),
        glo_channel=s["glonass_channel"].astype(np.int64),
        source=inv.get(int(s["orbit_source"][0]), "broadcast") if n else "broadcast")
    iono = {}
    alpha, beta, gal = c["klobuchar_alpha"][1], c["klobuchar_beta"][1], c["nequick_coefficients"][1]
    if len(alpha) == 4 and len(beta) == 4:
        iono["GPSA"], iono["GPSB"] = [float(v) for v in alpha], [float(v) for v in beta]
    if len(gal) >= 3:
        iono["GAL"] = [float(v) for v in gal[:3]]
    return (int(c["header.stamp.sec"][0]), int(c["header.stamp.nanosec"][0])), t, states, iono or None


def encode_visibility(stamp, frame_id: str, antenna_world_m, antenna_ecef_m, sv, az_deg, el_deg, state,
                      attenuation_db, extra_path_m, fraction_blocked, paths=None, path_rows=None) -> bytes:
    """The CDR bytes of a gnss_sim_msgs/Visibility with one SatelliteVisibility per row (what the visibility
    node's message gave: the reflections of row ``path_rows[i]`` of ``paths`` (all rows when None) as
    reflections_to_msgs gives them)."""
    from gnss_sim_ros2.messages.cdr import VISIBILITY_CODEC

    n = len(sv)
    if paths is not None and path_rows is not None:
        paths = _Rows(paths, path_rows)
    if paths is None:
        counts = np.zeros(n, dtype=np.int64)
        refl = {k: np.zeros(0) for k in ("excess_path_m", "gamma_co_re", "gamma_co_im", "gamma_cross_re",
                                         "gamma_cross_im", "arrival_elevation_deg")}
    else:
        valid = np.isfinite(paths.excess_m)              # (n, K), the rows given
        counts = valid.sum(axis=1)
        co, cross = np.asarray(paths.gamma_co)[valid], np.asarray(paths.gamma_cross)[valid]
        refl = {"excess_path_m": paths.excess_m[valid], "gamma_co_re": co.real, "gamma_co_im": co.imag,
                "gamma_cross_re": cross.real, "gamma_cross_im": cross.imag,
                "arrival_elevation_deg": paths.arrival_el_deg[valid]}
    w, e = (np.asarray(a, dtype=float).reshape(3) for a in (antenna_world_m, antenna_ecef_m))
    sats = {"sv": np.asarray(sv), "azimuth_deg": az_deg, "elevation_deg": el_deg, "state": state,
            "attenuation_db": attenuation_db, "extra_path_m": extra_path_m, "fraction_blocked": fraction_blocked,
            "reflections": (counts, refl)}
    return VISIBILITY_CODEC.encode({
        **_header(stamp, frame_id), "antenna_world_m.x": w[0], "antenna_world_m.y": w[1], "antenna_world_m.z": w[2],
        "antenna_ecef_m.x": e[0], "antenna_ecef_m.y": e[1], "antenna_ecef_m.z": e[2], "satellites": ([n], sats)})


class _Rows:
    """The rows ``rows`` of a ScenePaths' (N, K) arrays."""

    def __init__(self, paths, rows):
        self.excess_m, self.gamma_co = paths.excess_m[rows], np.asarray(paths.gamma_co)[rows]
        self.gamma_cross, self.arrival_el_deg = np.asarray(paths.gamma_cross)[rows], paths.arrival_el_deg[rows]


def decode_visibility(data: bytes) -> dict:
    """Columns of serialised gnss_sim_msgs/Visibility (cdr.VISIBILITY: "satellites" -> (counts, columns),
    its "reflections" -> (counts, flat columns)). Raises cdr.CdrError on bytes it does not read."""
    from gnss_sim_ros2.messages.cdr import VISIBILITY_CODEC

    return VISIBILITY_CODEC.decode(data)


def visibility_antenna(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """(antenna_world_m (3,), antenna_ecef_m (3,)) of serialised gnss_sim_msgs/Visibility: the fixed fields
    after the header, read without the satellites."""
    import struct

    from gnss_sim_ros2.messages.cdr import CdrError

    if len(data) < 16 or data[:2] != b"\x00\x01":
        raise CdrError("not little-endian CDR")
    p = (12 + int.from_bytes(data[12:16], "little") + 7) & -8      # body offsets: stamp, frame_id, align 8
    if 4 + p + 48 > len(data):
        raise CdrError("message shorter than its contents")
    v = struct.unpack_from("<6d", data, 4 + p)
    return np.array(v[:3]), np.array(v[3:])


def chain_inputs_from_visibility(vis: dict, svs):
    """(antenna ECEF (3,), visibility state (N,), attenuation dB (N,), ScenePaths or None) for the satellites
    ``svs`` (rows) from decode_visibility columns: what the receiver node made of the Visibility message
    (below the horizon = not in it: blocked, no attenuation; paths as paths_from_msg gives them)."""
    from gnss_sim_ros2.core.multipath.reflections import ScenePaths
    from gnss_sim_ros2.core.vocabulary import VisibilityState

    ecef = np.array([float(vis[f"antenna_ecef_m.{a}"][0]) for a in "xyz"])
    s = vis["satellites"][1]
    js = _rows_in(s["sv"], svs)
    seen = js >= 0
    jj = np.where(seen, js, 0)
    state = np.where(seen, s["state"][jj] if len(s["sv"]) else 0, int(VisibilityState.BLOCKED)).astype(np.int64)
    att = np.where(seen, s["attenuation_db"][jj] if len(s["sv"]) else 0.0, 0.0).astype(float)
    counts, refl = s["reflections"]
    c = np.where(seen, counts[jj] if len(counts) else 0, 0)
    k = int(c.max()) if len(c) else 0
    if k == 0:
        return ecef, state, att, None
    out = ScenePaths.empty(1, len(js), k).take(0)
    first = np.cumsum(counts) - counts                            # each vis row's first reflection
    rows = np.repeat(np.arange(len(js)), c)
    slot = np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
    src = np.repeat(first[jj], c) + slot
    out.excess_m[rows, slot] = refl["excess_path_m"][src]
    out.gamma_co[rows, slot] = _complex(refl["gamma_co_re"][src], refl["gamma_co_im"][src])
    out.gamma_cross[rows, slot] = _complex(refl["gamma_cross_re"][src], refl["gamma_cross_im"][src])
    out.arrival_el_deg[rows, slot] = refl["arrival_elevation_deg"][src]
    return ecef, state, att, out


#: _rows_in's rows by the two satellite lists' bytes (the same lists come back epoch after epoch and robot after
#: robot)
_ROWS_CACHE = BoundedCache(64)


def _rows_in(vis_sv, svs) -> np.ndarray:
    """The row of each of ``svs`` in ``vis_sv`` (-1: not there; a repeated sv: its last row, as a dict of them
    gives), read-only; remembered for numpy str arrays."""
    a, b = np.asarray(vis_sv), np.asarray(svs)
    key = (a.dtype.str, a.tobytes(), b.dtype.str, b.tobytes()) if a.dtype.kind == b.dtype.kind == "U" else None
    hit = None if key is None else _ROWS_CACHE.get(key)
    if hit is None:
        index = {sv: j for j, sv in enumerate(a.tolist())}
        hit = np.array([index.get(sv, -1) for sv in b.tolist()], dtype=np.int64)
        hit.setflags(write=False)
        if key is not None:
            _ROWS_CACHE.put(key, hit)
    return hit


def _complex(re, im) -> np.ndarray:
    z = np.empty(len(re), dtype=complex)
    z.real, z.imag = re, im
    return z


def encode_observations(stamp, frame_id: str, t: GnssTime, obs) -> bytes:
    """The CDR bytes of observations_to_msg(Header(stamp, frame_id), t, obs)."""
    from gnss_sim_ros2.messages.cdr import OBSERVATIONS_CODEC

    week, tow = t.week_tow()
    lli = np.asarray(obs.lli, dtype=np.int64)
    cols = {"sv": np.asarray(obs.sv), "code": np.asarray(obs.code), "frequency_hz": obs.frequency_hz,
            "pseudorange_m": obs.pseudorange_m, "carrier_phase_cycles": obs.carrier_phase_cyc,
            "doppler_hz": obs.doppler_hz, "cn0_dbhz": obs.cn0_dbhz, "lock_time_s": obs.lock_time_s, "lli": lli,
            "loss_of_lock": (lli & 1) != 0, "half_cycle_ambiguity": (lli & 2) != 0}
    return OBSERVATIONS_CODEC.encode({**_header(stamp, frame_id), "gps_week": int(week), "gps_tow_s": float(tow),
                                      "receiver_clock_offset_s": float(obs.clock_bias_s),
                                      "observations": ([len(lli)], cols)})


# ---------------------------------------------------------------------------------------------------------
# Received bytes: the codec, or rclpy's deserialisation for bytes it does not read (big endian from another
# machine's middleware): the same result either way.

def states_from_cdr(data: bytes) -> tuple[tuple[int, int], GnssTime, SatelliteStates, dict | None]:
    """decode_states, falling back to rclpy's deserialize_message + states_from_msg / iono_from_msg."""
    from gnss_sim_ros2.messages.cdr import CdrError

    try:
        return decode_states(data)
    except CdrError:
        from gnss_sim_msgs.msg import SatelliteStates as Msg
        from rclpy.serialization import deserialize_message

        msg = deserialize_message(data, Msg)
        t, states = states_from_msg(msg)
        return (msg.header.stamp.sec, msg.header.stamp.nanosec), t, states, iono_from_msg(msg)


def visibility_from_cdr(data: bytes) -> dict:
    """decode_visibility, falling back to rclpy's deserialize_message (then the message's columns)."""
    from gnss_sim_ros2.messages.cdr import CdrError

    try:
        return decode_visibility(data)
    except CdrError:
        from gnss_sim_msgs.msg import Visibility
        from rclpy.serialization import deserialize_message

        return visibility_columns(deserialize_message(data, Visibility))


def visibility_columns(msg) -> dict:
    """decode_visibility's columns of a gnss_sim_msgs/Visibility message object."""
    from gnss_sim_ros2.messages.cdr import REFLECTED_PATH

    sats = msg.satellites
    refl = [r for s in sats for r in s.reflections]
    h = msg.header
    cols = {"header.stamp.sec": np.array([h.stamp.sec]), "header.stamp.nanosec": np.array([h.stamp.nanosec]),
            "header.frame_id": np.array([h.frame_id])}
    for name in ("antenna_world_m", "antenna_ecef_m"):
        for a in "xyz":
            cols[f"{name}.{a}"] = np.array([getattr(getattr(msg, name), a)], dtype=float)
    sat_cols = {"sv": np.array([s.sv for s in sats], dtype=str)}
    for f in ("azimuth_deg", "elevation_deg", "attenuation_db", "extra_path_m"):
        sat_cols[f] = np.array([getattr(s, f) for s in sats], dtype=float)
    sat_cols["state"] = np.array([s.state for s in sats], dtype=np.uint8)
    sat_cols["fraction_blocked"] = np.array([s.fraction_blocked for s in sats], dtype=np.float32)
    sat_cols["reflections"] = (np.array([len(s.reflections) for s in sats], dtype=np.int64),
                               {f: np.array([getattr(r, f) for r in refl], dtype=float) for f, _ in
                                REFLECTED_PATH})
    cols["satellites"] = (np.array([len(sats)]), sat_cols)
    return cols
