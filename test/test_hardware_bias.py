"""Receiver hardware code biases: table lookup, validation, and their place in the observables."""
from __future__ import annotations

import numpy as np
import pytest

from gnss_sim_ros2.core.receiver import hardware_bias as hb
from gnss_sim_ros2.core.receiver.config import ReceiverConfig
from gnss_sim_ros2.core.receiver.engine import Receiver
from gnss_sim_ros2.core.time import GnssTime


def test_bds_generation_groups():
    assert [hb.group_of(s) for s in ("C01", "C05", "C16", "C18", "C19", "C46", "C60")] == \
        ["C2", "C2", "C2", "C2", "C3", "C3", "C3"]
    assert hb.group_of("G07") == "G" and hb.group_of("E33") == "E" and hb.group_of("R24") == "R"


def test_lookup_precedence():
    table = hb.validate({"G": {"2W": 1.0, "2": 2.0, "*": 3.0}, "C": {"*": 5.0}, "C2": {"6": 7.0}})
    svs = ["G01", "G01", "G01", "G01", "C06", "C06", "C30", "E01"]
    codes = ["2W", "2L", "1C", "5Q", "6I", "2I", "2I", "1C"]
    got = hb.code_bias_m(table, svs, codes)
    # exact code, band, "*", then (BeiDou) the generation's group before the system letter; none: 0
    np.testing.assert_array_equal(got, [1.0, 2.0, 3.0, 3.0, 7.0, 5.0, 5.0, 0.0])


@pytest.mark.parametrize("table, match", [
    ([1, 2], "must be a mapping"),
    ({"X": {"*": 1.0}}, "group 'X'"),
    ({"G": {"L1": 1.0}}, "entry G/L1"),
    ({"E": {"*": "a lot"}}, "entry E/\\*"),
    ({"C2": {"2": float("inf")}}, "entry C2/2"),
])
def test_validation_names_the_entry(table, match):
    with pytest.raises(ValueError, match=f"parameter 'code_bias_m'.*{match}|{match}"):
        hb.validate(table)
    with pytest.raises(ValueError, match="code_bias_m"):
        ReceiverConfig(code_bias_m=table)


def test_profile_defaults_and_ideal_receiver():
    # the tables measured on OPEC 2022-001 (NETR9: Galileo -2.9 m, BeiDou-2 7.5 m, BeiDou-3 8.9 m), in the
    # geodetic profile's YAML file; the single-frequency profile keeps only the BeiDou-2/-3 split
    geo = {"E": {"*": -2.9}, "C2": {"*": 7.5}, "C3": {"*": 8.9}}
    single = {"C2": {"*": -1.4}}
    assert ReceiverConfig().code_bias_m == geo
    assert ReceiverConfig(profile="single_frequency").code_bias_m == single
    assert ReceiverConfig(profile={"G": ["1C"]}).code_bias_m == {}            # a custom profile: none
    assert ReceiverConfig(noise=False).code_bias_m == {}                      # --noise-free: an ideal receiver
    assert ReceiverConfig(code_bias_m={"G": {"*": 1.5}}).code_bias_m == {"G": {"*": 1.5}}
    # the BeiDou-3 minus BeiDou-2 split is the same in both profiles
    assert geo["C3"]["*"] - geo["C2"]["*"] == pytest.approx(-single["C2"]["*"])


def test_biases_enter_code_only(tmp_path):
    """Same seeds, biases on and off: pseudoranges differ by exactly the table, phase and Doppler not."""
    from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
    from gnss_sim_ros2.core.frames import geodetic_to_ecef

    t = GnssTime.from_iso("2024-05-01T06:00:00")
    provider, _ = open_ephemeris("synthetic", t, 600.0, "GEC", workdir=tmp_path)
    ecef = np.array(geodetic_to_ecef(30.0, 110.0, 50.0))     # BeiDou-2 and -3 both in view
    table = {"E": {"*": -2.9}, "C2": {"*": 7.5}, "C3": {"*": 8.9, "6": -1.0}}
    out = {}
    for name, tab in (("on", table), ("off", {})):
        rx = Receiver(ReceiverConfig(systems="GEC", code_bias_m=tab, seed=4), provider, provider.iono)
        out[name] = [rx.epoch(t + k, ecef, provider.states(t + k, systems="GEC")) for k in range(3)]
    for a, b in zip(out["on"], out["off"]):
        assert np.array_equal(a.sv, b.sv) and np.array_equal(a.code, b.code)
        want = hb.code_bias_m(hb.validate(table), a.sv, a.code)
        np.testing.assert_allclose(a.pseudorange_m - b.pseudorange_m, want, atol=1e-6)
        np.testing.assert_array_equal(a.carrier_phase_cyc, b.carrier_phase_cyc)
        np.testing.assert_array_equal(a.doppler_hz, b.doppler_hz)
        groups = {hb.group_of(s) for s in a.sv}
        assert {"C2", "C3", "G", "E"} <= groups
