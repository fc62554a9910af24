"""Signal table: frequencies from the ICDs' 10.23 MHz multiples, GLONASS FDMA, profiles, validation."""
from __future__ import annotations

import numpy as np
import pytest

from gnss_sim_ros2.core import signals

F0 = 10.23e6  # fundamental frequency of GPS/Galileo/BeiDou/QZSS/NavIC carriers [Hz]


@pytest.mark.parametrize("system,code,multiple", [
    # carrier = n * 10.23 MHz (IS-GPS-200N 3.3.1.1, IS-GPS-705 3.3.1.1, Galileo OS SIS ICD 2.3,
    # BDS ICDs, IRNSS ICD 2.2)
    ("G", "1C", 154), ("G", "2W", 120), ("G", "2L", 120), ("G", "5Q", 115),
    ("E", "1C", 154), ("E", "5Q", 115), ("E", "7Q", 118), ("E", "8Q", 116.5), ("E", "6C", 125),
    ("C", "2I", 152.6), ("C", "1P", 154), ("C", "5P", 115), ("C", "7I", 118), ("C", "7D", 118),
    ("C", "6I", 124), ("J", "1C", 154), ("J", "2L", 120), ("J", "5Q", 115), ("J", "6Z", 125),
    ("I", "5A", 115), ("I", "9A", 243.6),
])
def test_carriers_are_icd_multiples_of_10_23_mhz(system, code, multiple):
    assert signals.frequency_hz(system, code) == pytest.approx(multiple * F0, rel=1e-12)
    assert signals.wavelength_m(system, code) == pytest.approx(299792458.0 / (multiple * F0), rel=1e-12)


def test_gps_l1_wavelength_and_ca_chip_length():
    # published: L1 wavelength 19.03 cm, one C/A chip 293.05 m (physics-anchors: 293 m)
    assert signals.wavelength_m("G", "1C") == pytest.approx(0.19029, abs=1e-5)
    assert signals.signal("G", "1C").chip_length_m == pytest.approx(293.05, abs=0.01)
    assert signals.signal("G", "2W").chip_length_m == pytest.approx(29.305, abs=0.001)


def test_glonass_fdma_channels_vectorised():
    k = np.arange(-7, 7)
    f1 = signals.frequency_hz("R", "1C", k)
    f2 = signals.frequency_hz("R", "2C", k)
    # GLONASS ICD 5.1 3.3.1.4: channel -7 -> 1598.0625 / 1242.9375 MHz, +6 -> 1605.375 / 1248.625 MHz
    assert f1[0] == pytest.approx(1598.0625e6) and f1[-1] == pytest.approx(1605.375e6)
    assert f2[0] == pytest.approx(1242.9375e6) and f2[-1] == pytest.approx(1248.625e6)
    # f1/f2 = 9/7 for every channel (same ICD)
    np.testing.assert_allclose(f1 / f2, 9.0 / 7.0, rtol=1e-14)
    assert signals.frequency_hz("R", "1P", 1) == pytest.approx(1602.5625e6)
    assert np.shape(signals.wavelength_m("R", "1C", k)) == k.shape
    # CDMA signals broadcast over an array channel argument too
    assert signals.frequency_hz("G", "1C", np.zeros(3, int)).shape == (3,)


def test_unknown_code_and_system_are_named():
    with pytest.raises(ValueError, match="'code'.*'9Z'"):
        signals.signal("G", "9Z")
    with pytest.raises(ValueError, match="'system'"):
        signals.signal("X", "1C")
    with pytest.raises(ValueError, match="glo_channel"):
        signals.frequency_hz("R", "1C", 20)
    with pytest.raises(ValueError, match="glo_channel"):
        signals.frequency_hz("R", "1C", 0.5)


def test_observation_type_prefix_accepted():
    assert signals.signal("G", "C1C") is signals.signal("G", "1C")
    assert signals.signal("E", "L5Q").band == "E5a"


def test_profiles_validate_and_geodetic_is_multi_frequency():
    from gnss_sim_ros2.core.receiver.profiles import builtin_names, load_profile

    for name in builtin_names():
        prof = load_profile(name).signal_map()
        signals.validate_profile(prof)
        for sys_, codes in prof.items():
            assert sys_ in signals.SYSTEMS
            assert all(len(c) == 2 for c in codes)
    geo = load_profile("geodetic").signal_map()
    for sys_ in "GECJ":
        freqs = {signals.frequency_hz(sys_, c) for c in geo[sys_]}
        assert len(freqs) >= 3, sys_
    with pytest.raises(ValueError, match="'code'"):
        signals.validate_profile({"G": ["1C", "4Q"]})


def test_minimum_power_values_are_plausible():
    # every ICD minimum received power lies in -167..-152 dBW (GLONASS L2 lowest, E5 AltBOC highest)
    for s in signals.SIGNALS.values():
        assert -167.0 <= s.min_power_dbw <= -152.0, s
        assert s.min_power_el_deg in (5.0, 10.0)
        assert s.source
