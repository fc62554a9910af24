"""Time scales: exact offsets from their ICDs, leap seconds, rollovers, resolution."""
from __future__ import annotations

import datetime as dt

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gnss_sim_ros2.core.time import GnssTime, resolve_week


def test_gps_epoch_and_week_tow():
    t = GnssTime.from_iso("1980-01-06T00:00:00")
    assert (t.sec, t.frac) == (0, 0.0)
    # 2022-01-01 is a Saturday of GPS week 2190: tow = 6 days
    assert GnssTime.from_iso("2022-01-01T00:00:00").week_tow() == (2190, 6 * 86400.0)


def test_week_rollovers_1999_and_2019():
    # IS-GPS-200: week 1024 began 1999-08-22, week 2048 began 2019-04-07 (both 00:00 GPST)
    assert GnssTime.from_iso("1999-08-22T00:00:00").week_tow() == (1024, 0.0)
    assert GnssTime.from_iso("2019-04-07T00:00:00").week_tow() == (2048, 0.0)
    near = GnssTime.from_iso("2019-04-06T23:59:00")
    assert resolve_week(0, near + 120) == 2048
    assert resolve_week(1023, near) == 2047
    assert resolve_week(1023, GnssTime.from_iso("1999-08-21T00:00:00")) == 1023


def test_bdt_and_gst_epochs():
    # BDS-SIS-ICD: BDT week 0 starts 2006-01-01 00:00:00 UTC = 00:00:14 GPST; BDT = GPST - 14 s
    t = GnssTime.from_iso("2006-01-01T00:00:14")
    assert t.week_tow("BDT") == (0, 0.0)
    assert GnssTime.from_week_tow(0, 0.0, "BDT") == t
    assert GnssTime.from_iso("2006-01-01T00:00:00", "BDT") == t
    # Galileo OS SIS ICD 5.1.2: GST week 0 starts 1999-08-22 00:00:00 GPST (GST is aligned with GPST)
    assert GnssTime.from_iso("1999-08-22T00:00:00").week_tow("GST") == (0, 0.0)
    assert GnssTime.from_week_tow(1166, 518700.0, "GST") == GnssTime.from_iso("2022-01-01T00:05:00")


def test_leap_seconds():
    # IERS Bulletin C: GPS-UTC was 17 s before 2017-01-01 and 18 s after
    before = GnssTime.from_iso("2016-12-31T23:59:59", "UTC")
    after = GnssTime.from_iso("2017-01-01T00:00:00", "UTC")
    assert after - before == 2.0  # the inserted leap second 23:59:60 lies between them
    assert before.isoformat("UTC") == "2016-12-31T23:59:59"
    assert after.isoformat("UTC") == "2017-01-01T00:00:00"
    assert after - GnssTime.from_iso("2017-01-01T00:00:00") == 18.0
    assert before - GnssTime.from_iso("2016-12-31T23:59:59") == 17.0


def test_glonass_time_is_utc_plus_3h():
    t = GnssTime.from_iso("2022-01-01T03:00:00", "GLO")
    assert t == GnssTime.from_iso("2022-01-01T00:00:00", "UTC")
    assert t.isoformat("GLO") == "2022-01-01T03:00:00"
    # GLONASS day boundary: midnight Moscow time is 21:00 UTC of the previous day
    assert GnssTime.from_iso("2022-01-02T00:00:00", "GLO").isoformat("UTC") == "2022-01-01T21:00:00"


def test_subnanosecond_resolution_over_decades():
    # 0.1 ns steps stay exact 45 years after the epoch; a float64 of seconds resolves only ~2e-7 s there.
    t0 = GnssTime.from_iso("2025-06-30T12:00:00")
    t1 = t0 + 1e-10
    assert t1 - t0 == pytest.approx(1e-10, abs=1e-15)
    far = t0 + 30 * 365.25 * 86400  # 2055
    assert (far + 3e-10) - far == pytest.approx(3e-10, abs=1e-15)
    assert (far + 3e-10) - t0 == pytest.approx(30 * 365.25 * 86400 + 3e-10, abs=1e-12)


def test_arrays_broadcast_like_numpy():
    t0 = GnssTime.from_iso("2022-01-01T00:00:00")
    ts = GnssTime.arange(t0, t0 + 5.0, 0.25)
    assert len(ts) == 20
    np.testing.assert_allclose(ts - t0, np.arange(20) * 0.25, atol=1e-15)
    wk, tow = ts.week_tow()
    assert np.all(wk == 2190)
    assert ts[3] == t0 + 0.75


@given(
    sec=st.integers(min_value=0, max_value=2**40),
    frac=st.floats(min_value=0.0, max_value=0.999999999, allow_nan=False),
    dt_s=st.floats(min_value=-1e9, max_value=1e9, allow_nan=False),
)
def test_add_then_subtract_is_exact_to_subnanosecond(sec, frac, dt_s):
    t = GnssTime(sec, frac)
    assert abs(((t + dt_s) - t) - dt_s) <= 1e-10 + abs(dt_s) * 1e-16


@given(st.datetimes(min_value=dt.datetime(1981, 1, 1), max_value=dt.datetime(2090, 1, 1)),
       st.sampled_from(["GPS", "GST", "BDT", "QZS", "IRN", "UTC", "GLO"]))
def test_datetime_round_trip_every_scale(d, scale):
    d = d.replace(microsecond=0)
    t = GnssTime.from_datetime(d, scale)
    back = t.to_datetime(scale)
    # a UTC/GLONASS instant inside an inserted leap second has no datetime of its own
    assert back == d


def test_bad_input_names_it():
    with pytest.raises(ValueError, match="2022-13"):
        GnssTime.from_iso("2022-13-01 x")
    with pytest.raises(ValueError, match="scale"):
        GnssTime.from_iso("2022-01-01T00:00:00", "TAI")
