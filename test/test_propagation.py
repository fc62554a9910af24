"""Light time / Earth rotation against an inertial-frame reference; ionosphere and troposphere models."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from gnss_sim_ros2.core import propagation as prop
from gnss_sim_ros2.core.frames import az_el_from_ecef, geodetic_to_ecef
from gnss_sim_ros2.core.time import GnssTime

C = 299792458.0
WE = 7.2921151467e-5
GM = 3.986005e14
RX = np.array([3149785.9652, 598260.8822, 5495348.4927])  # OPEC marker (shared data README)


def _rz(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


class CircularOrbits:
    """Satellites on circular Keplerian orbits, exact in the inertial frame; ECEF = R3(we t) ECI."""

    def __init__(self, radius_m, incl_deg, raan_deg, u0_deg):
        self.r = np.asarray(radius_m, float)
        self.n = np.sqrt(GM / self.r**3)
        self.i = np.radians(incl_deg)
        self.o = np.radians(raan_deg)
        self.u0 = np.radians(u0_deg)

    def eci(self, t):
        t = np.asarray(t, float)
        u = self.u0 + self.n * t
        co, so, ci, si = np.cos(self.o), np.sin(self.o), np.cos(self.i), np.sin(self.i)
        xo, yo = self.r * np.cos(u), self.r * np.sin(u)
        vxo, vyo = -self.r * self.n * np.sin(u), self.r * self.n * np.cos(u)
        pos = np.stack([co * xo - so * ci * yo, so * xo + co * ci * yo, si * yo], -1)
        vel = np.stack([co * vxo - so * ci * vyo, so * vxo + co * ci * vyo, si * vyo], -1)
        return pos, vel, -(self.n**2)[..., None] * pos

    def ecef(self, t):
        """ECEF position, velocity, acceleration (rotating-frame derivatives) at float times t (N,)."""
        t = np.asarray(t, float)
        p, v, a = self.eci(t)
        w = np.array([0.0, 0.0, WE])
        out_p, out_v, out_a = [], [], []
        for j in range(p.shape[0]):
            r = _rz(WE * t[j])
            pe = r @ p[j]
            ve = r @ v[j] - np.cross(w, pe)
            ae = r @ a[j] - 2.0 * np.cross(w, ve) - np.cross(w, np.cross(w, pe))
            out_p.append(pe)
            out_v.append(ve)
            out_a.append(ae)
        return np.array(out_p), np.array(out_v), np.array(out_a)


def _visible_orbits():
    # four MEO satellites; u0 chosen so they are above the OPEC horizon near t = 100 s
    return CircularOrbits(np.full(4, 26560e3), [55, 55, 55, 64.8], [0, 40, 80, 20], [60, 80, 45, 70])


def _inertial_reference(orbits, j, t_rx, rx_ecef_at):
    """tau with c tau = |s_I(t_rx - tau) - r_I(t_rx)|, solved in the inertial frame (independent path)."""
    r_i = _rz(-WE * t_rx) @ rx_ecef_at(t_rx)

    def f(tau):
        s = orbits.eci(np.full(len(orbits.r), t_rx - tau))[0][j]
        return C * tau - np.linalg.norm(s - r_i)

    return brentq(f, 0.05, 0.2, xtol=1e-18, rtol=1e-15, maxiter=200)


def test_elevations_of_test_geometry():
    orb = _visible_orbits()
    p, _, _ = orb.ecef(np.full(4, 100.0))
    _, el, _ = az_el_from_ecef(RX, p)
    assert np.all(el > 5.0), el


@pytest.mark.parametrize("moving", [False, True])
def test_light_time_matches_inertial_solution(moving):
    orb = _visible_orbits()
    t_rx = 100.0
    v_rx = np.array([30.0, -20.0, 10.0]) if moving else np.zeros(3)

    def rx_at(t):
        return RX + v_rx * (t - t_rx)

    def states_at(t_tx):
        p, v, _ = orb.ecef(t_tx)
        return p, v

    sol = prop.transmit_time_solution(RX, t_rx, states_at, iterations=2, rx_vel_ecef_mps=v_rx, n_sats=4)
    for j in range(4):
        tau_ref = _inertial_reference(orb, j, t_rx, rx_at)
        # tolerance 1e-4 m: float64 resolution of 2e7 m ranges is ~4e-9 m, brentq converges to ~1e-17 s
        assert sol.range_m[j] == pytest.approx(C * tau_ref, abs=1e-4)
        assert sol.tau_s[j] == pytest.approx(tau_ref, abs=1e-12)
        # range rate = central difference of the inertial reference range (h = 0.05 s, truncation < 1e-6 m/s)
        h = 0.05
        rr_ref = C * (_inertial_reference(orb, j, t_rx + h, rx_at) - _inertial_reference(orb, j, t_rx - h, rx_at)) / (
            2 * h)
        assert sol.range_rate_mps[j] == pytest.approx(rr_ref, abs=1e-5)
    np.testing.assert_allclose(sol.t_tx, t_rx - sol.tau_s)
    np.testing.assert_allclose(np.linalg.norm(sol.los_unit_ecef, axis=1), 1.0)


def test_rotation_agrees_with_rtklib_first_order_sagnac():
    orb = _visible_orbits()
    t_rx = 100.0

    def states_at(t):
        p, v, _ = orb.ecef(t)
        return p, v

    sol = prop.transmit_time_solution(RX, t_rx, states_at, n_sats=4)
    p_tx, _, _ = orb.ecef(t_rx - sol.tau_s)  # unrotated, ECEF of the transmit instant
    rtklib = np.linalg.norm(p_tx - RX, axis=1) + prop.sagnac_correction_m(p_tx, RX)
    # RTKLIB geodist(): |rs - rr| + OMGE (rs_x rr_y - rs_y rr_x) / c; second-order terms ~1e-4 m
    np.testing.assert_allclose(sol.range_m, rtklib, atol=1e-3)
    # the Sagnac term itself is tens of metres at most (published: up to ~40 m)
    assert np.all(np.abs(prop.sagnac_correction_m(p_tx, RX)) < 45.0)


def test_second_order_expansion_matches_reevaluation_submm():
    orb = _visible_orbits()
    t_rx = 100.0
    p, v, a = orb.ecef(np.full(4, t_rx))

    def states_at(t):
        pp, vv, _ = orb.ecef(t)
        return pp, vv

    full = prop.transmit_time_solution(RX, t_rx, states_at, n_sats=4)
    cheap = prop.transmit_time_from_states(RX, p, v, a, t_rx=t_rx)
    diff = np.abs(cheap.range_m - full.range_m)
    print(f"second-order expansion vs re-evaluation: max range difference {diff.max():.2e} m, "
          f"range rate {np.abs(cheap.range_rate_mps - full.range_rate_mps).max():.2e} m/s")
    assert diff.max() < 1e-3  # sub-millimetre, as the jerk term (|j| tau^3 / 6 ~ 1e-8 m) predicts
    np.testing.assert_allclose(cheap.range_rate_mps, full.range_rate_mps, atol=1e-4)


def test_gnsstime_receive_time():
    orb = _visible_orbits()
    t_ref = GnssTime.from_iso("2022-01-01T00:00:00")
    t_rx = t_ref + 100.0

    def states_at(t_tx):
        p, v, _ = orb.ecef(t_tx - t_ref)
        return p, v

    sol = prop.transmit_time_solution(RX, t_rx, states_at, n_sats=4)
    sol_f = prop.transmit_time_solution(RX, 100.0, lambda t: orb.ecef(t)[:2], n_sats=4)
    np.testing.assert_allclose(sol.range_m, sol_f.range_m, atol=1e-6)
    np.testing.assert_allclose(sol.t_tx - t_ref, 100.0 - sol.tau_s, atol=1e-12)
    with pytest.raises(ValueError, match="n_sats"):
        prop.transmit_time_solution(RX, t_rx, states_at)
    with pytest.raises(ValueError, match="iterations"):
        prop.transmit_time_solution(RX, t_rx, states_at, iterations=0, n_sats=4)


# ---------------------------------------------------------------------------- ionosphere
# GPS broadcast coefficients of the OPEC navigation file header are not needed: any set works
# for the structural properties; this set is typical (RTKLIB's default, 2004/1/1).
ALPHA = np.array([0.1118e-07, -0.7451e-08, -0.5961e-07, 0.1192e-06])
BETA = np.array([0.1167e06, -0.2294e06, -0.1311e06, 0.1049e07])
F_ZENITH = 1.0 + 16.0 * (0.53 - 0.5) ** 3  # IS-GPS-200N obliquity factor at 90 deg elevation


def test_klobuchar_night_constant_5ns():
    # local time 02:00 at lon 0 -> outside the cosine window: F * 5 ns (IS-GPS-200N 20.3.3.5.2.5)
    d = prop.klobuchar_l1_delay_s(2 * 3600.0, 45.0, 0.0, 0.0, 90.0, ALPHA, BETA)
    assert d == pytest.approx(F_ZENITH * 5e-9, rel=1e-12)
    assert C * d == pytest.approx(1.4997, abs=1e-3)  # 5 ns = 1.499 m


def test_klobuchar_peak_at_14h_equals_night_plus_amplitude():
    a0 = 20e-9
    alpha = np.array([a0, 0.0, 0.0, 0.0])
    # at zenith the IPP is the user (psi = 0.0137/0.61 - 0.022 = 4.6e-4 semicircles north for az 0:
    # the longitude, hence the local time, is unchanged); lon 30 deg -> local = t + 7200 s
    t = 14 * 3600.0 - 2 * 3600.0
    d = prop.klobuchar_l1_delay_s(t, 10.0, 30.0, 0.0, 90.0, alpha, BETA)
    assert d == pytest.approx(F_ZENITH * (5e-9 + a0), rel=1e-9)
    # symmetric around 14:00 local time
    for dt in (1800.0, 7200.0, 14000.0):
        before = prop.klobuchar_l1_delay_s(t - dt, 10.0, 30.0, 0.0, 90.0, ALPHA, BETA)
        after = prop.klobuchar_l1_delay_s(t + dt, 10.0, 30.0, 0.0, 90.0, ALPHA, BETA)
        assert before == pytest.approx(after, rel=1e-12)
    # negative amplitude is clamped to zero -> night value all day
    d_neg = prop.klobuchar_l1_delay_s(t, 10.0, 30.0, 0.0, 90.0, [-1e-8, 0, 0, 0], BETA)
    assert d_neg == pytest.approx(F_ZENITH * 5e-9, rel=1e-12)


def test_klobuchar_vectorised_and_obliquity():
    el = np.array([5.0, 15.0, 30.0, 60.0, 90.0])
    d = prop.klobuchar_l1_delay_s(2 * 3600.0, 45.0, 0.0, 0.0, el, ALPHA, BETA)
    assert d.shape == el.shape
    assert np.all(np.diff(d) < 0)  # night: only F changes; larger at low elevation
    # obliquity 1 + 16 (0.53 - E)^3: about 3 near the horizon (Klobuchar 1987)
    assert d[0] / d[-1] == pytest.approx((1 + 16 * (0.53 - 5 / 180) ** 3) / F_ZENITH, rel=1e-12)
    assert 2.9 < d[0] / d[-1] < 3.1
    with pytest.raises(ValueError, match="alpha"):
        prop.klobuchar_l1_delay_s(0.0, 45.0, 0.0, 0.0, 90.0, ALPHA[:3], BETA)


def test_iono_frequency_scaling_and_phase_advance():
    d_l1 = 10e-9
    f_l1, f_l2, f_l5 = 1575.42e6, 1227.60e6, 1176.45e6
    assert prop.iono_code_delay_m(d_l1, f_l1) == pytest.approx(C * d_l1)
    # first-order ionosphere: delay ~ 40.3 TEC / f^2 -> ratio (f1/f2)^2 = (154/120)^2 = 1.6469
    assert prop.iono_code_delay_m(d_l1, f_l2) / prop.iono_code_delay_m(d_l1, f_l1) == pytest.approx(
        (154 / 120) ** 2, rel=1e-12)
    assert prop.iono_code_delay_m(d_l1, f_l5) / (C * d_l1) == pytest.approx((154 / 115) ** 2, rel=1e-12)
    f = np.array([f_l1, f_l2, f_l5])
    np.testing.assert_array_equal(prop.iono_phase_advance_m(d_l1, f), -prop.iono_code_delay_m(d_l1, f))
    # 1 TECU at L1 = 40.3e16 / f^2 = 0.1624 m (published); 10 ns = 2.998 m = 18.5 TECU
    assert 40.3e16 / f_l1**2 == pytest.approx(0.1624, abs=1e-4)


# -------------------------------------------------------------------------- troposphere
def test_saastamoinen_zenith_sea_level():
    zhd, zwd = prop.saastamoinen_zenith_m(45.0, 0.0)
    # Saastamoinen/Davis: ZHD = 2.2768 mm/hPa * 1013.25 hPa at 45 deg latitude (cos 2 lat = 0)
    assert zhd == pytest.approx(2.2768e-3 * 1013.25, abs=1e-4)
    # published: total zenith delay about 2.3-2.5 m at sea level, wet part 0.05-0.3 m
    assert 2.3 < zhd + zwd < 2.5
    assert 0.05 < zwd < 0.3


def test_saastamoinen_height_standard_atmosphere():
    # ICAO standard atmosphere: 898.76 hPa at 1000 m, 795.01 hPa at 2000 m (independent table)
    for h, p_isa in ((1000.0, 898.76), (2000.0, 795.01)):
        zhd, _ = prop.saastamoinen_zenith_m(45.0, h)
        assert zhd == pytest.approx(2.2768e-3 * p_isa / (1 - 0.00028 * h / 1e3), abs=3e-3)
    with pytest.raises(ValueError, match="humidity"):
        prop.saastamoinen_zenith_m(45.0, 0.0, humidity=1.5)


def test_niell_mapping_properties_and_mops_comparison():
    el = np.array([5.0, 7.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 90.0])
    mh, mw = prop.niell_mapping(el, 45.0, 0.0, 100.0)
    assert mh[-1] == pytest.approx(1.0, abs=1e-12) and mw[-1] == pytest.approx(1.0, abs=1e-12)
    # RTCA DO-229 (WAAS MOPS) mapping 1.001 / sqrt(0.002001 + sin^2 el): independent, within 3 %
    mops = 1.001 / np.sqrt(0.002001 + np.sin(np.radians(el)) ** 2)
    np.testing.assert_allclose(mh, mops, rtol=0.03)
    np.testing.assert_allclose(mw[el >= 7], mops[el >= 7], rtol=0.03)
    # the wet layer is lower than the dry one: its mapping is larger near the horizon (Niell 1996)
    assert np.all(mw[:3] > mh[:3])
    # Earth curvature: both below the flat-Earth cosecant, and close to it at high elevation
    assert np.all(mh[:-1] < 1 / np.sin(np.radians(el[:-1])))
    np.testing.assert_allclose(mh[el >= 30], 1 / np.sin(np.radians(el[el >= 30])), rtol=0.005)
    # hemispheres are half a year apart
    a = prop.niell_mapping(10.0, 50.0, 300.0, 30.0)
    b = prop.niell_mapping(10.0, -50.0, 300.0, 30.0 + 365.25 / 2)
    np.testing.assert_allclose(a, b, rtol=1e-12)


def test_slant_tropo_delay_magnitudes():
    d = prop.tropo_slant_delay_m(np.array([90.0, 30.0, 10.0, 5.0]), 45.0, 0.0, 180.0)
    assert 2.3 < d[0] < 2.5
    assert d[1] == pytest.approx(2 * d[0], rel=0.01)      # ~1/sin(30 deg)
    assert 12.0 < d[2] < 15.0 and 22.0 < d[3] < 27.0      # published ~13-14 m at 10 deg, ~25 m at 5 deg


def test_day_of_year():
    assert prop.day_of_year(GnssTime.from_iso("2022-01-01T12:00:00")) == pytest.approx(1.5)
    lat, lon, h = 45.0, 7.0, 300.0
    assert np.all(np.isfinite(geodetic_to_ecef(lat, lon, h)))


def test_slant_tropo_delay_per_epoch_equals_per_row():
    """Latitude, height and day of year given once per epoch (epoch_of_row) give every row the same delay,
    to the bit, as the per-row values (the receiver's block and one-epoch paths)."""
    rng = np.random.default_rng(4)
    k, n = 7, 60
    lat = rng.uniform(-80.0, 80.0, k)
    h = rng.uniform(-50.0, 3000.0, k)
    doy = rng.uniform(1.0, 366.0, k)
    e = np.sort(rng.integers(0, k, n))
    el = rng.uniform(-2.0, 90.0, n)
    a = prop.tropo_slant_delay_m(np.maximum(el, 1.0), lat, h, doy, epoch_of_row=e)
    b = prop.tropo_slant_delay_m(np.maximum(el, 1.0), lat[e], h[e], doy[e])
    np.testing.assert_array_equal(a, b)
    assert np.all(np.isfinite(a)) and np.all(a > 1.0)      # >= the zenith delay at 3 km
