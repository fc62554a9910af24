"""Broadcast ephemeris: reading (RINEX 2/3/4), Kepler and GLONASS orbits, record selection.

Expectations come from physics (two-body energy and angular momentum, an
independent numerical integration, finite differences), from a scalar
re-implementation of the ICD equations written here from IS-GPS-200N table
20-IV / BDS-SIS-ICD-B1I 5.2.4.12 (loop code, week-of-tow arithmetic as the ICD
does it, independent of the vectorised absolute-time code under test), and from
the IERS leap second table.  The small RINEX files are written by the tests.
"""
from __future__ import annotations

import gzip
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from gnss_sim_ros2.core import constants as K
from gnss_sim_ros2.core.ephemeris.broadcast import BroadcastEphemeris
from gnss_sim_ros2.core.ephemeris.glonass import glonass_acceleration
from gnss_sim_ros2.core.ephemeris.kepler import kepler_states
from gnss_sim_ros2.core.rinex.nav import parse_nav_text, read_nav_files, records_as_dicts, toe_time
from gnss_sim_ros2.core.time import GnssTime

# ------------------------------------------------------------------------------------------------
# small RINEX writers (text, as the format documents describe it)
# ------------------------------------------------------------------------------------------------


def _f(v: float) -> str:
    return f"{v:19.12E}"


def _hdr3(extra: str = "", version: str = "3.04") -> str:
    lines = [f"{version:>9}{'':11}{'N: GNSS NAV DATA':<20}{'M: MIXED':<20}RINEX VERSION / TYPE",
             f"{'    18':<60}LEAP SECONDS"]
    if extra:
        lines.append(extra)
    lines.append(f"{'':60}END OF HEADER")
    return "\n".join(lines) + "\n"


def _epoch_str(dt):
    y, mo, d, h, mi, s = dt
    return f"{y:04d} {mo:02d} {d:02d} {h:02d} {mi:02d} {s:02d}"


def _rec3(sv: str, epoch, values: list[float], blank: tuple[int, ...] = ()) -> str:
    """RINEX 3 record: epoch line with 3 values, then lines of 4 (``blank``: fields left empty)."""
    cells = ["" .rjust(19) if k in blank else _f(v) for k, v in enumerate(values)]
    out = [f"{sv} {_epoch_str(epoch)}" + "".join(cells[:3])]
    for k in range(3, len(cells), 4):
        out.append("    " + "".join(cells[k:k + 4]))
    return "\n".join(out) + "\n"


def _rec2(prn: int, epoch, values: list[float]) -> str:
    y, mo, d, h, mi, s = epoch
    out = [f"{prn:2d} {y % 100:02d} {mo:2d} {d:2d} {h:2d} {mi:2d}{float(s):5.1f}" + "".join(_f(v) for v in values[:3])]
    for k in range(3, len(values), 4):
        out.append("   " + "".join(_f(v) for v in values[k:k + 4]))
    return "\n".join(out) + "\n"


def gps_values(p: dict) -> list[float]:
    """The 29 values of a GPS/QZSS record in RINEX 3.04 table A6 order."""
    return [p["af0"], p["af1"], p["af2"], p["iode"], p["crs"], p["dn"], p["m0"], p["cuc"], p["e"], p["cus"],
            p["sqrta"], p["toe"], p["cic"], p["omega0"], p["cis"], p["i0"], p["crc"], p["omega"], p["omegadot"],
            p["idot"], 1.0, p["week"], 0.0, 2.0, p["health"], p["tgd"], p["iodc"], p["toe"] - 18.0, p["fit"]]


def gal_values(p: dict, src: int) -> list[float]:
    return [p["af0"], p["af1"], p["af2"], p["iode"], p["crs"], p["dn"], p["m0"], p["cuc"], p["e"], p["cus"],
            p["sqrta"], p["toe"], p["cic"], p["omega0"], p["cis"], p["i0"], p["crc"], p["omega"], p["omegadot"],
            p["idot"], float(src), p["week"], 0.0, 3.12, p["health"], p["bgda"], p["bgdb"], p["toe"] + 30.0]


def bds_values(p: dict) -> list[float]:
    return [p["af0"], p["af1"], p["af2"], 1.0, p["crs"], p["dn"], p["m0"], p["cuc"], p["e"], p["cus"],
            p["sqrta"], p["toe"], p["cic"], p["omega0"], p["cis"], p["i0"], p["crc"], p["omega"], p["omegadot"],
            p["idot"], 0.0, p["week"], 0.0, 2.0, p["health"], p["tgd1"], 0.0, p["toe"], 0.0]


def glo_values(p: dict) -> list[float]:
    x, y, z = (np.asarray(p["pos_m"]) / 1e3).tolist()
    vx, vy, vz = (np.asarray(p["vel_mps"]) / 1e3).tolist()
    ax, ay, az = (np.asarray(p["acc_mps2"]) / 1e3).tolist()
    return [-p["tau_n"], p["gamma_n"], 0.0, x, vx, ax, p["health"], y, vy, ay, p["k"], z, vz, az, 0.0]


# a real GPS record (G30, OPEC 2022-001, 02:00 GPST; values as broadcast)
G30 = dict(af0=-5.035293288529e-04, af1=-2.728484105319e-12, af2=0.0, iode=94.0, crs=-8.65625,
           dn=5.173786937564e-09, m0=-2.315157581206e-01, cuc=-4.135072231293e-07, e=5.383261595853e-03,
           cus=8.381903171539e-06, sqrta=5.153595811844e+03, toe=525600.0, cic=4.284083843231e-08,
           omega0=2.113095554454, cis=1.154839992523e-07, i0=9.359002012800e-01, crc=204.5625,
           omega=-2.751309879534, omegadot=-8.298917111780e-09, idot=-5.953819429049e-10, week=2190.0,
           health=0.0, tgd=3.725290298462e-09, iodc=94.0, fit=0.0)
G30_EPOCH = (2022, 1, 1, 2, 0, 0)


# ------------------------------------------------------------------------------------------------
# independent scalar ICD implementation (IS-GPS-200N table 20-IV; BDS-SIS-ICD-B1I 3.0 5.2.4.12)
# ------------------------------------------------------------------------------------------------
def icd_position(p: dict, t_tow: float, gm: float, we: float, geo: bool = False) -> np.ndarray:
    a = p["sqrta"] ** 2
    tk = t_tow - p["toe"]
    if tk > 302400.0:          # IS-GPS-200N 20.3.3.4.3: account for beginning or end of week crossovers
        tk -= 604800.0
    elif tk < -302400.0:
        tk += 604800.0
    n = math.sqrt(gm / a**3) + p["dn"]
    m = p["m0"] + n * tk
    ecc = m
    for _ in range(50):
        ecc = m + p["e"] * math.sin(ecc)     # fixed-point iteration (not Newton as the code under test)
    nu = math.atan2(math.sqrt(1 - p["e"] ** 2) * math.sin(ecc), math.cos(ecc) - p["e"])
    phi = nu + p["omega"]
    u = phi + p["cus"] * math.sin(2 * phi) + p["cuc"] * math.cos(2 * phi)
    r = a * (1 - p["e"] * math.cos(ecc)) + p["crs"] * math.sin(2 * phi) + p["crc"] * math.cos(2 * phi)
    i = p["i0"] + p["idot"] * tk + p["cis"] * math.sin(2 * phi) + p["cic"] * math.cos(2 * phi)
    xp, yp = r * math.cos(u), r * math.sin(u)
    if not geo:
        om = p["omega0"] + (p["omegadot"] - we) * tk - we * p["toe"]
    else:
        om = p["omega0"] + p["omegadot"] * tk - we * p["toe"]
    xyz = np.array([xp * math.cos(om) - yp * math.cos(i) * math.sin(om),
                    xp * math.sin(om) + yp * math.cos(i) * math.cos(om),
                    yp * math.sin(i)])
    if geo:
        f = math.radians(-5.0)
        rx = np.array([[1, 0, 0], [0, math.cos(f), math.sin(f)], [0, -math.sin(f), math.cos(f)]])
        z = we * tk
        rz = np.array([[math.cos(z), math.sin(z), 0], [-math.sin(z), math.cos(z), 0], [0, 0, 1]])
        xyz = rz @ rx @ xyz
    return xyz


def _eph_from_text(tmp_path, text, name="nav.rnx", **kw):
    p = tmp_path / name
    p.write_text(text)
    return BroadcastEphemeris.from_files([p], **kw)


# ------------------------------------------------------------------------------------------------
# Kepler: GPS against the scalar ICD code; velocity and acceleration against finite differences
# ------------------------------------------------------------------------------------------------
def test_gps_position_matches_scalar_icd(tmp_path):
    eph = _eph_from_text(tmp_path, _hdr3() + _rec3("G30", G30_EPOCH, gps_values(G30)))
    toe = GnssTime.from_iso("2022-01-01T02:00:00")
    for dt in (-7200.0, -1234.5, 0.0, 3600.0, 7200.0):
        st = eph.states(toe + dt)
        assert list(st.sv) == ["G30"]
        ref = icd_position(G30, G30["toe"] + dt, K.GM_GPS_M3PS2, K.OMEGA_E_GPS_RADPS)
        np.testing.assert_allclose(st.pos_ecef_m[0], ref, atol=1e-4)  # 0.1 mm
        # clock polynomial and relativistic term (IS-GPS-200N 20.3.3.3.3.1)
        assert st.clock_bias_s[0] == pytest.approx(G30["af0"] + G30["af1"] * dt, abs=1e-15)
        assert abs(st.relativistic_s[0]) <= 4.443e-10 * G30["e"] * G30["sqrta"] + 1e-15
        assert st.tgd_s[0] == pytest.approx(G30["tgd"], rel=1e-12)
        assert st.age_s[0] == pytest.approx(dt)


def test_velocity_and_acceleration_against_finite_differences(tmp_path):
    eph = _eph_from_text(tmp_path, _hdr3() + _rec3("G30", G30_EPOCH, gps_values(G30)))
    t = GnssTime.from_iso("2022-01-01T02:37:11")
    h = 0.5
    s0, sp, sm = eph.states(t), eph.states(t + h), eph.states(t - h)
    v_fd = (sp.pos_ecef_m - sm.pos_ecef_m) / (2 * h)
    # central difference truncation: h^2/6 |jerk| ~ 1e-5 m/s; rounding ~1e-8 m / 1 s
    np.testing.assert_allclose(s0.vel_ecef_mps, v_fd, atol=2e-5)
    a_fd = (sp.vel_ecef_mps - sm.vel_ecef_mps) / (2 * h)
    # the analytic acceleration is two-body + J2 only: luni-solar (< 7e-6 m/s^2) and the fitted
    # harmonic terms are missing; stated tolerance 2e-5 m/s^2 (|a| is 0.57 m/s^2)
    np.testing.assert_allclose(s0.acc_ecef_mps2, a_fd, atol=2e-5)
    # clock drift = derivative of the clock polynomial
    assert s0.clock_drift_sps[0] == pytest.approx((sp.clock_bias_s[0] - sm.clock_bias_s[0]) / (2 * h), abs=1e-16)


def _pure_kepler(sqrta, e, i0, omega, m0, omega0, toe_tow, week):
    return dict(af0=0.0, af1=0.0, af2=0.0, iode=1.0, crs=0.0, dn=0.0, m0=m0, cuc=0.0, e=e, cus=0.0, sqrta=sqrta,
                toe=toe_tow, cic=0.0, omega0=omega0, cis=0.0, i0=i0, crc=0.0, omega=omega, omegadot=0.0,
                idot=0.0, week=week, health=0.0, tgd=0.0, iodc=1.0, fit=0.0, bgda=0.0, bgdb=0.0)


@pytest.mark.parametrize("system,sv,e,sqrta,i0,gm,we", [
    # Galileo E14/E18 (launched into an eccentric orbit, e ~ 0.16)
    ("E", "E14", 0.1614, 5289.6, 0.872, K.GM_GAL_M3PS2, K.OMEGA_E_GAL_RADPS),
    # QZSS IGSO/QZO, e ~ 0.075
    ("J", "J01", 0.0750, 6493.3, 0.716, K.GM_QZS_M3PS2, K.OMEGA_E_QZS_RADPS),
])
def test_eccentric_orbits_conserve_energy_and_match_two_body_integration(tmp_path, system, sv, e, sqrta, i0, gm, we):
    """Pure Kepler records (no harmonics, no node/inclination rates): in the inertial frame the
    motion must be the two-body problem: energy -GM/2a and |h| = sqrt(GM a (1-e^2)) conserved, and
    equal to a numerical integration of r'' = -GM r / r^3 (DOP853, rtol 1e-12)."""
    p = _pure_kepler(sqrta, e, i0, 1.1, -2.9, 0.4, 0.0, 2190.0)
    epoch = (2021, 12, 26, 0, 0, 0)  # week 2190, tow 0
    vals = gal_values(p, 517) if system == "E" else gps_values(p)
    eph = _eph_from_text(tmp_path, _hdr3() + _rec3(sv, epoch, vals), windows_s={system: 6 * 3600.0})
    toe = GnssTime.from_iso("2021-12-26T00:00:00")
    dts = np.arange(-3 * 3600.0, 3 * 3600.0 + 1, 600.0)
    a = sqrta**2
    r_in, v_in = [], []
    for dt in dts:
        st = eph.states(toe + dt)
        r, v = st.pos_ecef_m[0], st.vel_ecef_mps[0]
        # ECEF -> inertial frame aligned with ECEF at toe (rotation by we*dt about Z)
        ang = we * dt
        rz = np.array([[math.cos(ang), -math.sin(ang), 0], [math.sin(ang), math.cos(ang), 0], [0, 0, 1]])
        vi = rz @ (v + np.cross([0, 0, we], r))
        ri = rz @ r
        r_in.append(ri)
        v_in.append(vi)
        energy = 0.5 * vi @ vi - gm / np.linalg.norm(ri)
        assert energy == pytest.approx(-gm / (2 * a), rel=1e-9)
        assert np.linalg.norm(np.cross(ri, vi)) == pytest.approx(math.sqrt(gm * a * (1 - e * e)), rel=1e-9)
    k0 = int(np.flatnonzero(dts == 0)[0])
    y0 = np.concatenate([r_in[k0], v_in[k0]])

    def f(_t, y):
        r = y[:3]
        return np.concatenate([y[3:], -gm * r / np.linalg.norm(r) ** 3])

    for sign in (1, -1):
        sel = dts * sign >= 0
        sol = solve_ivp(f, (0, sign * 3 * 3600.0), y0, method="DOP853", rtol=1e-12, atol=1e-6,
                        t_eval=dts[sel][:: sign])
        ref = sol.y[:3].T
        got = np.array(r_in)[sel][:: sign]
        np.testing.assert_allclose(got, ref, atol=1e-3)  # 1 mm over 3 h


def test_bds_geo_and_igso_match_scalar_icd(tmp_path):
    # C05-like GEO and C06-like IGSO (values from OPEC 2022-001, radians)
    geo = dict(af0=3.5e-4, af1=1.1e-11, af2=0.0, crs=-429.90625, dn=-3.107629709120e-09 * math.pi,
               m0=9.572916454636e-01 * math.pi, cuc=2.604443579912e-05, e=6.461676675826e-04,
               cus=1.388974487782e-05, sqrta=6493.483388901, toe=518400.0, cic=2.328306436539e-08,
               omega0=-8.736521936953e-01 * math.pi, cis=3.213062882423e-07, i0=1.889726286754e-02 * math.pi,
               crc=792.703125, omega=2.759860465303e-01 * math.pi, omegadot=3.468358045211e-09 * math.pi,
               idot=1.0e-10, week=834.0, health=0.0, tgd1=-5e-10)
    igso = dict(geo, sqrta=6492.844846725, e=2.717333845794e-03, i0=0.9446, omega0=1.4497, omega=3.0351,
                m0=-2.5326, omegadot=-2.128e-09, crs=-16.3, crc=158.4)
    epoch = (2022, 1, 1, 0, 0, 0)  # BDT; toe 518400 = Saturday 00:00 BDT, BDT week 834
    text = _hdr3() + _rec3("C05", epoch, bds_values(geo)) + _rec3("C06", epoch, bds_values(igso))
    eph = _eph_from_text(tmp_path, text)
    # toc/toe are BDT: 2022-01-01T00:00:00 BDT = 00:00:14 GPST
    toe_gps = GnssTime.from_iso("2022-01-01T00:00:14")
    assert eph.records("C")["toe_sec"][0] == toe_gps.sec
    for dt in (-3000.0, 0.0, 2500.0):
        st = eph.states(toe_gps + dt)
        k5, k6 = st.index_of("C05"), st.index_of("C06")
        ref5 = icd_position(geo, 518400.0 + dt, K.GM_BDS_M3PS2, K.OMEGA_E_BDS_RADPS, geo=True)
        ref6 = icd_position(igso, 518400.0 + dt, K.GM_BDS_M3PS2, K.OMEGA_E_BDS_RADPS)
        np.testing.assert_allclose(st.pos_ecef_m[k5], ref5, atol=1e-4)
        np.testing.assert_allclose(st.pos_ecef_m[k6], ref6, atol=1e-4)
        # a GEO barely moves in ECEF: at most v_orbit sin(i) (plus drift), vs 3.07 km/s inertial
        assert np.linalg.norm(st.vel_ecef_mps[k5]) < 3075.0 * math.sin(geo["i0"]) + 10.0
        assert st.tgd_s[k5] == pytest.approx(-5e-10)
    # GEO velocity against a central difference of positions
    t = toe_gps + 100.0
    v_fd = (eph.states(t + 0.5).pos_ecef_m - eph.states(t - 0.5).pos_ecef_m)
    np.testing.assert_allclose(eph.states(t).vel_ecef_mps, v_fd, atol=2e-5)


def test_bds_angles_in_semicircles_are_detected(tmp_path):
    igso = dict(af0=0.0, af1=0.0, af2=0.0, crs=0.0, dn=1e-9, m0=0.3, cuc=0.0, e=0.002, cus=0.0,
                sqrta=6492.8, toe=518400.0, cic=0.0, omega0=0.5, cis=0.0, i0=0.3007, crc=0.0, omega=0.9,
                omegadot=-6.7e-10, idot=-4e-11, week=834.0, health=0.0, tgd1=0.0)
    rad = {k: (v * math.pi if k in ("dn", "m0", "omega0", "i0", "omega", "omegadot", "idot") else v)
           for k, v in igso.items()}
    epoch = (2022, 1, 1, 0, 0, 0)
    e_sc = _eph_from_text(tmp_path, _hdr3() + _rec3("C06", epoch, bds_values(igso)), "sc.rnx")
    e_rad = _eph_from_text(tmp_path, _hdr3() + _rec3("C06", epoch, bds_values(rad)), "rad.rnx")
    assert e_sc.nav.notes and "semicircles" in e_sc.nav.notes[0]
    assert not e_rad.nav.notes
    t = GnssTime.from_iso("2022-01-01T00:20:00")
    np.testing.assert_allclose(e_sc.states(t).pos_ecef_m, e_rad.states(t).pos_ecef_m, atol=1e-6)


# ------------------------------------------------------------------------------------------------
# reading: RINEX 2 / 3 / 4, compression, blank fields, duplicates, Galileo messages
# ------------------------------------------------------------------------------------------------
def test_rinex2_3_4_and_gzip_give_the_same_states(tmp_path):
    v = gps_values(G30)
    r3 = _hdr3() + _rec3("G30", G30_EPOCH, v)
    r2 = (f"{'2.11':>9}{'':11}{'N: GPS NAV DATA':<40}RINEX VERSION / TYPE\n"
          f"{'    0.1211D-07 -0.7451D-08 -0.5960D-07  0.1192D-06':<60}ION ALPHA\n"
          f"{'    0.1167D+06 -0.2458D+06 -0.6554D+05  0.1114D+07':<60}ION BETA\n"
          f"{'':60}END OF HEADER\n") + _rec2(30, G30_EPOCH, v)
    r4 = (f"{'4.00':>9}{'':11}{'N: GNSS NAV DATA':<20}{'M: MIXED':<20}RINEX VERSION / TYPE\n"
          f"{'':60}END OF HEADER\n"
          "> EPH G30 LNAV\n" + _rec3("G30", G30_EPOCH, v)
          + "> EPH G30 CNAV\n" + _rec3("G30", G30_EPOCH, v + [0.0] * 6)
          + "> ION G30 LNAV\n"
          + "    2022 01 01 02 00 00" + "".join(_f(x) for x in (1.2107e-08, -7.4506e-09, -5.9605e-08)) + "\n"
          + "    " + "".join(_f(x) for x in (1.1921e-07, 116740.0, -245760.0, -65536.0)) + "\n"
          + "    " + "".join(_f(x) for x in (1114100.0, 1.0)) + "\n")
    (tmp_path / "a.rnx").write_text(r3)
    (tmp_path / "b.22n").write_text(r2)
    (tmp_path / "c.rnx").write_text(r4)
    with gzip.open(tmp_path / "d.rnx.gz", "wt") as f:
        f.write(r3)
    t = GnssTime.from_iso("2022-01-01T03:10:00")
    out = {}
    for name in ("a.rnx", "b.22n", "c.rnx", "d.rnx.gz"):
        eph = BroadcastEphemeris.from_files([tmp_path / name])
        out[name] = eph.states(t)
        assert list(out[name].sv) == ["G30"]
    for name in ("b.22n", "c.rnx", "d.rnx.gz"):
        np.testing.assert_array_equal(out[name].pos_ecef_m, out["a.rnx"].pos_ecef_m)
    nav4 = read_nav_files([tmp_path / "c.rnx"])
    assert sum(nav4.skipped.values()) == 1  # the CNAV record
    assert nav4.iono["GPSA"] == pytest.approx([1.2107e-08, -7.4506e-09, -5.9605e-08, 1.1921e-07])
    assert nav4.iono["GPSB"] == pytest.approx([116740.0, -245760.0, -65536.0, 1114100.0])
    nav2 = read_nav_files([tmp_path / "b.22n"])
    assert nav2.iono["GPSB"][3] == pytest.approx(1114000.0)  # 0.1114D+07 as written


def test_blank_spare_fields_do_not_lose_records(tmp_path):
    """A BeiDou record whose spare fields are blank (as station files write them): georinex alone
    turns the whole record into NaN."""
    p = dict(af0=1e-4, af1=0.0, af2=0.0, crs=0.0, dn=1e-9, m0=0.3, cuc=0.0, e=0.002, cus=0.0, sqrta=5282.6,
             toe=518400.0, cic=0.0, omega0=0.4, cis=0.0, i0=0.96, crc=0.0, omega=0.9, omegadot=-6.7e-9,
             idot=-4e-11, week=834.0, health=0.0, tgd1=1e-9)
    text = _hdr3() + _rec3("C20", (2022, 1, 1, 0, 0, 0), bds_values(p), blank=(20, 22, 28))
    nav = parse_nav_text(text)
    rec = nav.records("C")
    assert len(rec) == 1 and rec["sqrt_a"][0] == pytest.approx(5282.6) and rec["week"][0] == 834
    assert rec["tgd_s"][0] == pytest.approx(1e-9)


def test_galileo_inav_fnav_choice(tmp_path):
    p = _pure_kepler(5440.6, 0.0003, 0.975, 1.0, 2.0, 3.0, 518400.0, 2190.0)
    inav, fnav = dict(p, af0=1.0e-4, bgda=2e-9, bgdb=3e-9), dict(p, af0=1.1e-4, bgda=2e-9, bgdb=3e-9)
    epoch = (2022, 1, 1, 0, 0, 0)
    text = _hdr3() + _rec3("E01", epoch, gal_values(inav, 517)) + _rec3("E01", epoch, gal_values(fnav, 258))
    t = GnssTime.from_iso("2022-01-01T00:30:00")
    e_i = _eph_from_text(tmp_path, text)
    e_f = _eph_from_text(tmp_path, text, galileo_nav="fnav")
    si, sf = e_i.states(t), e_f.states(t)
    assert si.clock_bias_s[0] == pytest.approx(1.0e-4) and si.tgd_s[0] == pytest.approx(3e-9)  # E1/E5b
    assert sf.clock_bias_s[0] == pytest.approx(1.1e-4) and sf.tgd_s[0] == pytest.approx(2e-9)  # E1/E5a
    assert set(e_i.nav.tables["E"].rec["nav"]) == {"INAV", "FNAV"}


# ------------------------------------------------------------------------------------------------
# time edges: week rollover, fit interval, leap second, GLONASS day boundary
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("week_field", [2047.0, 1023.0])
def test_week_rollover_2019(tmp_path, week_field):
    """A record with toe in GPS week 2047 (2019-04-06 23:59:44) used at 2019-04-07 00:30:00, in
    week 2048 (the second 10-bit rollover).  The week field may be continuous or mod 1024."""
    p = dict(G30, toe=604784.0, week=week_field, fit=0.0)
    eph = _eph_from_text(tmp_path, _hdr3() + _rec3("G30", (2019, 4, 6, 23, 59, 44), gps_values(p)))
    t = GnssTime.from_iso("2019-04-07T00:30:00")
    assert t.week_tow() == (2048, 1800.0)
    st = eph.states(t)
    assert list(st.sv) == ["G30"]
    assert st.age_s[0] == pytest.approx(1816.0)
    ref = icd_position(p, 1800.0, K.GM_GPS_M3PS2, K.OMEGA_E_GPS_RADPS)  # ICD tk crossover rule
    np.testing.assert_allclose(st.pos_ecef_m[0], ref, atol=1e-4)
    assert st.clock_bias_s[0] == pytest.approx(p["af0"] + p["af1"] * 1816.0, abs=1e-15)


def test_fit_interval_edges(tmp_path):
    p4 = dict(G30)                           # fit flag 0: 4 h -> toe +- 2 h
    p14 = dict(G30, iodc=250.0, fit=1.0)     # flag 1, IODC 248-255: 14 h (IS-GPS-200N table 20-XII)
    text = _hdr3() + _rec3("G30", G30_EPOCH, gps_values(p4)) + _rec3("G07", G30_EPOCH, gps_values(p14))
    eph = _eph_from_text(tmp_path, text)
    toe = GnssTime.from_iso("2022-01-01T02:00:00")
    assert "G30" in eph.states(toe + 7200.0).sv and "G30" in eph.states(toe - 7200.0).sv
    assert "G30" not in eph.states(toe + 7200.001).sv and "G30" not in eph.states(toe - 7200.001).sv
    assert "G07" in eph.states(toe + 7 * 3600.0).sv and "G07" not in eph.states(toe + 7 * 3600.0 + 1).sv
    # the satpos command follows the same windows (end inclusive grid)
    from gnss_sim_ros2.cli import main

    out = tmp_path / "edge.csv"
    assert main(["satpos", "--nav", str(tmp_path / "nav.rnx"), "--start", "2022-01-01T03:59:58",
                 "--end", "2022-01-01T04:00:02", "--step", "1", "--systems", "G", "--out", str(out)]) == 0
    rows = [ln.split(",") for ln in out.read_text().splitlines()[1:]]
    g30_times = [r[0] for r in rows if r[1] == "G30"]
    assert g30_times == ["2022-01-01T03:59:58", "2022-01-01T03:59:59", "2022-01-01T04:00:00"]
    assert sum(r[1] == "G07" for r in rows) == 5


def _glonass_record(pos, vel, acc=(0.0, 0.0, 0.0), tau_n=1e-5, gamma_n=1e-12, k=-3):
    return dict(pos_m=pos, vel_mps=vel, acc_mps2=acc, tau_n=tau_n, gamma_n=gamma_n, health=0.0, k=float(k))


def _integrate_icd(y0, acc_ls, dt):
    """Independent integration of the GLONASS ICD 5.1 A.3.1.2 equations (DOP853)."""
    def f(_t, y):
        return np.concatenate([y[3:], glonass_acceleration(y[:3], y[3:], np.asarray(acc_ls))])

    sol = solve_ivp(f, (0.0, dt), y0, method="DOP853", rtol=1e-12, atol=1e-6)
    return sol.y[:, -1]


R_POS = [-9576941.40625, 7429831.054688, 22469889.16016]
R_VEL = [-2822.994232178, -1203.627586365, -811.1238479614]
R_ACC = [9.313225746155e-07, 0.0, -3.725290298462e-06]


def test_glonass_leap_second_day(tmp_path):
    """Records at 2016-12-31 23:45:00 and 2017-01-01 00:15:00 UTC: 30 min + 1 leap second apart
    (IERS Bulletin C 52: 2016-12-31 23:59:60 inserted)."""
    y0 = np.concatenate([R_POS, R_VEL])
    # the second record is the first one integrated over the real elapsed time, 1801 s
    y1 = _integrate_icd(y0, R_ACC, 1801.0)
    r1 = _glonass_record(R_POS, R_VEL, R_ACC)
    r2 = _glonass_record(y1[:3], y1[3:], R_ACC)
    text = (_hdr3() + _rec3("R07", (2016, 12, 31, 23, 45, 0), glo_values(r1))
            + _rec3("R07", (2017, 1, 1, 0, 15, 0), glo_values(r2)))
    eph = _eph_from_text(tmp_path, text)
    tb1 = GnssTime.from_iso("2016-12-31T23:45:00", "UTC")
    tb2 = GnssTime.from_iso("2017-01-01T00:15:00", "UTC")
    assert tb2 - tb1 == 1801.0
    assert eph.records("R")["toe_sec"][0] == tb1.sec
    assert tb1 == GnssTime.from_iso("2016-12-31T23:45:17")  # GPS - UTC = 17 s before the leap
    assert tb2 == GnssTime.from_iso("2017-01-01T00:15:18")  # and 18 s after it
    # selection: +-15 min windows (+1 s); 900 s after tb1 the first record, 901 s after (= 900 s before
    # tb2) the second; at 900.5 s both are equally near: the later one (no hole at the leap second)
    s_a, s_b = eph.states(tb1 + 900.0), eph.states(tb1 + 901.0)
    assert s_a.age_s[0] == pytest.approx(900.0) and s_a.iode[0] == (23 * 60 + 45 + 180) % 1440 // 15
    assert s_b.age_s[0] == pytest.approx(-900.0)
    # both records describe the same trajectory: states agree at the switch (RK4 + interpolation vs DOP853)
    assert eph.states(tb1 + 900.5).age_s[0] == pytest.approx(-900.5)
    for dt in (450.0, 900.0, 900.5):
        t = tb1 + dt
        ref = _integrate_icd(y0, R_ACC, dt)
        st = eph.states_at(["R07"], t)
        tol = 1e-2 if dt <= 900 else 2e-2
        np.testing.assert_allclose(st.pos_ecef_m[0], ref[:3], atol=tol)   # cm
        np.testing.assert_allclose(st.vel_ecef_mps[0], ref[3:], atol=1e-5)
    # clock: -tau_n + gamma_n (t - tb) in elapsed seconds
    assert s_a.clock_bias_s[0] == pytest.approx(-1e-5 + 1e-12 * 900.0, abs=1e-18)


def test_glonass_day_boundary_and_acceleration(tmp_path):
    """GLONASS days start at 21:00 UTC (GLONASST = UTC + 3 h): records at 20:45 and 21:15 UTC
    belong to two GLONASS days (tb index 95 and 1); the orbit is continuous across."""
    y0 = np.concatenate([R_POS, R_VEL])
    y1 = _integrate_icd(y0, R_ACC, 1800.0)
    text = (_hdr3() + _rec3("R07", (2022, 1, 1, 20, 45, 0), glo_values(_glonass_record(R_POS, R_VEL, R_ACC)))
            + _rec3("R07", (2022, 1, 1, 21, 15, 0), glo_values(_glonass_record(y1[:3], y1[3:], R_ACC))))
    eph = _eph_from_text(tmp_path, text)
    assert list(eph.records("R")["iode"]) == [95, 1]
    tb1 = GnssTime.from_iso("2022-01-01T20:45:00", "UTC")
    before, after = eph.states(tb1 + 899.999), eph.states(tb1 + 900.001)
    assert before.iode[0] == 95 and after.iode[0] == 1
    jump = np.linalg.norm(after.pos_ecef_m[0] - before.pos_ecef_m[0] - before.vel_ecef_mps[0] * 0.002)
    assert jump < 0.02
    # acceleration = ICD right-hand side (central difference of velocity agrees)
    t = tb1 + 333.3
    a_fd = (eph.states(t + 0.5).vel_ecef_mps - eph.states(t - 0.5).vel_ecef_mps)
    np.testing.assert_allclose(eph.states(t).acc_ecef_mps2, a_fd, atol=1e-6)
    assert eph.states(t).glo_channel[0] == -3


def test_glonass_rinex305_fourth_orbit_line(tmp_path):
    r = _glonass_record(R_POS, R_VEL, R_ACC)
    body = _rec3("R07", (2022, 1, 1, 0, 15, 0), glo_values(r))
    extra = "    " + "".join(_f(x) for x in (0.0, 1e-9, 2.0, 0.0)) + "\n"
    eph = _eph_from_text(tmp_path, _hdr3(version="3.05") + body + extra + body.replace("00 15 00", "00 45 00"))
    assert len(eph.records("R")) == 2
    np.testing.assert_allclose(eph.records("R")["pos_m"][0], R_POS, atol=1e-3)


# ------------------------------------------------------------------------------------------------
# diagnostics, missing satellites, provider contract, export
# ------------------------------------------------------------------------------------------------
def test_diagnostics_gap_stale_unhealthy_missing(tmp_path):
    e0 = (2022, 1, 1, 0, 0, 0)
    e8 = (2022, 1, 1, 8, 0, 0)
    g01a = dict(G30, toe=518400.0)
    g01b = dict(G30, toe=518400.0 + 8 * 3600)
    g03 = dict(G30, toe=518400.0, health=1.0)
    text = (_hdr3() + _rec3("G01", e0, gps_values(g01a)) + _rec3("G01", e8, gps_values(g01b))
            + _rec3("G03", e0, gps_values(g03)))
    eph = _eph_from_text(tmp_path, text)
    t0 = GnssTime.from_iso("2022-01-01T00:00:00")
    d = eph.diagnostics(t0, svs=["G01", "G02", "G03"])
    assert d.ok == ["G01"] and d.unhealthy == ["G03"] and d.missing == ["G02"]
    assert d.age_s["G01"] == 0.0
    assert list(eph.states(t0, svs=["G01", "G02", "G03"]).sv) == ["G01"]
    assert eph.diagnostics(t0 + 4 * 3600.0).status("G01") == "gap"
    assert eph.diagnostics(t0 + 11 * 3600.0).status("G01") == "stale"
    assert len(eph.states(t0 + 4 * 3600.0)) == 0
    assert "G02" in str(d)
    lo, hi = eph.time_span()
    assert lo == t0 - 7200.0 and hi == t0 + 10 * 3600.0


def test_states_at_and_contract(tmp_path):
    text = _hdr3() + _rec3("G30", G30_EPOCH, gps_values(G30)) + _rec3(
        "R07", (2022, 1, 1, 2, 15, 0), glo_values(_glonass_record(R_POS, R_VEL, R_ACC)))
    eph = _eph_from_text(tmp_path, text)
    t = GnssTime.from_iso("2022-01-01T02:10:00")
    st = eph.states(t)
    assert list(st.sv) == ["G30", "R07"] and st.source == "broadcast"
    for name in ("pos_ecef_m", "vel_ecef_mps", "acc_ecef_mps2"):
        assert getattr(st, name).shape == (2, 3)
    assert st.relativistic_s[1] == 0.0 and st.tgd_s[1] == 0.0 and st.glo_channel[0] == 0
    tt = GnssTime(np.array([t.sec, t.sec + 1]), np.array([0.25, 0.5]))
    sa = eph.states_at(["R07", "G30"], tt)
    assert list(sa.sv) == ["R07", "G30"]
    np.testing.assert_allclose(sa.pos_ecef_m[1], eph.states(tt[1], svs=["G30"]).pos_ecef_m[0], atol=1e-9)
    np.testing.assert_allclose(sa.pos_ecef_m[0], eph.states(tt[0], svs=["R07"]).pos_ecef_m[0], atol=1e-9)
    assert len(eph.states_at(["G99", "G30"], t)) == 1
    assert eph.svs() == ["G30", "R07"] and eph.svs("R") == ["R07"]
    assert eph.leap_seconds == 18
    with pytest.raises(ValueError, match="systems"):
        eph.states(t, systems="GX")


def test_bad_input_errors_name_the_file(tmp_path):
    with pytest.raises(ValueError, match="nope.rnx"):
        BroadcastEphemeris.from_files([tmp_path / "nope.rnx"])
    bad = tmp_path / "bad.rnx"
    bad.write_text(_hdr3() + "G30 2022 01 01 02 00 00" + _f(1.0) + "\n")
    with pytest.raises(ValueError, match=r"bad.rnx, line 4"):
        BroadcastEphemeris.from_files([bad])
    v5 = tmp_path / "v5.rnx"
    v5.write_text(_hdr3(version="5.00"))
    with pytest.raises(ValueError, match="version"):
        BroadcastEphemeris.from_files([v5])


def test_records_roundtrip_through_rinex3_writer(tmp_path):
    from gnss_sim_ros2.core.rinex import nav_write as writer
    text = (_hdr3(f"{'GPSA   1.2107E-08 -7.4506E-09 -5.9605E-08  1.1921E-07':<60}IONOSPHERIC CORR")
            + _rec3("G30", G30_EPOCH, gps_values(G30))
            + _rec3("R07", (2022, 1, 1, 2, 15, 0), glo_values(_glonass_record(R_POS, R_VEL, R_ACC))))
    nav = parse_nav_text(text)
    from gnss_sim_ros2.core.rinex.nav import header_dict

    out = writer.write_rinex3_nav(tmp_path / "rt.rnx", records_as_dicts(nav), header_dict(nav))
    back = read_nav_files([out])
    for s in "GR":
        a, b = nav.records(s), back.records(s)
        for name in a.dtype.names:
            if a.dtype[name].kind == "f":
                np.testing.assert_allclose(a[name], b[name], rtol=1e-11, err_msg=name)
            else:
                np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    assert back.iono["GPSA"] == pytest.approx(nav.iono["GPSA"])
    assert toe_time(back.records("G")) == toe_time(nav.records("G"))


def test_kepler_states_function_matches_provider(tmp_path):
    eph = _eph_from_text(tmp_path, _hdr3() + _rec3("G30", G30_EPOCH, gps_values(G30)))
    t = GnssTime.from_iso("2022-01-01T01:00:00")
    o = kepler_states(eph.records("G"), t)
    np.testing.assert_array_equal(o["pos_ecef_m"], eph.states(t).pos_ecef_m)


def test_rinex2_glonass_equals_rinex3(tmp_path):
    r = _glonass_record(R_POS, R_VEL, R_ACC)
    epoch = (2022, 1, 1, 0, 15, 0)
    r3 = _hdr3() + _rec3("R07", epoch, glo_values(r))
    r2 = (f"{'2.11':>9}{'':11}{'G: GLONASS NAV DATA':<40}RINEX VERSION / TYPE\n"
          f"{'':60}END OF HEADER\n") + _rec2(7, epoch, glo_values(r))
    t = GnssTime.from_iso("2022-01-01T00:20:18")  # 00:20:00 UTC
    s3 = _eph_from_text(tmp_path, r3, "a.rnx").states(t)
    s2 = _eph_from_text(tmp_path, r2, "b.22g").states(t)
    assert list(s2.sv) == ["R07"] and s2.age_s[0] == pytest.approx(300.0)
    np.testing.assert_array_equal(s2.pos_ecef_m, s3.pos_ecef_m)
    assert s2.glo_channel[0] == -3 and s2.clock_bias_s[0] == pytest.approx(-1e-5 + 300e-12)
