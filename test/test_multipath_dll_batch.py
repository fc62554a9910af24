"""dll.tracking_error of many calls at once (``calls``, the engine's epochs of a block) gives each call's bits."""
import numpy as np
import pytest

from gnss_sim_ros2.core.multipath import dll


def _calls(rng, n_calls=60, paths=4):
    out = []
    for _ in range(n_calls):
        n = int(rng.integers(1, 6))
        a = np.c_[rng.choice([0.0, 0.5, 1.0], n),
                  rng.uniform(0, 1, (n, paths - 1)) * (rng.uniform(size=(n, paths - 1)) > 0.3)]
        d = np.c_[np.zeros(n), rng.uniform(0, rng.choice([0.2, 3.0, 40.0]), (n, paths - 1))]
        p = np.c_[np.zeros(n), rng.uniform(-7, 7, (n, paths - 1))]
        out.append((a, d, p))
    return out


@pytest.mark.parametrize("bandwidth", [np.inf, 1.7, 20.0])
def test_calls_at_once_equal_separate_calls_bit_for_bit(bandwidth):
    calls = _calls(np.random.default_rng(3))
    separate = [dll.tracking_error(a, d, p, 0.2, bandwidth) for a, d, p in calls]
    label = np.concatenate([np.full(len(c[0]), i) for i, c in enumerate(calls)])
    a, d, p = (np.concatenate(x) for x in zip(*calls))
    together = dll.tracking_error(a, d, p, 0.2, bandwidth, calls=label)
    sizes = {dll._grid_points(np.max(np.ptp(c[1], axis=1)) + 2.0, 0.05) for c in calls}
    assert len(sizes) > 3                     # the calls' peak grids differ in size
    for k in range(3):
        assert np.array_equal(np.concatenate([s[k] for s in separate]), together[k], equal_nan=True)
    assert not np.array_equal(together[0], dll.tracking_error(a, d, p, 0.2, bandwidth)[0], equal_nan=True)


@pytest.mark.parametrize("bandwidth", [1.564, 4.0, 31.3])
def test_table_interpolation_equals_np_interp_bit_for_bit(bandwidth):
    tau, r = dll._bandlimited_table(bandwidth)
    x = np.concatenate([np.random.default_rng(5).uniform(-3.5, 3.5, 200_000), tau, np.nextafter(tau, 9),
                        np.nextafter(tau, -9), [-np.inf, np.inf, np.nan, 0.0, -0.0, 1e300, -1e300]])
    want = np.interp(x, tau, r, left=0.0, right=0.0)
    got = dll.correlation(x, bandwidth)
    assert np.array_equal(want.view(np.int64), got.view(np.int64))
