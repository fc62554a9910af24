"""Sp3Ephemeris: interpolation accuracy against withheld SP3 samples, derivatives,
edges, gaps and bad values, time systems, RINEX clock files.

Reference data: CODE MGEX final orbits 2022-001 (5 min, SP3-d), ``opec_dir``.
"""
from __future__ import annotations

import gzip

import numpy as np
import pytest

from gnss_sim_ros2.core.constants import A_E_GLO_M, GM_GAL_M3PS2, J2_GLO, OMEGA_E_GPS_RADPS
from gnss_sim_ros2.core.ephemeris.sp3 import Sp3Ephemeris, read_sp3
from gnss_sim_ros2.core.time import GnssTime

SP3_NAME = "COD0MGXFIN_20220010000_01D_05M_ORB.SP3"


@pytest.fixture(scope="module")
def sp3_path(opec_dir):
    return opec_dir / SP3_NAME


@pytest.fixture(scope="module")
def raw(sp3_path):
    return read_sp3(sp3_path)


@pytest.fixture(scope="module")
def eph(sp3_path):
    return Sp3Ephemeris.from_files([sp3_path], require_clock=False)


def _split_blocks(path):
    """(header lines, [epoch block lines]) of an SP3 file."""
    lines = path.read_text().splitlines(keepends=True)
    first = next(i for i, ln in enumerate(lines) if ln.startswith("* "))
    header, blocks = lines[:first], []
    for ln in lines[first:]:
        if ln.startswith("* "):
            blocks.append([ln])
        elif ln.startswith("EOF"):
            break
        else:
            blocks[-1].append(ln)
    return header, blocks


def _write(path, header, blocks):
    path.write_text("".join(header) + "".join(ln for b in blocks for ln in b) + "EOF\n")
    return path


def test_read_sp3_header_and_values(raw):
    ep, svs, pos, clk = raw
    assert len(ep) == 289  # 00:00 to 24:00 every 5 min, file header "289"
    assert len(svs) == 116  # header "+  116"
    assert ep[0] == GnssTime.from_iso("2022-01-01T00:00:00", "GPS")
    assert ep[-1] == GnssTime.from_iso("2022-01-02T00:00:00", "GPS")
    # first record of the file: PG01 13882.271938 -21710.006216 5357.125462 469.127768
    g01 = svs.index("G01")
    np.testing.assert_allclose(pos[0, g01], [13882271.938, -21710006.216, 5357125.462], rtol=0, atol=1e-6)
    assert clk[0, g01] == pytest.approx(469.127768e-6, abs=1e-15)
    # the last epoch carries 999999.999999 clocks for every satellite; C06 13 bad clocks during the day
    assert np.all(np.isnan(clk[-1]))
    assert np.isnan(clk[:, svs.index("C06")]).sum() == 13


@pytest.mark.parametrize("k", list(range(6, 283, 12)))
def test_withhold_one_sample_in_full_window(raw, k):
    """5 min spacing: one sample withheld in the middle of a full 11-sample window
    (the window then spans 55 min instead of 50) is reproduced within 2 cm."""
    ep, svs, pos, clk = raw
    keep = np.array([j for j in range(len(ep)) if j != k])
    e = Sp3Ephemeris(ep[keep], svs, pos[keep], clk[keep], require_clock=False, max_gap_factor=2.5)
    st = e.states(ep[k])
    assert len(st.sv) == len(svs)  # every satellite has a full window
    idx = [svs.index(s) for s in st.sv]
    err = np.linalg.norm(st.pos_ecef_m - pos[k, idx], axis=1)
    assert err.max() < 0.02, f"{st.sv[np.argmax(err)]}: {err.max():.4f} m"


def test_withhold_every_other_sample(raw):
    """10 min spacing (every other sample withheld): still within 2 cm (measured max 1.3 cm)."""
    ep, svs, pos, clk = raw
    e = Sp3Ephemeris(ep[::2], svs, pos[::2], clk[::2], require_clock=False)
    errs = []
    for k in range(11, len(ep) - 11, 2):  # away from the file edges
        st = e.states(ep[k])
        idx = [svs.index(s) for s in st.sv]
        errs.append(np.linalg.norm(st.pos_ecef_m - pos[k, idx], axis=1))
    err = np.concatenate(errs)
    assert err.max() < 0.02


def test_nodes_are_reproduced_exactly(eph, raw):
    ep, svs, pos, _ = raw
    for k in (0, 1, 144, 287, 288):
        st = eph.states(ep[k])
        idx = [svs.index(s) for s in st.sv]
        np.testing.assert_allclose(st.pos_ecef_m, pos[k, idx], rtol=0, atol=1e-6)


def test_velocity_against_five_point_difference(eph, raw):
    """Velocity of the interpolant vs the 5-point central difference of raw samples
    (truncation error h^4/30 |x^(5)| ~ 4 mm/s at h = 300 s)."""
    ep, svs, pos, _ = raw
    h = 300.0
    for k in (50, 150, 230):
        st = eph.states(ep[k])
        idx = [svs.index(s) for s in st.sv]
        fd = (pos[k - 2, idx] - 8 * pos[k - 1, idx] + 8 * pos[k + 1, idx] - pos[k + 2, idx]) / (12 * h)
        np.testing.assert_allclose(st.vel_ecef_mps, fd, rtol=0, atol=0.01)


def test_acceleration_matches_gravity_in_rotating_frame(eph):
    """ECEF acceleration of the interpolant = central gravity + J2 - centrifugal - Coriolis
    (Montenbruck & Gill, Satellite Orbits, 3.2 and 2.4); sun/moon/SRP (< 1e-5 m/s^2) are left out,
    the Coriolis term (0.5 m/s^2) checks the velocity as well."""
    t = GnssTime.from_iso("2022-01-01T10:02:30", "GPS")
    st = eph.states(t)
    r = st.pos_ecef_m
    v = st.vel_ecef_mps
    rn = np.linalg.norm(r, axis=1)[:, None]
    z = r[:, 2:3]
    a_grav = -GM_GAL_M3PS2 * r / rn**3
    k = 1.5 * J2_GLO * GM_GAL_M3PS2 * A_E_GLO_M**2 / rn**5
    a_j2 = -k * r * (1 - 5 * z**2 / rn**2)
    a_j2[:, 2] -= (2 * k * r[:, 2:3]).ravel()
    w = np.array([0.0, 0.0, OMEGA_E_GPS_RADPS])
    a_model = a_grav + a_j2 - np.cross(w, np.cross(w, r)) - 2 * np.cross(w, v)
    np.testing.assert_allclose(st.acc_ecef_mps2, a_model, rtol=0, atol=2e-5)


def test_edges_no_extrapolation(eph, raw):
    ep = raw[0]
    first, last = eph.time_span()
    assert first == ep[0] and last == ep[-1]
    assert len(eph.states(first).sv) == 116
    assert len(eph.states(last).sv) == 116
    assert len(eph.states(first - 1e-3).sv) == 0
    assert len(eph.states(last + 1e-3).sv) == 0
    assert len(eph.states(last + 3600).sv) == 0


def test_clock_required_by_default(sp3_path, raw):
    """With require_clock (default) a satellite without a clock on both sides of t is not served:
    the 24:00 epoch has no clocks, so the last 5 min are served only at 23:55 exactly."""
    ep, svs, _, clk = raw
    e = Sp3Ephemeris.from_files(sp3_path)
    assert len(e.states(ep[-1]).sv) == 0
    assert len(e.states(ep[-1] - 60).sv) == 0
    at_2355 = e.states(ep[-2])
    assert "G01" in at_2355.sv
    c06 = svs.index("C06")
    bad = np.flatnonzero(np.isnan(clk[:-1, c06]))
    assert "C06" not in e.states(ep[bad[0]]).sv
    # clocks: exact at nodes, linear in between (drift = slope of the two samples)
    g01 = svs.index("G01")
    st = e.states(ep[100] + 75.0, svs=["G01"])
    slope = (clk[101, g01] - clk[100, g01]) / 300.0
    assert st.clock_bias_s[0] == pytest.approx(clk[100, g01] + 75.0 * slope, abs=1e-16)
    assert st.clock_drift_sps[0] == pytest.approx(slope, rel=1e-12)
    assert st.source == "sp3"
    assert np.all(st.relativistic_s == 0) and np.all(st.tgd_s == 0)


def test_missing_satellite_and_bad_positions(tmp_path, sp3_path, raw, eph):
    """A satellite absent from the file, a line missing at one epoch (must not shift the others,
    as a reader indexing by line order would) and 0.000000 positions over 50 minutes."""
    ep, svs, pos, _ = raw
    header, blocks = _split_blocks(sp3_path)
    blocks = [list(b) for b in blocks]
    blocks[50] = [ln for ln in blocks[50] if not ln.startswith("PG07")]
    for k in range(100, 111):
        blocks[k] = [("PG05      0.000000      0.000000      0.000000 999999.999999\n"
                      if ln.startswith("PG05") else ln) for ln in blocks[k]]
    e = Sp3Ephemeris.from_files([_write(tmp_path / "mod.sp3", header, blocks)], require_clock=False)
    assert "E06" not in e.svs()
    assert len(e.states(ep[10], svs=["E06", "G99"]).sv) == 0
    st = e.states(ep[50])
    assert "G07" not in st.sv
    g08 = list(st.sv).index("G08")
    np.testing.assert_allclose(st.pos_ecef_m[g08], pos[50, svs.index("G08")], atol=1e-6)
    for t in (ep[99] + 1.0, ep[105], ep[110] + 299.0):
        assert "G05" not in e.states(t).sv
    # next to the gap the window shifts (still interpolation): agrees with the full file within 2 cm
    for t in (ep[98] + 150.0, ep[111] + 150.0):
        a = e.states(t, svs=["G05"])
        b = eph.states(t, svs=["G05"])
        assert len(a.sv) == 1
        assert np.linalg.norm(a.pos_ecef_m - b.pos_ecef_m) < 0.02


def test_two_files_merge_like_one(tmp_path, sp3_path, eph):
    header, blocks = _split_blocks(sp3_path)
    a = _write(tmp_path / "a.sp3", header, blocks[:150])
    b = _write(tmp_path / "b.sp3.gz", [], [])
    with gzip.open(b, "wt") as f:  # gzip accepted; the 150th epoch appears in both files
        f.write("".join(header) + "".join(ln for blk in blocks[149:] for ln in blk) + "EOF\n")
    e = Sp3Ephemeris.from_files([a, b], require_clock=False)
    for t in (GnssTime.from_iso("2022-01-01T12:21:40"), GnssTime.from_iso("2022-01-01T12:27:30")):
        s1, s2 = e.states(t), eph.states(t)
        assert list(s1.sv) == list(s2.sv)
        np.testing.assert_allclose(s1.pos_ecef_m, s2.pos_ecef_m, rtol=0, atol=1e-6)
    # start/end keep only what is needed
    t0 = GnssTime.from_iso("2022-01-01T06:00:00")
    e2 = Sp3Ephemeris.from_files([a, b], start=t0, end=t0 + 3600, require_clock=False)
    assert e2.time_span()[0] <= t0 - 5 * 300 and e2.time_span()[1] >= t0 + 3600 + 5 * 300
    assert e2.time_span()[1] - e2.time_span()[0] < 4 * 3600
    np.testing.assert_allclose(e2.states(t0 + 1234.5).pos_ecef_m, eph.states(t0 + 1234.5).pos_ecef_m, atol=1e-6)


@pytest.mark.parametrize("ts, offset_s", [("UTC", 18), ("BDT", 14), ("GAL", 0), ("TAI", -19)])
def test_time_system_from_header(tmp_path, sp3_path, ts, offset_s):
    """Epochs are read in the header's time system: 00:00:00 UTC on 2022-01-01 is 00:00:18 GPST
    (GPS-UTC = 18 s, IERS Bulletin C), BDT = GPST - 14 s, TAI = GPST + 19 s."""
    header, blocks = _split_blocks(sp3_path)
    header = [(ln[:9] + f"{ts:<3}" + ln[12:]) if ln.startswith("%c M") else ln for ln in header]
    e = Sp3Ephemeris.from_files([_write(tmp_path / "ts.sp3", header, blocks[:20])], require_clock=False)
    assert e.time_span()[0] - GnssTime.from_iso("2022-01-01T00:00:00", "GPS") == pytest.approx(offset_s, abs=1e-9)


def test_rinex_clock_file_is_used(tmp_path, sp3_path, raw):
    """RINEX clock 3.04 AS records at 30 s replace the SP3 clocks for the satellites they have."""
    ep, svs, _, clk = raw
    lines = [
        "     3.04           C                   G                   RINEX VERSION / TYPE\n",
        "GPS                                                         TIME SYSTEM ID\n",
        "                                                            END OF HEADER\n",
    ]
    vals = {}
    for j in range(0, 41):
        sec = j * 30
        v = 1.0e-4 + 1.0e-9 * j + (2.0e-10 if j % 2 else 0.0)  # zig-zag: linear only between samples
        vals[sec] = v
        hh, mm, ss = sec // 3600, (sec // 60) % 60, sec % 60
        lines.append(f"AS G01      2022 01 01 {hh:2d} {mm:2d} {ss:9.6f}  1   {v:19.12E}\n")
    lines.append("AS G02      2022 01 01  0  0  0.000000  2   9.999999999990E-01  0.000000000000E+00\n")
    p = tmp_path / "test.clk"
    p.write_text("".join(lines))
    e = Sp3Ephemeris.from_files([sp3_path], [p])
    t = ep[0] + 45.0
    st = e.states(t, svs=["G01", "G03"])
    assert list(st.sv) == ["G01", "G03"]
    assert st.clock_bias_s[0] == pytest.approx(0.5 * (vals[30] + vals[60]), abs=1e-18)
    assert st.clock_drift_sps[0] == pytest.approx((vals[60] - vals[30]) / 30.0, rel=1e-9)
    g03 = svs.index("G03")
    assert st.clock_bias_s[1] == pytest.approx(clk[0, g03] + 45.0 * (clk[1, g03] - clk[0, g03]) / 300, abs=1e-16)
    # beyond the clock file's last record (20 min) G01 has no clock: not served
    assert "G01" not in e.states(ep[0] + 1300.0).sv
    # G02's only record is a bad value (>= 999999 us)... a single record gives no clock either
    assert "G02" not in e.states(ep[0] + 10.0).sv


def test_states_at_matches_states(eph):
    t0 = GnssTime.from_iso("2022-01-01T03:00:00")
    svs = ["G01", "E11", "C23", "R07", "J02"]
    dts = np.array([-0.072, -0.081, -0.13, -0.069, -0.12])
    ts = GnssTime.stack([t0 + d for d in dts])
    st = eph.states_at(svs, ts)
    assert list(st.sv) == svs
    for k, sv in enumerate(svs):
        one = eph.states(t0 + dts[k], svs=[sv])
        np.testing.assert_allclose(st.pos_ecef_m[k], one.pos_ecef_m[0], rtol=0, atol=1e-7)
        np.testing.assert_allclose(st.vel_ecef_mps[k], one.vel_ecef_mps[0], rtol=0, atol=1e-9)
    assert np.allclose(st.age_s, dts)


def test_systems_filter(eph):
    t = GnssTime.from_iso("2022-01-01T03:00:00")
    st = eph.states(t, systems="EJ")
    assert set(s[0] for s in st.sv) == {"E", "J"}
    assert len(st.sv) == 24 + 3


def test_unix_compress_and_empty_queries(tmp_path, sp3_path, eph):
    import ncompress  # georinex's dependency for .Z files
    z = tmp_path / "orb.sp3.Z"
    z.write_bytes(ncompress.compress(sp3_path.read_bytes()))
    e = Sp3Ephemeris.from_files(z, require_clock=False)
    t = GnssTime.from_iso("2022-01-01T07:07:07")
    np.testing.assert_array_equal(e.states(t).pos_ecef_m, eph.states(t).pos_ecef_m)
    assert len(eph.states(t, svs=[])) == 0
    assert len(eph.states(t, systems="I")) == 0  # no NavIC in the file
    assert len(eph.states_at([], t)) == 0


def test_bad_file_names_the_file(tmp_path):
    p = tmp_path / "bad.sp3"
    p.write_text("hello\n")
    with pytest.raises(ValueError, match="bad.sp3"):
        Sp3Ephemeris.from_files([p])
    p.write_text("#dP2022  1  1  0  0  0.00000000\n*  2022  1  1  0  0  0.00000000\nPG01  1.0 x\n")
    with pytest.raises(ValueError, match="bad.sp3 line 3"):
        Sp3Ephemeris.from_files([p])
