"""core/metrics.py: horizontal error, RMS and 95th percentile, on scalars, arrays and empty input."""
from __future__ import annotations

import math

import numpy as np
import pytest

from gnss_sim_ros2.core.frames import enu_to_ecef, geodetic_to_ecef
from gnss_sim_ros2.core.metrics import horizontal_errors_m, horizontal_stats, p95, percentile, rms, rounded

LAT, LON, H = 47.3769, 8.5417, 408.0
TRUE = np.array(geodetic_to_ecef(LAT, LON, H))


def test_horizontal_error_ignores_the_vertical():
    est = enu_to_ecef(np.array([[3.0, 4.0, 0.0], [3.0, 4.0, 25.0], [0.0, 0.0, -7.0]]), LAT, LON, H)
    np.testing.assert_allclose(horizontal_errors_m(est, np.tile(TRUE, (3, 1))), [5.0, 5.0, 0.0], atol=1e-6)


def test_horizontal_error_of_one_position_and_of_none():
    one = horizontal_errors_m(enu_to_ecef(np.array([0.0, 2.0, 1.0]), LAT, LON, H), TRUE)
    assert one.shape == (1,) and one[0] == pytest.approx(2.0, abs=1e-6)
    assert horizontal_errors_m(np.zeros((0, 3)), np.zeros((0, 3))).shape == (0,)
    assert horizontal_errors_m([], []).shape == (0,)


def test_rms_and_p95_of_scalars_lists_arrays():
    assert rms(3.0) == 3.0 and rms(-2) == 2.0
    assert rms([3.0, 4.0]) == pytest.approx(math.sqrt(12.5))
    assert rms(np.array([[1.0, 1.0], [1.0, 1.0]])) == 1.0
    assert p95(7.0) == 7.0
    assert p95(np.arange(101.0)) == pytest.approx(95.0)
    assert percentile([1.0, 2.0, 3.0], 50) == 2.0
    assert isinstance(rms(np.float32(2.0)), float) and isinstance(p95([1, 2]), float)


def test_empty_input_gives_none_without_warning():
    with np.errstate(all="raise"):
        assert rms([]) is None and p95([]) is None and percentile(np.zeros(0), 50) is None
        assert rms([np.nan, np.inf], skip_nonfinite=True) is None


def test_nonfinite_values_count_unless_skipped():
    assert math.isnan(rms([1.0, np.nan]))
    assert rms([3.0, np.nan, -np.inf, 3.0], skip_nonfinite=True) == 3.0
    assert p95([np.nan, 2.0], skip_nonfinite=True) == 2.0


def test_rounded_keeps_none():
    assert rounded(None, 3) is None and rounded(1.23456, 3) == 1.235


def test_horizontal_stats_skips_epochs_without_solution():
    est = enu_to_ecef(np.array([[3.0, 4.0, 0.0], [np.nan] * 3, [0.0, 5.0, 9.0]]), LAT, LON, H)
    s = horizontal_stats(est, np.tile(TRUE, (3, 1)))
    assert s["epochs"] == 2 and s["rms_m"] == pytest.approx(5.0) and s["p95_m"] == pytest.approx(5.0)
    none = horizontal_stats(np.full((2, 3), np.nan), np.tile(TRUE, (2, 1)))
    assert none["epochs"] == 0 and math.isnan(none["rms_m"]) and math.isnan(none["p95_m"])
