"""Single point solver on simulated exact measurements.

Geometry is built independently of the solver with pymap3d (ENU at the true
receiver -> ECEF); DOPs are checked against the closed-form geometry of a
zenith + 3 horizon satellites constellation and against (H^T H)^-1 built in
ENU directly from azimuth/elevation.
"""
from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest

from gnss_sim_ros2.core.solver import (
    SolverConfig,
    pseudorange_sigma_m,
    range_rate_from_doppler,
    solve_pvt,
    solve_pvt_many,
)

C = 299792458.0

AZ = np.array([10.0, 75.0, 140.0, 200.0, 260.0, 320.0, 35.0, 110.0, 180.0, 250.0, 300.0])
EL = np.array([75.0, 40.0, 25.0, 55.0, 15.0, 35.0, 20.0, 65.0, 30.0, 45.0, 12.0])
SV2 = ["G02", "G05", "G07", "G13", "G20", "G29", "E01", "E04", "E11", "E19", "E33"]


def make_sats(lat, lon, h, az_deg, el_deg, range_m=22.0e6):
    """Satellite ECEF positions at the given az/el and slant ranges from the true receiver."""
    az, el = np.radians(az_deg), np.radians(el_deg)
    rng = np.broadcast_to(range_m, np.shape(az_deg))
    e = rng * np.cos(el) * np.sin(az)
    n = rng * np.cos(el) * np.cos(az)
    u = rng * np.sin(el)
    x, y, z = pymap3d.enu2ecef(e, n, u, lat, lon, h)
    return np.column_stack([x, y, z]), np.array(pymap3d.geodetic2ecef(lat, lon, h))


def ranges(sats, rx, sv, clock_m, isb_m=0.0):
    geo = np.linalg.norm(sats - rx, axis=1)
    return geo + clock_m + np.array([isb_m if s[0] == "E" else 0.0 for s in sv])


@pytest.mark.parametrize("lat, lon, h, mask", [
    (59.9, 10.75, 60.0, 10.0),            # Oslo
    (-33.9, -70.6, 520.0, 10.0),          # southern/western hemispheres
    (89.9999, 45.0, 0.0, 10.0),           # next to the North pole
    (-89.95, -120.0, 2800.0, 10.0),       # South pole plateau
    (0.5, 180.0, 10.0, 10.0),             # date line
    (-10.0, -179.99999, 0.0, 10.0),       # date line, west side
    (40.0, -100.0, 12000.0, 10.0),        # aircraft
    (20.0, 30.0, 550e3, -90.0),           # low Earth orbit, far from the surface
])
def test_recovers_position_two_systems_from_earth_centre(lat, lon, h, mask):
    sats, rx = make_sats(lat, lon, h, AZ, EL, range_m=np.linspace(20.5e6, 25.5e6, AZ.size))
    clock_m = 1.234e-3 * C  # 370 km: a free-running receiver clock
    isb_m = 37.5
    pr = ranges(sats, rx, SV2, clock_m, isb_m)
    sol = solve_pvt(SV2, sats, pr, config=SolverConfig(elevation_mask_deg=mask))
    assert sol.status == "fix", sol.reason
    np.testing.assert_allclose(sol.pos_ecef_m, rx, atol=1e-3, rtol=0)
    assert sol.clock_bias_m["G"] == pytest.approx(clock_m, abs=1e-3)
    assert sol.clock_bias_m["E"] == pytest.approx(clock_m + isb_m, abs=1e-3)
    assert sol.clock_bias_s["G"] == pytest.approx(1.234e-3, abs=1e-11)
    assert sol.ref_system == "G" and sol.clock_systems == ["G", "E"]
    assert sol.n_used == len(SV2) and sol.excluded == []
    np.testing.assert_allclose(sol.residuals_m, 0.0, atol=1e-3)
    lat_s, lon_s, h_s = pymap3d.ecef2geodetic(*rx)
    assert sol.h_m == pytest.approx(h_s, abs=1e-3)
    assert sol.lat_deg == pytest.approx(lat_s, abs=1e-9)
    assert abs((sol.lon_deg - lon_s + 180.0) % 360.0 - 180.0) < 1e-7
    if h < 1e5:  # elevations at the solution are those of the construction
        np.testing.assert_allclose(sol.el_deg, EL, atol=1e-6)


def test_prior_and_corrections():
    lat, lon, h = 48.1, 11.6, 520.0
    sats, rx = make_sats(lat, lon, h, AZ, EL)
    rng = np.random.default_rng(3)
    dts = rng.uniform(-5e-4, 5e-4, AZ.size)
    iono = rng.uniform(1.0, 8.0, AZ.size)
    tropo = 2.3 / np.sin(np.radians(EL))
    # P = rho + c dt_rx - c dt_sat + I + T (IS-GPS-200N 20.3.3.3.3)
    pr = ranges(sats, rx, SV2, 5000.0, -12.0) - C * dts + iono + tropo
    sol = solve_pvt(SV2, sats, pr, sat_clock_bias_s=dts, iono_delay_m=iono, tropo_delay_m=tropo,
                    prior_ecef_m=rx + 3000.0)
    assert sol.status == "fix", sol.reason
    np.testing.assert_allclose(sol.pos_ecef_m, rx, atol=1e-3, rtol=0)
    assert sol.clock_bias_m["E"] - sol.clock_bias_m["G"] == pytest.approx(-12.0, abs=1e-3)
    assert sol.n_iterations <= 4  # from 5 km away Gauss-Newton converges in a few steps


def test_dops_closed_form_zenith_plus_three_on_horizon():
    # One satellite at the zenith, three on the horizon 120 deg apart:
    # H^T H (ENU + clock) = [[3/2,0,0,0],[0,3/2,0,0],[0,0,1,-1],[0,0,-1,4]] ->
    # HDOP^2 = 2/3+2/3, VDOP^2 = 4/3, TDOP^2 = 1/3, PDOP^2 = 8/3, GDOP^2 = 3.
    sats, rx = make_sats(45.0, 7.0, 300.0, np.array([0.0, 0.0, 120.0, 240.0]), np.array([90.0, 0.0, 0.0, 0.0]))
    sv = ["G01", "G02", "G03", "G04"]
    sol = solve_pvt(sv, sats, ranges(sats, rx, sv, 100.0), config=SolverConfig(elevation_mask_deg=-1.0))
    assert sol.status == "fix", sol.reason
    assert sol.hdop == pytest.approx(math.sqrt(4 / 3), rel=1e-6)
    assert sol.vdop == pytest.approx(math.sqrt(4 / 3), rel=1e-6)
    assert sol.tdop == pytest.approx(math.sqrt(1 / 3), rel=1e-6)
    assert sol.pdop == pytest.approx(math.sqrt(8 / 3), rel=1e-6)
    assert sol.gdop == pytest.approx(math.sqrt(3.0), rel=1e-6)
    assert sol.chi2_ok is None and "no redundancy" in sol.reason


def test_dops_and_covariance_match_explicit_formula():
    lat, lon, h = -23.5, 133.9, 600.0
    sats, rx = make_sats(lat, lon, h, AZ, EL)
    sol = solve_pvt(SV2, sats, ranges(sats, rx, SV2, 0.0, 5.0),
                    config=SolverConfig(weighting="equal", sigma_a_m=2.0, sigma_b_m=0.0))
    assert sol.status == "fix", sol.reason
    az, el = np.radians(AZ), np.radians(EL)
    # design matrix in ENU: minus the line-of-sight unit vector, one clock column per system
    hm = np.column_stack([-np.cos(el) * np.sin(az), -np.cos(el) * np.cos(az), -np.sin(el),
                          [s[0] == "G" for s in SV2], [s[0] == "E" for s in SV2]]).astype(float)
    q = np.linalg.inv(hm.T @ hm)
    assert sol.hdop == pytest.approx(math.sqrt(q[0, 0] + q[1, 1]), rel=1e-6)
    assert sol.vdop == pytest.approx(math.sqrt(q[2, 2]), rel=1e-6)
    assert sol.pdop == pytest.approx(math.sqrt(q[0, 0] + q[1, 1] + q[2, 2]), rel=1e-6)
    assert sol.tdop == pytest.approx(math.sqrt(q[3, 3]), rel=1e-6)
    assert sol.gdop == pytest.approx(math.sqrt(q[0, 0] + q[1, 1] + q[2, 2] + q[3, 3]), rel=1e-6)
    # equal weights, sigma 2 m: covariance = 4 m^2 (H^T H)^-1
    np.testing.assert_allclose(sol.cov_enu_m2, 4.0 * q[:3, :3], rtol=1e-6, atol=1e-9)
    rot = np.array(pymap3d.enu2uvw(*np.eye(3), lat, lon))  # columns: E, N, U in ECEF
    np.testing.assert_allclose(sol.cov_ecef_m2, rot @ (4.0 * q[:3, :3]) @ rot.T, rtol=1e-6, atol=1e-9)


def test_outlier_detected_and_excluded():
    lat, lon, h = 35.7, 139.7, 40.0
    sv = [s for s in SV2 if s[0] == "G"] + ["G30", "G31", "G32"]
    az = np.concatenate([AZ[:6], [95.0, 160.0, 340.0]])
    el = np.concatenate([EL[:6], [50.0, 70.0, 28.0]])
    sats, rx = make_sats(lat, lon, h, az, el)
    pr = ranges(sats, rx, sv, 1000.0)
    pr[3] += 60.0  # G13: 60 m multipath / fault
    sol = solve_pvt(sv, sats, pr)
    assert sol.status == "fix", sol.reason
    assert sol.excluded == ["G13"] and not sol.used[3] and sol.n_used == 8
    assert "G13" in sol.reason and sol.chi2_ok
    np.testing.assert_allclose(sol.pos_ecef_m, rx, atol=1e-3, rtol=0)
    # without the check the fault goes into the position
    raw = solve_pvt(sv, sats, pr, config=SolverConfig(check_residuals=False))
    assert np.linalg.norm(raw.pos_ecef_m - rx) > 5.0

    # with noise drawn with the sigmas of the weighting model (RTKLIB-like a = b = 0.3 m)
    rng = np.random.default_rng(11)
    sig = np.sqrt(0.3**2 + 0.3**2 / np.sin(np.radians(el)) ** 2)
    noisy = pr + rng.normal(0.0, sig)
    sol = solve_pvt(sv, sats, noisy)
    assert sol.status == "fix" and sol.excluded == ["G13"], sol.reason
    assert np.linalg.norm(sol.pos_ecef_m - rx) < 5.0  # a few sigma x PDOP
    clean = noisy.copy()
    clean[3] -= 60.0
    sol = solve_pvt(sv, sats, clean)
    assert sol.status == "fix" and sol.excluded == [] and sol.chi2_ok  # no false alarm on this draw


def test_outlier_with_one_redundant_satellite_is_no_fix():
    sv = ["G01", "G02", "G03", "G04", "G05"]
    sats, rx = make_sats(10.0, 20.0, 0.0, AZ[:5], EL[:5])
    pr = ranges(sats, rx, sv, 0.0)
    pr[1] += 80.0
    sol = solve_pvt(sv, sats, pr, config=SolverConfig(residual_failure="no_fix"))
    assert sol.status == "no_fix"
    assert "chi-square" in sol.reason and "identify" in sol.reason


def test_outlier_that_cannot_be_named_keeps_a_flagged_fix_with_a_wider_covariance():
    """Default residual_failure="fix": a fix wherever four satellites are usable (issue 16), flagged, with the
    covariance scaled by chi2 / dof."""
    sv = ["G01", "G02", "G03", "G04", "G05"]
    sats, rx = make_sats(10.0, 20.0, 0.0, AZ[:5], EL[:5])
    pr = ranges(sats, rx, sv, 0.0)
    clean = solve_pvt(sv, sats, pr)
    pr[1] += 80.0
    sol = solve_pvt(sv, sats, pr)
    assert sol.status == "fix" and sol.chi2_ok is False
    assert "chi-square" in sol.reason and "solution kept" in sol.reason
    factor = sol.chi2 / 1.0                                       # 5 satellites, 4 unknowns: 1 dof
    assert factor > 1
    # (the elevation weights are taken at a position moved by the outlier: 3e-5 relative)
    np.testing.assert_allclose(np.trace(sol.cov_ecef_m2), factor * np.trace(clean.cov_ecef_m2), rtol=1e-3)
    unscaled = solve_pvt(sv, sats, pr, config=SolverConfig(scale_covariance=False))
    np.testing.assert_allclose(unscaled.cov_ecef_m2, clean.cov_ecef_m2, rtol=1e-3)  # weights at a moved position


def test_too_few_satellites_no_fix_with_reason():
    sats, rx = make_sats(50.0, 5.0, 100.0, AZ[:3], EL[:3])
    sol = solve_pvt(SV2[:3], sats, ranges(sats, rx, SV2[:3], 0.0))
    assert sol.status == "no_fix" and not sol.is_fix
    assert "too few satellites" in sol.reason and "need 4" in sol.reason
    assert np.all(np.isnan(sol.pos_ecef_m))
    # 5 satellites, 2 below a 20 deg mask: 3 left
    sats, rx = make_sats(50.0, 5.0, 100.0, AZ[:5], np.array([60.0, 45.0, 30.0, 10.0, 5.0]))
    sv = SV2[:5]
    sol = solve_pvt(sv, sats, ranges(sats, rx, sv, 0.0), config=SolverConfig(elevation_mask_deg=20.0))
    assert sol.status == "no_fix" and "2 below the 20 deg mask" in sol.reason
    # two systems need 5: 3 GPS + 1 Galileo is not enough
    sv = ["G01", "G02", "G03", "E01"]
    sats, rx = make_sats(50.0, 5.0, 100.0, AZ[:4], EL[:4])
    sol = solve_pvt(sv, sats, ranges(sats, rx, sv, 0.0))
    assert sol.status == "no_fix" and "need 5" in sol.reason
    # NaN pseudoranges do not count
    pr = ranges(sats, rx, ["G01"] * 4, 0.0)
    pr[0] = np.nan
    sol = solve_pvt(["G01", "G02", "G03", "G04"], sats, pr)
    assert sol.status == "no_fix" and "1 without data" in sol.reason


def test_velocity_and_drift_from_range_rates():
    lat, lon, h = 59.9, 10.75, 60.0
    sats0, rx0 = make_sats(lat, lon, h, AZ, EL)
    rng = np.random.default_rng(5)
    vsat = rng.normal(0.0, 2500.0, sats0.shape)
    vrx = np.array(pymap3d.enu2uvw(12.0, -7.5, 0.8, lat, lon))  # ECEF velocity of 12 m/s E, -7.5 N, 0.8 U
    drift_mps, isb = 85.0, 4.0  # receiver clock drift [m/s]

    def pr_at(t):  # straight-line motion; pseudorange with a drifting clock
        return ranges(sats0 + vsat * t, rx0 + vrx * t, SV2, 1000.0 + drift_mps * t, isb)

    dt = 1e-3
    rate = (pr_at(dt) - pr_at(-dt)) / (2 * dt)  # central difference: independent of the solver's model
    sol = solve_pvt(SV2, sats0, pr_at(0.0), sat_vel_ecef_mps=vsat, range_rate_mps=rate)
    assert sol.status == "fix" and sol.vel_status == "fix", sol.vel_reason
    np.testing.assert_allclose(sol.vel_ecef_mps, vrx, atol=1e-4)
    np.testing.assert_allclose(sol.vel_enu_mps, [12.0, -7.5, 0.8], atol=1e-4)
    assert sol.clock_drift_mps == pytest.approx(drift_mps, abs=1e-4)
    assert sol.clock_drift_sps == pytest.approx(drift_mps / C, rel=1e-6)
    # satellite clock drift given separately
    sdrift = rng.uniform(-1e-10, 1e-10, AZ.size)
    sol2 = solve_pvt(SV2, sats0, pr_at(0.0), sat_vel_ecef_mps=vsat, range_rate_mps=rate - C * sdrift,
                     sat_clock_drift_sps=sdrift)
    np.testing.assert_allclose(sol2.vel_enu_mps, [12.0, -7.5, 0.8], atol=1e-4)
    # too few rates
    r3 = rate.copy()
    r3[3:] = np.nan
    sol3 = solve_pvt(SV2, sats0, pr_at(0.0), sat_vel_ecef_mps=vsat, range_rate_mps=r3)
    assert sol3.status == "fix" and sol3.vel_status == "no_fix" and "too few range rates" in sol3.vel_reason


def test_velocity_covariance_matches_scatter():
    """Range rates with noise drawn from the solver's own a-priori sigmas (rate_sigma_a/b, elevation
    model): the ENU velocity covariance it reports equals R cov_ecef R^T and the scatter of 2000 velocity
    solutions (each diagonal within 10 %: sampling error of a variance over 2000 draws ~3 %)."""
    lat, lon, h = 59.9, 10.75, 60.0
    sats, rx = make_sats(lat, lon, h, AZ, EL)
    vsat = np.zeros_like(sats)
    cfg = SolverConfig()
    s = np.sin(np.radians(EL))
    sigma = np.sqrt(cfg.rate_sigma_a_mps**2 + cfg.rate_sigma_b_mps**2 / s**2)
    los = (sats - rx) / np.linalg.norm(sats - rx, axis=1)[:, None]
    rng = np.random.default_rng(11)
    pr = ranges(sats, rx, SV2, 0.0)
    vel, cov = [], None
    for _ in range(2000):
        rate = np.einsum("ij,ij->i", los, vsat) + sigma * rng.standard_normal(AZ.size)
        sol = solve_pvt(SV2, sats, pr, sat_vel_ecef_mps=vsat, range_rate_mps=rate, config=cfg)
        vel.append(sol.vel_enu_mps)
        cov = sol.cov_vel_enu_m2ps2
    rot = np.array(pymap3d.ecef2enuv(*np.eye(3), lat, lon)).reshape(3, 3)
    np.testing.assert_allclose(cov, rot @ sol.cov_vel_ecef_m2ps2 @ rot.T, rtol=1e-9, atol=1e-15)
    emp = np.cov(np.array(vel).T)
    np.testing.assert_allclose(np.diag(emp), np.diag(cov), rtol=0.10)


def test_doppler_sign_convention():
    # RINEX 3.04 5.3: Doppler positive for approaching satellites, i.e. a negative range rate
    assert range_rate_from_doppler(1000.0, 1575.42e6) == pytest.approx(-1000.0 * C / 1575.42e6)


def test_sigma_models():
    # elevation model: a^2 + b^2/sin^2(el), RTKLIB default a = b = 0.3 m
    assert pseudorange_sigma_m(90.0) == pytest.approx(math.sqrt(0.18))
    assert pseudorange_sigma_m(30.0) == pytest.approx(math.sqrt(0.09 + 0.09 * 4))
    assert pseudorange_sigma_m(30.0, ["R01"]) == pytest.approx(1.5 * math.sqrt(0.45))
    # C/N0 model against Kaplan eq. 5.23 (physics-anchors.md): 4.8/2.6/1.5/0.82/0.46 m at 30..50 dB-Hz
    cfg = SolverConfig(weighting="cn0", sigma_a_m=0.0)
    got = pseudorange_sigma_m(np.full(5, 45.0), cn0_dbhz=[30.0, 35.0, 40.0, 45.0, 50.0], config=cfg)
    np.testing.assert_allclose(got, [4.8, 2.6, 1.5, 0.82, 0.46], rtol=0.06)


def test_cn0_weighting_solves():
    sats, rx = make_sats(59.9, 10.75, 60.0, AZ, EL)
    cn0 = 30.0 + 20.0 * np.sin(np.radians(EL))
    sol = solve_pvt(SV2, sats, ranges(sats, rx, SV2, 10.0, 1.0), cn0_dbhz=cn0,
                    config=SolverConfig(weighting="cn0"))
    assert sol.status == "fix"
    np.testing.assert_allclose(sol.pos_ecef_m, rx, atol=1e-3)
    with pytest.raises(ValueError, match="cn0_dbhz"):
        solve_pvt(SV2, sats, ranges(sats, rx, SV2, 10.0, 1.0), config=SolverConfig(weighting="cn0"))


def test_bad_input_names_parameter():
    sats, rx = make_sats(59.9, 10.75, 60.0, AZ, EL)
    with pytest.raises(ValueError, match="sat_pos_ecef_m"):
        solve_pvt(SV2, sats[:, :2], np.zeros(len(SV2)))
    with pytest.raises(ValueError, match="pseudorange_m"):
        solve_pvt(SV2, sats, np.zeros(3))
    with pytest.raises(ValueError, match="not RINEX satellite ids"):
        solve_pvt(["X1"] + SV2[1:], sats, np.zeros(len(SV2)))


def test_chi2_quantile_table_is_scipys():
    """The residual test's default quantiles (no scipy import at start-up) are scipy.special.chdtri's values,
    and other probabilities or degrees of freedom still come from scipy."""
    from scipy.special import chdtri

    from gnss_sim_ros2.core.solver import CHI2_QUANTILE_P001, _chi2_threshold

    assert len(CHI2_QUANTILE_P001) >= 40
    for dof, v in enumerate(CHI2_QUANTILE_P001, start=1):
        assert v == float(chdtri(dof, 1e-3)), dof
        assert _chi2_threshold(1e-3, dof) == v
    assert _chi2_threshold(1e-3, 200) == float(chdtri(200, 1e-3))
    assert _chi2_threshold(0.01, 5) == float(chdtri(5, 0.01))


@pytest.mark.parametrize("spread", [0.0, 1e-9])
def test_singular_geometry_is_no_fix(spread):
    """Satellites all in one direction (exactly, or within 1e-9 rad): the normal matrix fails the geometry
    check (condition number above 1e14; the norm bound does not let it pass) and the epoch has no fix,
    alone and in a block with a good epoch, which keeps its fix."""
    rng = np.random.default_rng(5)
    rx = np.array([4027894.0, 307045.6, 4919474.9])
    up = rx / np.linalg.norm(rx)
    dirs = up + spread * rng.normal(size=(7, 3))
    sat = rx + 2.2e7 * dirs / np.linalg.norm(dirs, axis=1)[:, None]
    bad = dict(sv=[f"G{i + 1:02d}" for i in range(7)], sat_pos_ecef_m=sat,
               pseudorange_m=np.linalg.norm(sat - rx, axis=1) + 10.0, prior_ecef_m=rx + 5.0)
    good_dirs = rng.normal(size=(7, 3))
    good_dirs = good_dirs / np.linalg.norm(good_dirs, axis=1)[:, None] + 1.5 * up
    good_sat = rx + 2.2e7 * good_dirs / np.linalg.norm(good_dirs, axis=1)[:, None]
    good = dict(bad, sat_pos_ecef_m=good_sat, pseudorange_m=np.linalg.norm(good_sat - rx, axis=1) + 10.0)
    alone = solve_pvt(**bad)
    assert alone.status == "no_fix" and "singular geometry" in alone.reason
    s_bad, s_good = solve_pvt_many([bad, good])
    assert s_bad.status == "no_fix" and "singular geometry" in s_bad.reason
    assert s_good.is_fix and np.linalg.norm(s_good.pos_ecef_m - rx) < 1e-3
