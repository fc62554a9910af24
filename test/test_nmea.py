"""NMEA 0183 sentences, parsed back with an independent parser (pynmea2 from PyPI)."""
from __future__ import annotations

import datetime as dt
import functools
import operator

import numpy as np
import pynmea2  # noqa: E402  (an independent NMEA parser, requirements/test.txt)
import pytest

from gnss_sim_ros2.core.nmea import (
    MAX_SENTENCE_CHARS,
    epoch_sentences,
    format_lat,
    format_lon,
    gga,
    gsa,
    gsv,
    nmea_satellite,
    rmc,
    sentences_from_solution,
)
from gnss_sim_ros2.core.time import GnssTime

# 1e-5 arc minute, the last digit of ddmm.mmmmm, is 1.7e-7 deg; half of it is the rounding error
LATLON_TOL_DEG = 0.5e-5 / 60.0 + 1e-12
T_NOON = GnssTime.from_iso("2022-03-01T12:34:56.78", scale="UTC")


def parse(s: str):
    # pynmea2 verifies the checksum whenever a "*hh" is present, whatever check= says
    return pynmea2.parse(s, check=True)


def xor_checksum(s: str) -> int:
    body = s[1:s.index("*")]
    return functools.reduce(operator.xor, body.encode(), 0)


@pytest.mark.parametrize("lat, lon", [
    (59.907072474, 10.754482924),
    (-33.8688, 151.2093),       # south, east
    (40.7128, -74.0060),        # north, west
    (-54.8019, -68.3030),       # south, west
    (0.0, 179.99999),
    (1.0, -180.0),
    (89.99999999, 0.0),         # next to the North pole: minutes round to 60 -> 90 deg
    (-89.9999, 120.0),
    (12.0, 359.5),              # wraps to -0.5
])
def test_gga_roundtrip(lat, lon):
    h, sep = 123.4567, 18.25
    s = gga(T_NOON, lat, lon, h, 1, 9, 0.87, geoid_sep_m=sep, talker="GN")
    assert len(s) + 2 <= MAX_SENTENCE_CHARS
    m = parse(s)
    assert m.sentence_type == "GGA" and m.talker == "GN"
    assert m.latitude == pytest.approx(lat, abs=LATLON_TOL_DEG)
    lon_w = (lon + 180.0) % 360.0 - 180.0 if not -180.0 <= lon <= 180.0 else lon
    got = m.longitude
    assert abs((got - lon_w + 180.0) % 360.0 - 180.0) <= LATLON_TOL_DEG
    assert float(m.altitude) == pytest.approx(h - sep, abs=5e-4)  # MSL = h - N
    assert float(m.geo_sep) == pytest.approx(sep, abs=5e-4)
    assert m.gps_qual == 1 and int(m.num_sats) == 9 and float(m.horizontal_dil) == pytest.approx(0.9)
    assert m.timestamp == dt.time(12, 34, 56, 780000, tzinfo=dt.timezone.utc)
    assert int(s[-2:], 16) == xor_checksum(s)


def test_hemisphere_letters_and_carry():
    assert format_lat(-33.5) == ("3330.00000", "S")
    assert format_lon(-74.25) == ("07415.00000", "W")
    assert format_lon(-180.0) == ("18000.00000", "W")
    assert format_lon(179.99999) == ("17959.99940", "E")
    assert format_lat(89.999999999) == ("9000.00000", "N")  # 59.99999994' rounds up into 90 deg
    assert format_lat(-0.0000000001) == ("0000.00000", "N")  # rounds to zero: no "south zero"
    with pytest.raises(ValueError, match="lat_deg"):
        format_lat(91.0)


def test_rmc_midnight_rollover_date():
    # 2021-12-31 23:59:59.996 UTC rounds (2 decimals) to 00:00:00.00 on 2022-01-01
    t = GnssTime.from_iso("2021-12-31T23:59:59", scale="UTC") + 0.996
    s = rmc(t, 48.1, 11.6, 1.0, 90.0, 1, talker="GP")
    m = parse(s)
    assert m.timestamp == dt.time(0, 0, 0, tzinfo=dt.timezone.utc)
    assert m.datestamp == dt.date(2022, 1, 1)
    # and before rounding up
    m = parse(rmc(GnssTime.from_iso("2021-12-31T23:59:59.99", scale="UTC"), 48.1, 11.6, 1.0, 90.0, 1))
    assert m.datestamp == dt.date(2021, 12, 31)
    assert m.timestamp == dt.time(23, 59, 59, 990000, tzinfo=dt.timezone.utc)


def test_utc_fields_of_the_last_instant_remembered_exactly():
    """utc_time_fields remembers the last instant's fields (GGA, RMC and a fleet's robots ask for one instant): an
    instant one rounding step or one second away, or fewer decimals, gets its own fields."""
    from gnss_sim_ros2.core import nmea

    t = GnssTime.from_iso("2021-12-31T23:59:59", scale="UTC")
    asked = [(t + 0.994, 2), (t + 0.996, 2), (t + 0.994, 2), (t + 0.994, 1), (t + 1.994, 2), (t + 0.994, 2)]
    got = [nmea.utc_time_fields(x, d) for x, d in asked]
    assert got == [nmea._utc_time_fields(x, d) for x, d in asked]
    assert got[0] == ("235959.99", "311221") and got[1] == ("000000.00", "010122") and got[3][0] == "000000.0"


def test_rmc_fields_and_gps_to_utc():
    # GPS time runs 18 s ahead of UTC in 2022 (IERS Bulletin C)
    t = GnssTime.from_iso("2022-06-30T10:00:18", scale="GPS")
    s = rmc(t, -12.5, -77.25, 10.0, 271.3, 1, talker="GN")
    m = parse(s)
    assert m.timestamp == dt.time(10, 0, 0, tzinfo=dt.timezone.utc)
    assert m.datestamp == dt.date(2022, 6, 30)
    assert m.status == "A" and m.mode_indicator == "A"
    assert float(m.spd_over_grnd) == pytest.approx(10.0 * 3600 / 1852, abs=5e-4)
    assert float(m.true_course) == pytest.approx(271.3, abs=5e-3)
    assert m.latitude == pytest.approx(-12.5, abs=LATLON_TOL_DEG)
    assert m.longitude == pytest.approx(-77.25, abs=LATLON_TOL_DEG)
    bad = parse(rmc(t, 0.0, 0.0, None, None, 0))
    assert bad.status == "V" and bad.mode_indicator == "N" and bad.lat == ""


def test_no_fix_gga():
    m = parse(gga(T_NOON, 0.0, 0.0, 0.0, 0, 2, None))
    assert m.gps_qual == 0 and m.lat == "" and m.altitude is None


def test_gsa_and_gsv_parse():
    nums = [1, 3, 7, 8, 11, 14, 17, 19, 22, 28, 30, 32, 5]
    out = gsa(nums, 3, 1.61, 0.93, 1.31, system_id=1, talker="GN")
    assert len(out) == 2  # 13 satellites: 12 + 1
    m = parse(out[0])
    assert m.mode == "A" and m.mode_fix_type == "3"
    assert [int(getattr(m, f"sv_id{i:02d}")) for i in range(1, 13)] == nums[:12]
    assert float(m.pdop) == pytest.approx(1.6) and float(m.hdop) == pytest.approx(0.9)
    assert float(m.vdop) == pytest.approx(1.3)
    assert m.data[-1] == "1"  # NMEA 4.10 system ID (GPS)
    assert int(parse(out[1]).sv_id01) == 5

    sats = [(65 + i, 5.0 + 8.6 * i, 33.3 * i, 30.0 + i) for i in range(10)]
    msgs = gsv("GL", sats, signal_id=1)
    assert len(msgs) == 3
    seen = []
    for k, s in enumerate(msgs):
        m = parse(s)
        assert m.talker == "GL" and int(m.num_messages) == 3 and int(m.msg_num) == k + 1
        assert int(m.num_sv_in_view) == 10
        for j in range(1, 5):
            if len(seen) == len(sats):
                break
            prn, el, az, snr = sats[len(seen)]
            assert int(getattr(m, f"sv_prn_num_{j}")) == prn
            assert int(getattr(m, f"elevation_deg_{j}")) == round(el)
            assert int(getattr(m, f"azimuth_{j}")) == round(az) % 360
            assert int(getattr(m, f"snr_{j}")) == round(snr)
            seen.append(prn)
        assert s.split("*")[0].endswith(",1")  # signal ID
    assert seen == [s[0] for s in sats]


def test_satellite_numbering():
    assert nmea_satellite("G05") == ("GP", 5)
    assert nmea_satellite("R07") == ("GL", 71)
    assert nmea_satellite("S20") == ("GP", 33)  # PRN 120
    assert nmea_satellite("E11") == ("GA", 11)
    assert nmea_satellite("C23") == ("GB", 23)
    assert nmea_satellite("J02") == ("GQ", 2)
    assert nmea_satellite("I03") == ("GI", 3)
    with pytest.raises(ValueError, match="X01"):
        nmea_satellite("X01")


def test_epoch_talkers_gps_only_vs_multi():
    t = T_NOON
    gps = epoch_sentences(t, lat_deg=10.0, lon_deg=20.0, h_m=5.0, fix_quality=1,
                          sv_used=["G01", "G02", "G03", "G04"], pdop=2.0, hdop=1.0, vdop=1.7,
                          sv_in_view=["G01", "G02", "G03", "G04", "G09"], el_deg=[80, 40, 30, 20, -3],
                          az_deg=[0, 90, 180, 270, 10], cn0_dbhz=[50, 45, 42, 38, np.nan])
    kinds = [(parse(s).talker, parse(s).sentence_type) for s in gps]
    assert kinds == [("GP", "GGA"), ("GP", "RMC"), ("GP", "GSA"), ("GP", "GSV")]
    assert int(parse(gps[3]).num_sv_in_view) == 4  # G09 below the horizon is not in view
    multi = epoch_sentences(t, lat_deg=10.0, lon_deg=20.0, h_m=5.0, fix_quality=1,
                            sv_used=["G01", "G02", "R01", "E05", "C10"], pdop=2.0, hdop=1.0, vdop=1.7,
                            sv_in_view=["G01", "G02", "R01", "E05", "C10"], el_deg=[80, 40, 30, 20, 60],
                            az_deg=[0, 90, 180, 270, 10], cn0_dbhz=None, vel_enu_mps=[0.0, -2.0, 0.0])
    parsed = [parse(s) for s in multi]
    assert [(m.talker, m.sentence_type) for m in parsed] == [
        ("GN", "GGA"), ("GN", "RMC"), ("GN", "GSA"), ("GN", "GSA"), ("GN", "GSA"), ("GN", "GSA"),
        ("GP", "GSV"), ("GL", "GSV"), ("GA", "GSV"), ("GB", "GSV")]
    assert [m.data[-1] for m in parsed[2:6]] == ["1", "2", "3", "4"]  # system IDs G, R, E, C
    assert int(parsed[0].num_sats) == 5
    assert float(parsed[1].true_course) == pytest.approx(180.0)
    assert parsed[7].sv_prn_num_1 == "65" and parsed[7].snr_1 == ""
    for s in multi:
        assert len(s) + 2 <= MAX_SENTENCE_CHARS


def test_from_solver_solution():
    import pymap3d

    from gnss_sim_ros2.core.solver import solve_pvt
    lat, lon, h = -41.29, 174.78, 25.0
    az = np.array([10.0, 75.0, 140.0, 200.0, 260.0, 320.0])
    el = np.array([75.0, 40.0, 25.0, 55.0, 15.0, 35.0])
    rng = 2.2e7
    e, n, u = rng * np.cos(np.radians(el)) * np.sin(np.radians(az)), rng * np.cos(np.radians(el)) * np.cos(
        np.radians(az)), rng * np.sin(np.radians(el))
    sats = np.column_stack(pymap3d.enu2ecef(e, n, u, lat, lon, h))
    rx = np.array(pymap3d.geodetic2ecef(lat, lon, h))
    sv = ["G01", "G02", "G03", "G04", "G05", "G06"]
    sol = solve_pvt(sv, sats, np.linalg.norm(sats - rx, axis=1) + 77.0)
    out = sentences_from_solution(T_NOON, sol, cn0_dbhz=np.full(6, 44.0))
    m = parse(out[0])
    assert m.latitude == pytest.approx(lat, abs=LATLON_TOL_DEG)
    assert m.longitude == pytest.approx(lon, abs=LATLON_TOL_DEG)
    assert float(m.altitude) == pytest.approx(h, abs=5e-4)
    assert int(m.num_sats) == 6 and m.gps_qual == 1
    assert float(m.horizontal_dil) == pytest.approx(round(sol.hdop, 1))
