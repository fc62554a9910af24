"""The numpy CDR codec (gnss_sim_ros2/messages/cdr.py) against rclpy's own serialisation, field by field and byte for
byte (every byte that is not alignment padding: rclpy leaves padding uninitialised), and the conversions that
use it (conversions.encode_* / decode_*) against their message twins (states_to_msg, states_from_msg, ...)."""
from __future__ import annotations

import numpy as np
import pytest

from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
from gnss_sim_ros2.core.multipath.reflections import ScenePaths
from gnss_sim_ros2.core.time import GnssTime
from gnss_sim_ros2.messages import cdr, conversions

rclpy_serialization = pytest.importorskip(
    "rclpy.serialization", reason="rclpy is not installed (run make test, or source ROS 2): the codec is checked "
    "against its serialisation")
msgs = pytest.importorskip("gnss_sim_msgs.msg", reason="gnss_sim_msgs is not built (run make test)")
serialize_message, deserialize_message = rclpy_serialization.serialize_message, rclpy_serialization.deserialize_message

T0 = GnssTime.from_iso("2025-06-01T10:00:00")


def _same_bytes(codec: cdr.Codec, cols: dict, rclpy_bytes: bytes) -> bytes:
    """The codec's bytes of ``cols``; asserts they equal rclpy's wherever they are not padding (the bytes
    that change with the padding value) and that the lengths agree up to rclpy's trailing slack."""
    ours = codec.encode(cols)
    other = codec.encode(cols, pad=0xFF)
    assert len(ours) == len(other) and len(ours) % 4 == 0
    pad = np.frombuffer(ours, np.uint8) != np.frombuffer(other, np.uint8)
    assert len(rclpy_bytes) >= len(ours) - 3          # rclpy's serialised size may round up, never down
    theirs = np.frombuffer(rclpy_bytes[:len(ours)], np.uint8)
    data = np.frombuffer(ours, np.uint8)
    n = min(len(theirs), len(data))
    diff = np.flatnonzero((theirs[:n] != data[:n]) & ~pad[:n])
    assert diff.size == 0, f"bytes differ at {diff[:10]} of {len(ours)}"
    assert not np.any(data[n:] & ~pad[n:])             # beyond rclpy's length: only our zero padding
    return ours


def _states(systems="GRECJI"):
    provider, _ = open_ephemeris("synthetic", T0, 60.0, systems)
    return provider, provider.states(T0, systems=systems)


@pytest.mark.parametrize("iono", [None, {"GPSA": [1e-8, 2e-8, -6e-8, 1e-7], "GPSB": [9e4, 1e5, -6e4, -3e5],
                                         "GAL": [87.75, 0.41797, -0.010742]}, {"GAL": [1.0, 2.0, 3.0, 4.0]}])
def test_states_bytes_equal_rclpy(iono):
    from std_msgs.msg import Header

    _, st = _states()
    header = Header(frame_id="earth")
    header.stamp.sec, header.stamp.nanosec = 1234, 500_000_000
    msg = conversions.states_to_msg(st, T0, header, iono)
    ours = conversions.encode_states(st, T0, (1234, 500_000_000), "earth", iono)
    _same_bytes(cdr.STATES_CODEC, cdr.STATES_CODEC.decode(ours), serialize_message(msg))
    assert deserialize_message(ours, msgs.SatelliteStates) == msg
    # decoding rclpy's bytes gives what the message conversions give
    stamp, t, back, iono_back = conversions.decode_states(serialize_message(msg))
    t_ref, ref = conversions.states_from_msg(msg)
    assert stamp == (1234, 500_000_000) and t == t_ref
    for name in ("sv", "pos_ecef_m", "vel_ecef_mps", "acc_ecef_mps2", "clock_bias_s", "clock_drift_sps",
                 "relativistic_s", "tgd_s", "health", "iode", "age_s", "glo_channel"):
        a, b = getattr(back, name), getattr(ref, name)
        assert a.dtype == b.dtype and a.shape == b.shape, name
        np.testing.assert_array_equal(a, b, err_msg=name)
    assert back.source == ref.source
    assert iono_back == conversions.iono_from_msg(msg)


IONOS = [None, {"GPSA": [1e-8, 2e-8, -6e-8, 1e-7], "GPSB": [9e4, 1e5, -6e4, -3e5], "GAL": [87.75, 0.41797, -0.010742]},
         {"GAL": [1.0, 2.0, 3.0, 4.0]}, {"GPSA": [1e-8, 2e-8, -6e-8, 1e-7], "GPSB": [9e4, 1e5, -6e4]},
         {"GPSA": [np.float32(1e-8)] * 4, "GPSB": [1, 2, 3, 4], "GAL": [1.0, 2.0]}]


@pytest.mark.parametrize("iono", IONOS)
@pytest.mark.parametrize("case", ["all", "empty", "sp3+clk", "unknown source", "float32 and lists", "one row"])
def test_states_as_decoded_is_the_decode_of_the_bytes(iono, case):
    """What the ephemeris node hands in-process beside its message (conversions.states_as_decoded) is, bit for bit
    and dtype for dtype, what decode_states gives of encode_states' bytes."""
    import dataclasses

    _, st = _states()
    if case == "empty":
        st = st.select(np.zeros(0, dtype=np.int64))
    elif case == "one row":
        st = st.select(np.array([3]))
    elif case in ("sp3+clk", "unknown source"):
        st = dataclasses.replace(st, source="sp3+clk" if case == "sp3+clk" else "almanac")
    elif case == "float32 and lists":
        st = dataclasses.replace(st, sv=list(st.sv), pos_ecef_m=st.pos_ecef_m.astype(np.float32),
                                 health=st.health.astype(np.int32).tolist(), tgd_s=st.tgd_s.astype(np.float32))
    t = T0 + 0.1          # a tow with a fraction
    stamp = (1234, 100_000_000)
    ref = conversions.decode_states(conversions.encode_states(st, t, stamp, "earth", iono))
    got = conversions.states_as_decoded(st, t, stamp, iono)
    assert got[0] == ref[0] and got[1] == ref[1] and got[3] == ref[3]
    a, b = got[2], ref[2]
    assert a.t == b.t and a.source == b.source
    for name in ("sv", "pos_ecef_m", "vel_ecef_mps", "acc_ecef_mps2", "clock_bias_s", "clock_drift_sps",
                 "relativistic_s", "tgd_s", "health", "iode", "age_s", "glo_channel"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x.dtype, x.shape, x.flags.c_contiguous) == (y.dtype, y.shape, y.flags.c_contiguous), name
        assert x.tobytes() == y.tobytes(), name


def test_empty_messages_and_odd_strings():
    """No satellite, empty frame id, strings of other lengths (alignment changes from element to element),
    non-ASCII text: field by field equal to rclpy's message both ways."""
    from geometry_msgs.msg import Point

    for frame in ("", "e", "earth", "wörld_frame"):
        m = msgs.SatelliteStates()
        m.header.frame_id = frame
        m.gps_week, m.gps_tow_s = 2369, 12.25
        cols = cdr.STATES_CODEC.decode(serialize_message(m))
        assert cols["states"][0].tolist() == [0] and cols["header.frame_id"][0] == frame
        assert deserialize_message(cdr.STATES_CODEC.encode(cols), msgs.SatelliteStates) == m
        _same_bytes(cdr.STATES_CODEC, cols, serialize_message(m))
        m.states = [msgs.SatelliteState(sv=sv, prn=i, glonass_channel=-7 + i, health=i, issue_of_data=-1 - i,
                                        position_ecef_m=Point(x=1e7 + i, y=-2.5, z=float("nan")))
                    for i, sv in enumerate(["G05", "", "R7", "E11x", "C23", "ß1"])]
        m.klobuchar_alpha = [1.0]
        raw = serialize_message(m)
        cols = cdr.STATES_CODEC.decode(raw)
        assert cols["states"][1]["sv"].tolist() == ["G05", "", "R7", "E11x", "C23", "ß1"]
        back = deserialize_message(cdr.STATES_CODEC.encode(cols), msgs.SatelliteStates)
        assert [s.sv for s in back.states] == [s.sv for s in m.states]
        assert np.isnan(back.states[0].position_ecef_m.z) and back.states[3].glonass_channel == -4
        _same_bytes(cdr.STATES_CODEC, cols, raw)


def _paths(n: int, k: int, rng) -> ScenePaths:
    p = ScenePaths.empty(1, n, k).take(0)
    for i in range(n):
        for j in range(int(rng.integers(0, k + 1))):      # valid slots first, NaN after, as the cast leaves them
            p.excess_m[i, j] = rng.uniform(0.1, 80.0)
            p.gamma_co[i, j] = complex(rng.normal(), rng.normal())
            p.gamma_cross[i, j] = complex(rng.normal(), rng.normal())
            p.arrival_el_deg[i, j] = rng.uniform(-60.0, 80.0)
    return p


@pytest.mark.parametrize("k", [0, 1, 6])
def test_visibility_with_nested_reflections_equals_rclpy(k):
    """The nested ReflectedPath[] sequence of each SatelliteVisibility (empty ones among full ones)."""
    from geometry_msgs.msg import Point
    from std_msgs.msg import Header

    rng = np.random.default_rng(k)
    n = 17
    sv = [f"{'GREC'[i % 4]}{i + 1:02d}" for i in range(n)]
    az, el = rng.uniform(0, 360, n), rng.uniform(0, 90, n)
    state, att = rng.integers(0, 4, n), rng.uniform(0, 20, n)
    extra, frac = rng.uniform(0, 30, n), rng.uniform(0, 1, n).astype(np.float32)
    paths = _paths(n, k, rng) if k else None
    world, ecef = np.array([1.5, -2.25, 1.8]), np.array([4027894.0, 307045.6, 4919474.9])
    msg = msgs.Visibility(header=Header(frame_id="world"), antenna_world_m=Point(x=1.5, y=-2.25, z=1.8),
                          antenna_ecef_m=Point(x=4027894.0, y=307045.6, z=4919474.9))
    msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 100_000_000
    msg.satellites = [msgs.SatelliteVisibility(
        sv=sv[i], azimuth_deg=float(az[i]), elevation_deg=float(el[i]), state=int(state[i]),
        attenuation_db=float(att[i]), extra_path_m=float(extra[i]), fraction_blocked=float(frac[i]),
        reflections=conversions.reflections_to_msgs(paths, i)) for i in range(n)]
    ours = conversions.encode_visibility((7, 100_000_000), "world", world, ecef, sv, az, el, state, att, extra, frac,
                                         paths)
    assert deserialize_message(ours, msgs.Visibility) == msg
    raw = serialize_message(msg)
    _same_bytes(cdr.VISIBILITY_CODEC, cdr.VISIBILITY_CODEC.decode(ours), raw)
    # the receiver's inputs from rclpy's bytes equal those the message path made (rows in another order, one
    # satellite below the horizon: not in the message)
    order = [3, 0, 16, 5, 2] + [i for i in range(n) if i not in (3, 0, 16, 5, 2)]
    svs = np.array([sv[i] for i in order] + ["J02"])
    ecef_b, vis_state, att_b, paths_b = conversions.chain_inputs_from_visibility(conversions.decode_visibility(raw),
                                                                                 svs)
    by_sv = {s.sv: s for s in msg.satellites}
    np.testing.assert_array_equal(ecef_b, ecef)
    np.testing.assert_array_equal(vis_state, [by_sv[s].state if s in by_sv else 1 for s in svs])
    np.testing.assert_array_equal(att_b, [by_sv[s].attenuation_db if s in by_sv else 0.0 for s in svs])
    ref = conversions.paths_from_msg(by_sv, svs)
    if ref is None:
        assert paths_b is None
    else:
        for name in ("excess_m", "gamma_co", "gamma_cross", "arrival_el_deg"):
            np.testing.assert_array_equal(getattr(paths_b, name), getattr(ref, name), err_msg=name)


def test_observations_equal_rclpy():
    from types import SimpleNamespace

    from std_msgs.msg import Header

    rng = np.random.default_rng(3)
    n = 23
    obs = SimpleNamespace(
        sv=np.array([f"G{i:02d}" for i in range(n)]), code=np.array(["1C", "5Q", "2I"] * 7 + ["1C", "7X"]),
        frequency_hz=rng.uniform(1.1e9, 1.6e9, n), pseudorange_m=rng.uniform(2e7, 2.6e7, n),
        carrier_phase_cyc=rng.uniform(1e8, 1.4e8, n), doppler_hz=rng.uniform(-4e3, 4e3, n),
        cn0_dbhz=rng.uniform(20, 50, n), lock_time_s=rng.uniform(0, 100, n), lli=rng.integers(0, 4, n),
        clock_bias_s=1.5e-4)
    header = Header(frame_id="antenna")
    header.stamp.sec, header.stamp.nanosec = 9, 300_000_000
    msg = conversions.observations_to_msg(header, T0 + 9.3, obs)
    ours = conversions.encode_observations((9, 300_000_000), "antenna", T0 + 9.3, obs)
    assert deserialize_message(ours, msgs.Observations) == msg
    _same_bytes(cdr.OBSERVATIONS_CODEC, cdr.OBSERVATIONS_CODEC.decode(ours), serialize_message(msg))
    obs.pseudorange_m[4] = np.nan          # what the receiver does not produce (NaN != NaN: bytes compared)
    msg = conversions.observations_to_msg(header, T0 + 9.3, obs)
    ours = conversions.encode_observations((9, 300_000_000), "antenna", T0 + 9.3, obs)
    _same_bytes(cdr.OBSERVATIONS_CODEC, cdr.OBSERVATIONS_CODEC.decode(ours), serialize_message(msg))
    obs0 = SimpleNamespace(**{k: (v[:0] if isinstance(v, np.ndarray) else v) for k, v in vars(obs).items()})
    ours0 = conversions.encode_observations((9, 0), "", T0, obs0)
    msg0 = conversions.observations_to_msg(Header(), T0, obs0)
    msg0.header.stamp.sec = 9
    assert deserialize_message(ours0, msgs.Observations) == msg0


def test_bags_read_the_codecs_bytes():
    """The recorder writes the bytes as they travel: rosbags' own CDR reader takes the codec's bytes."""
    from gnss_sim_ros2.recorder import typestore

    store = typestore()
    _, st = _states("GE")
    got = store.deserialize_cdr(conversions.encode_states(st, T0, (1, 2), "earth", None),
                                "gnss_sim_msgs/msg/SatelliteStates")
    assert [s.sv for s in got.states] == list(st.sv) and got.header.stamp.nanosec == 2
    np.testing.assert_array_equal([s.position_ecef_m.x for s in got.states], st.pos_ecef_m[:, 0])


def test_bytes_the_codec_does_not_read_are_refused():
    _, st = _states("G")
    good = conversions.encode_states(st, T0, (1, 2), "earth", None)
    with pytest.raises(cdr.CdrError):
        conversions.decode_states(good[:40])                       # truncated
    with pytest.raises(cdr.CdrError):
        conversions.decode_states(b"\x00\x00\x00\x00" + good[4:])  # big endian
    bad = bytearray(good)
    bad[36:40] = (10**6).to_bytes(4, "little")                     # a sequence count past the end
    with pytest.raises(cdr.CdrError):
        conversions.decode_states(bytes(bad))


def test_schemas_follow_the_message_definitions():
    """Every field of each schema, in order, is the generated message's (names and kinds)."""
    prim = {"double": "f8", "float": "f4", "uint8": "u1", "int8": "i1", "boolean": "b1", "uint16": "u2",
            "int16": "i2", "uint32": "u4", "int32": "i4", "octet": "u1"}
    nested = {"std_msgs/Header": cdr.HEADER, "builtin_interfaces/Time": cdr.TIME, "geometry_msgs/Point": cdr.XYZ,
              "geometry_msgs/Vector3": cdr.XYZ, "gnss_sim_msgs/SatelliteState": cdr.SATELLITE_STATE,
              "gnss_sim_msgs/ReflectedPath": cdr.REFLECTED_PATH,
              "gnss_sim_msgs/SatelliteVisibility": cdr.SATELLITE_VISIBILITY,
              "gnss_sim_msgs/SignalObservation": cdr.SIGNAL_OBSERVATION}
    import importlib

    def check(cls, schema):
        fields = cls.get_fields_and_field_types()
        assert [n for n, _ in schema] == list(fields), cls.__name__
        for (name, kind), ros in zip(schema, fields.values()):
            if ros.startswith("sequence<"):
                inner = ros[len("sequence<"):-1]
                assert kind[0] == "seq"
                if inner in prim:
                    assert kind[1] == prim[inner]
                else:
                    assert kind[1] is nested[inner]
                    pkg, name_ = inner.split("/")
                    check(getattr(importlib.import_module(f"{pkg}.msg"), name_), kind[1])
            elif ros in prim:
                assert kind == prim[ros], name
            elif ros == "string":
                assert kind == "str", name
            else:
                assert kind is nested[ros], name
                pkg, name_ = ros.split("/")
                check(getattr(importlib.import_module(f"{pkg}.msg"), name_), kind)

    for cls, schema in ((msgs.SatelliteStates, cdr.SATELLITE_STATES), (msgs.Visibility, cdr.VISIBILITY),
                        (msgs.Observations, cdr.OBSERVATIONS)):
        check(cls, schema)


def test_antenna_read_from_the_head_of_the_visibility():
    for frame in ("", "world", "a_longer_world_frame"):
        data = conversions.encode_visibility((3, 4), frame, [1.0, 2.0, 3.5], [4e6, 3e5, 4.9e6], [], [], [], [], [], [],
                                             [])
        world, ecef = conversions.visibility_antenna(data)
        np.testing.assert_array_equal(world, [1.0, 2.0, 3.5])
        np.testing.assert_array_equal(ecef, [4e6, 3e5, 4.9e6])
        assert conversions.stamp_of(data) == (3, 4)
