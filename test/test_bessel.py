"""core/bessel.i0e (numpy, Cephes) against scipy.special.i0e: the same algorithm, the same bits."""
from __future__ import annotations

import numpy as np
from scipy.special import i0e as scipy_i0e

from gnss_sim_ros2.core.bessel import i0e


def test_i0e_equals_scipy_to_the_last_bit():
    x = np.concatenate([np.linspace(-60.0, 60.0, 400_001), np.geomspace(1e-300, 1e300, 20_001),
                        [0.0, 8.0, 8.0 + 1e-15]])
    assert np.array_equal(i0e(x), scipy_i0e(x))
    assert i0e(3.5) == scipy_i0e(3.5) and isinstance(i0e(3.5), float)
    assert i0e(np.zeros((2, 3))).shape == (2, 3)
