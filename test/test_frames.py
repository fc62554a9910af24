"""core/frames.py: the closed-form ECEF -> geodetic conversion against pymap3d (an independent library).

Reference points are generated in geodetic coordinates and taken to ECEF with
pymap3d.geodetic2ecef (a direct formula, exact to round-off), so the inverse is
checked against known truth, not against another inverse.  pymap3d's own inverse
(You 2000) is compared where it is itself accurate (near the surface).
"""
from __future__ import annotations

import numpy as np
import pymap3d
import pytest

from gnss_sim_ros2.core import frames

#: 1e-7 m on the ground: far below anything the simulator resolves (round-off is ~4e-9 m)
TOL_M = 1e-7
M_PER_DEG = np.pi / 180.0 * 6.4e6


def _points(h_lo, h_hi, n=20000, seed=0):
    g = np.random.default_rng(seed)
    lat = np.degrees(np.arcsin(g.uniform(-1.0, 1.0, n)))
    lat[:200] = 90.0 - g.uniform(0.0, 1e-6, 200)           # at the north pole
    lat[200:400] = -90.0 + g.uniform(0.0, 1e-3, 200)        # near the south pole
    lat[400:600] = g.uniform(-1e-9, 1e-9, 200)              # on the equator
    lat[600] = 90.0
    lat[601] = -90.0
    lon = g.uniform(-180.0, 180.0, n)
    h = g.uniform(h_lo, h_hi, n)
    return lat, lon, h


@pytest.mark.parametrize("h_lo,h_hi", [(-10e3, 10e3), (10e3, 1000e3), (1000e3, 40000e3), (-300e3, -10e3)],
                         ids=["surface", "leo", "meo-geo", "below"])
def test_ecef_to_geodetic_round_trip(h_lo, h_hi):
    lat, lon, h = _points(h_lo, h_hi)
    x, y, z = pymap3d.geodetic2ecef(lat, lon, h)
    la, lo, hh = frames.ecef_to_geodetic(x, y, z)
    assert np.max(np.abs(la - lat)) * M_PER_DEG < TOL_M
    dlon = (lo - lon + 180.0) % 360.0 - 180.0
    assert np.max(np.abs(dlon) * np.cos(np.radians(lat))) * M_PER_DEG < TOL_M
    assert np.max(np.abs(hh - h)) < TOL_M * (1.0 + h_hi / 1e6)   # relative round-off far out
    assert np.all((lo > -180.0 - 1e-12) & (lo <= 180.0))


def test_ecef_to_geodetic_matches_pymap3d_near_surface():
    lat, lon, h = _points(-10e3, 10e3, n=5000, seed=3)
    x, y, z = pymap3d.geodetic2ecef(lat, lon, h)
    ref = pymap3d.ecef2geodetic(x, y, z)
    got = frames.ecef_to_geodetic(x, y, z)
    assert np.max(np.abs(got[0] - ref[0])) * M_PER_DEG < TOL_M
    assert np.max(np.abs(got[2] - ref[2])) < TOL_M


def test_ecef_to_geodetic_scalar_and_array_agree():
    x, y, z = 3149785.9652, 598260.8822, 5495348.4927      # OPEC, Oslo
    s = frames.ecef_to_geodetic(x, y, z)
    a = frames.ecef_to_geodetic(np.array([x, x]), np.array([y, y]), np.array([z, z]))
    ref = pymap3d.ecef2geodetic(x, y, z)
    for v, va, vr in zip(s, a, ref):
        assert np.ndim(v) == 0 and isinstance(v, np.floating)
        assert va.shape == (2,)
        assert abs(float(v) - float(va[0])) < 1e-12 * max(1.0, abs(float(v)))
        assert abs(float(v) - float(vr)) < TOL_M    # deg or m: both far below round-off of 1e-7 m
    # broadcasting of mixed shapes
    b = frames.ecef_to_geodetic(np.array([x, x]), y, z)
    assert b[0].shape == (2,)


def test_ecef_to_geodetic_poles_and_deep_points():
    lat, lon, h = frames.ecef_to_geodetic(0.0, 0.0, 6356752.314245179 + 100.0)
    assert lat == pytest.approx(90.0, abs=1e-12) and h == pytest.approx(100.0, abs=TOL_M)
    lat, lon, h = frames.ecef_to_geodetic(0.0, 0.0, -6356752.314245179 - 5.0)
    assert lat == pytest.approx(-90.0, abs=1e-12) and h == pytest.approx(5.0, abs=TOL_M)
    # deep inside the Earth (no antenna there): pymap3d's answer, unchanged
    for p in [(0.0, 0.0, 0.0), (1000.0, 0.0, 0.0), (0.0, 0.0, -1000.0)]:
        assert np.allclose(frames.ecef_to_geodetic(*p), pymap3d.ecef2geodetic(*p))
    got = frames.ecef_to_geodetic(np.array([0.0, 6378137.0]), np.array([0.0, 0.0]), np.array([0.0, 0.0]))
    ref = pymap3d.ecef2geodetic(np.array([0.0, 6378137.0]), np.array([0.0, 0.0]), np.array([0.0, 0.0]))
    assert np.allclose(got, ref)


def test_az_el_at_equals_az_el_from_ecef():
    rx = np.array([3149785.9652, 598260.8822, 5495348.4927])
    g = np.random.default_rng(1)
    sat = g.normal(size=(50, 3)) * 1.5e7 + rx
    lat, lon, h = pymap3d.ecef2geodetic(*rx)
    az, el, rng = frames.az_el_from_ecef(rx, sat)
    az2, el2, rng2 = frames.az_el_at(rx, lat, lon, sat)
    assert np.allclose(az, az2, atol=1e-9) and np.allclose(el, el2, atol=1e-9)
    assert np.allclose(rng, np.linalg.norm(sat - rx, axis=1), rtol=1e-14)
    # elevation from pymap3d's own ECEF -> AER (independent implementation)
    a3, e3, r3 = pymap3d.ecef2aer(sat[:, 0], sat[:, 1], sat[:, 2], lat, lon, h)
    assert np.allclose(el, e3, atol=1e-8) and np.allclose(az, a3 % 360.0, atol=1e-8)
