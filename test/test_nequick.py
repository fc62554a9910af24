"""NeQuick-G as the true ionosphere: the JRC library binding, the thin-shell geometry, the receiver's choice."""
from __future__ import annotations

import datetime as dt

import numpy as np
import pytest
from nequick import NeQuick

from gnss_sim_ros2.core import nequick as nq
from gnss_sim_ros2.core import propagation as prop
from gnss_sim_ros2.core.receiver.config import ReceiverConfig
from gnss_sim_ros2.core.receiver.engine import Receiver
from gnss_sim_ros2.core.time import GnssTime

#: OPEC 2022-001 Galileo header (RINEX IONOSPHERIC CORR GAL), and a high solar activity set
GAL_OPEC = [87.75, 0.41797, -0.010742]
GAL_HIGH = [236.831641, -0.39362878, 0.00402826613]


def test_interpolated_vtec_matches_library():
    """Trilinear interpolation between cached nodes against the library's own value at the point."""
    model = nq.NeQuickG(GAL_HIGH)
    raw = NeQuick(*GAL_HIGH)
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(40):
        t = dt.datetime(2025, 3, 21) + dt.timedelta(seconds=float(rng.uniform(0, 86400)))
        lat, lon = rng.uniform(-80, 80), rng.uniform(-180, 180)
        got = model.vtec_tecu(t, lat, lon)[0]
        want = raw.compute_vtec(t, lon, lat)   # the binding takes longitude first
        worst = max(worst, abs(got - want) / max(want, 1.0))
    # a 0.25 deg, 60 s grid: within 1 % of the value (or 0.01 TECU where TEC is near 1 TECU)
    assert worst < 0.01


def test_vtec_daily_and_latitude_structure():
    """What makes it a better truth than Klobuchar: higher TEC by day than by night and towards the
    geomagnetic equator (NeQuick-G on the OPEC coefficients: 3.7 TECU at 00 UT, 14.7 at 12 UT at OPEC)."""
    model = nq.NeQuickG(GAL_OPEC)
    night = model.vtec_tecu(dt.datetime(2022, 1, 1, 0, 5), 59.9, 10.75)[0]
    noon = model.vtec_tecu(dt.datetime(2022, 1, 1, 12, 5), 59.9, 10.75)[0]
    low_lat = model.vtec_tecu(dt.datetime(2022, 1, 1, 12, 5), 20.0, 10.75)[0]
    assert 1.0 < night < 10.0
    assert noon > 2.5 * night
    assert low_lat > 1.5 * noon


@pytest.mark.parametrize("lat, lon", [(0.0, 0.0), (59.9, 10.75), (89.99, 0.0), (-89.99, 45.0), (10.0, 179.99),
                                      (-33.0, -179.99)])
def test_pierce_point_geometry_extremes(lat, lon):
    """Zenith: the pierce point is the user; az 0 at the horizon from the equator: the Earth central
    angle (20.6 deg for 450 km); the poles and the date line give finite, wrapped coordinates."""
    la, lo = nq.pierce_point_deg(lat, lon, 0.0, 90.0)
    assert la == pytest.approx(lat, abs=1e-9)
    assert ((lo - lon + 180.0) % 360.0 - 180.0) == pytest.approx(0.0, abs=1e-6)
    az = np.arange(0.0, 360.0, 15.0)
    la, lo = nq.pierce_point_deg(lat, lon, az, 5.0)
    assert np.all(np.isfinite(la)) and np.all(np.abs(la) <= 90.0)
    assert np.all((lo >= -180.0) & (lo < 180.0))


def test_pierce_point_central_angle_at_horizon():
    r, h = nq.EARTH_RADIUS_M, nq.SHELL_HEIGHT_M
    psi_deg = np.degrees(np.arccos(r / (r + h)))
    la, lo = nq.pierce_point_deg(0.0, 0.0, 0.0, 0.0)
    assert la == pytest.approx(psi_deg, abs=1e-9)
    assert lo == pytest.approx(0.0, abs=1e-9)
    la, lo = nq.pierce_point_deg(0.0, 170.0, 90.0, 0.0)      # east across the date line
    assert lo == pytest.approx(170.0 + psi_deg - 360.0, abs=1e-6)


def test_mapping_function():
    assert nq.mapping_function(90.0) == pytest.approx(1.0, abs=1e-12)
    el = np.linspace(0.0, 90.0, 91)
    m = nq.mapping_function(el)
    assert np.all(np.diff(m) < 0)                              # larger towards the horizon
    r, h = nq.EARTH_RADIUS_M, nq.SHELL_HEIGHT_M
    assert m[0] == pytest.approx(1.0 / np.sqrt(1.0 - (r / (r + h)) ** 2), rel=1e-12)
    assert nq.mapping_function(30.0) == pytest.approx(1.0 / np.cos(np.arcsin(r / (r + h) * np.cos(np.pi / 6))))


def test_slant_delay_scalar_and_array():
    model = nq.NeQuickG(GAL_OPEC)
    t = dt.datetime(2022, 1, 1, 1, 0, 0)
    arr = model.l1_delay_s(t, 59.9, 10.75, np.array([0.0, 180.0]), np.array([90.0, 20.0]))
    one = model.l1_delay_s(t, 59.9, 10.75, 180.0, 20.0)
    assert arr.shape == (2,) and one.shape == (1,)
    assert one[0] == pytest.approx(arr[1], rel=1e-12)
    # zenith delay = 40.3e16 / f^2 * VTEC (IERS 2010 eq. 9.22): metres per TECU at L1 ~ 0.162
    assert nq.TECU_TO_M_L1 == pytest.approx(0.1624, abs=1e-4)
    vtec = model.vtec_tecu(t, 59.9, 10.75)[0]
    assert arr[0] * 299792458.0 == pytest.approx(nq.TECU_TO_M_L1 * vtec, rel=1e-9)
    assert arr[1] > 2.0 * arr[0]                               # slant at 20 deg, to the south


def test_bad_coefficients_named():
    with pytest.raises(ValueError, match="coefficients"):
        nq.NeQuickG([1.0, 2.0])
    with pytest.raises(ValueError, match="coefficients"):
        nq.NeQuickG([float("nan"), 0.0, 0.0])


# ----------------------------------------------------------------------------- the receiver's choice
KLOB = {"GPSA": [1.1176e-08, 7.4506e-09, -5.9605e-08, -5.9605e-08],
        "GPSB": [9.0112e04, 4.9152e04, -1.3107e05, -6.5536e04]}


def test_receiver_picks_the_true_ionosphere():
    assert Receiver(ReceiverConfig(), None, {**KLOB, "GAL": GAL_OPEC}).iono_truth == "nequick"
    assert Receiver(ReceiverConfig(), None, KLOB).iono_truth == "klobuchar"
    assert Receiver(ReceiverConfig(), None, None).iono_truth == "klobuchar"
    assert Receiver(ReceiverConfig(ionosphere="klobuchar"), None, {**KLOB, "GAL": GAL_OPEC}).iono_truth == "klobuchar"
    assert Receiver(ReceiverConfig(ionosphere="none"), None, {**KLOB, "GAL": GAL_OPEC}).iono_truth == "none"
    # a node before its first message: Klobuchar until the coefficients arrive
    rx = Receiver(ReceiverConfig(ionosphere="nequick"), None, None)
    assert rx.iono_truth == "klobuchar"
    rx.set_iono_coefficients({**KLOB, "GAL": GAL_OPEC})
    assert rx.iono_truth == "nequick"
    with pytest.raises(ValueError, match="'ionosphere' = 'nequick' needs the Galileo coefficients"):
        Receiver(ReceiverConfig(ionosphere="nequick"), None, KLOB)
    with pytest.raises(ValueError, match="parameter 'ionosphere'"):
        ReceiverConfig(ionosphere="iri")


def test_observables_carry_nequick_and_receiver_keeps_klobuchar(synthetic_gps):
    """Noise-free: the code delay is NeQuick-G's (minus the phase advance: P - lambda L = 2 I), the
    receiver's own correction (iono_model_m) stays Klobuchar."""
    provider, t, ecef = synthetic_gps
    obs = {}
    for name, iono in (("nequick", {**KLOB, "GAL": GAL_OPEC}), ("klobuchar", KLOB)):
        rx = Receiver(ReceiverConfig(systems="G", noise=False, profile="geodetic"), provider, iono)
        obs[name] = rx.epoch(t, ecef, provider.states(t, systems="G"))
    a, b = obs["nequick"], obs["klobuchar"]
    assert np.array_equal(a.sv, b.sv) and len(a.sv) > 10
    np.testing.assert_allclose(a.iono_model_m, b.iono_model_m, rtol=0, atol=1e-9)
    lam = 299792458.0 / a.frequency_hz
    # divergence P - lambda*L minus the integer ambiguity part: 2 I (same ambiguities: same seed)
    div_a = a.pseudorange_m - lam * a.carrier_phase_cyc
    div_b = b.pseudorange_m - lam * b.carrier_phase_cyc
    d_iono = (div_a - div_b) / 2.0                      # I_nequick - I_klobuchar per signal
    assert np.max(np.abs(d_iono)) > 0.2                 # the two models differ by decimetres to metres
    np.testing.assert_allclose(a.pseudorange_m - b.pseudorange_m, d_iono, atol=1e-6)
    # L2 sees (f1/f2)^2 times the L1 difference
    for sv in np.unique(a.sv):
        i1 = np.where((a.sv == sv) & (a.code == "1C"))[0]
        i2 = np.where((a.sv == sv) & (a.code == "2W"))[0]
        if len(i1) and len(i2):
            assert d_iono[i2[0]] == pytest.approx(d_iono[i1[0]] * float(prop.iono_scale(a.frequency_hz[i2[0]])),
                                                  rel=1e-6, abs=1e-9)


@pytest.fixture(scope="module")
def synthetic_gps(tmp_path_factory):
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.frames import geodetic_to_ecef

    t = GnssTime.from_iso("2022-01-01T10:00:00")
    provider, _ = open_ephemeris("synthetic", t, 600.0, "G", workdir=tmp_path_factory.mktemp("eph"))
    return provider, t, np.array(geodetic_to_ecef(47.0, 8.0, 400.0))


#: validation rows of the Galileo Ionospheric Correction Algorithm 1.2 (2016), as shipped with the JRC
#: implementation: coefficients, month, UT [h], station lon/lat [deg] h [m], satellite lon/lat [deg] h [m],
#: slant TEC [TECU]
ICA_VALIDATION = [
    ([121.129893, 0.351254133, 0.0134635348], 4, 0, 40.19, -3.00, -23.32, 76.65, -41.43, 20157673.93, 18.26001),
    ([121.129893, 0.351254133, 0.0134635348], 4, 4, 40.19, -3.00, -23.32, 107.19, -10.65, 19943686.06, 76.77456),
    ([236.831641, -0.39362878, 0.00402826613], 4, 0, 297.66, 82.49, 78.11, 8.23, 54.29, 20281546.18, 20.40224),
    ([236.831641, -0.39362878, 0.00402826613], 4, 0, 297.66, 82.49, 78.11, -158.03, 24.05, 20275295.43, 53.44495),
]


@pytest.mark.parametrize("coeffs, month, ut, slon, slat, sh, tlon, tlat, th, stec", ICA_VALIDATION)
def test_library_reproduces_ica_validation(coeffs, month, ut, slon, slat, sh, tlon, tlat, th, stec):
    """The binding (longitude first) against the ICA's published slant TEC, to 1e-4 TECU."""
    got = NeQuick(*coeffs).compute_stec(dt.datetime(2016, month, 1, ut), slon, slat, sh, tlon, tlat, th)
    assert got == pytest.approx(stec, abs=1e-4)


def test_thin_shell_against_slant_integration():
    """The stated approximation: thin-shell VTEC x mapping against the library's slant integration on the
    ICA rows, within 10 % (measured 0.95-1.05 at 9-47 deg elevation)."""
    from gnss_sim_ros2.core.frames import az_el_from_ecef, geodetic_to_ecef

    for coeffs, month, ut, slon, slat, sh, tlon, tlat, th, stec in ICA_VALIDATION:
        rx = np.array(geodetic_to_ecef(slat, slon, sh))
        sat = np.array(geodetic_to_ecef(tlat, tlon, th))
        az, el, _ = az_el_from_ecef(rx, sat[None, :])
        delay_s = nq.NeQuickG(coeffs).l1_delay_s(dt.datetime(2016, month, 1, ut), slat, slon, az, el)
        approx_tecu = delay_s[0] * 299792458.0 / nq.TECU_TO_M_L1
        assert approx_tecu == pytest.approx(stec, rel=0.10), (month, ut, slon, slat, tlon, tlat)
