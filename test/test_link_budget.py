"""Link budget per signal, antenna classes, the profile's per-signal tables and noise from the loop parameters
(issue 26, part C): core/receiver/cn0.py, core/signals.py power columns, core/multipath/antenna.py,
core/receiver/code_multipath.py, core/receiver/noise.py."""
from __future__ import annotations

import numpy as np
import pytest
from test_receiver_fastpaths import ORB, RX  # exact circular orbits above the OPEC marker

from gnss_sim_ros2.core import signals
from gnss_sim_ros2.core.ephemeris.states import SatelliteStates
from gnss_sim_ros2.core.multipath import antenna
from gnss_sim_ros2.core.receiver import cn0 as rcn0
from gnss_sim_ros2.core.receiver import noise
from gnss_sim_ros2.core.receiver.code_multipath import OPEN_SKY_MP_M, CodeMultipath
from gnss_sim_ros2.core.receiver.config import ReceiverConfig
from gnss_sim_ros2.core.receiver.engine import Receiver
from gnss_sim_ros2.core.time import GnssTime

R_GPS, R_GAL = 26560e3, 29600e3


def _cn0(sys_, code, el, budget, r=None):
    r = r if r is not None else (R_GAL if sys_ == "E" else R_GPS)
    el = np.asarray(el, dtype=float)
    return rcn0.cn0_dbhz(sys_, code, rcn0.slant_range_m(r, el), el, budget=budget)


# ---------------------------------------------------------------- transmitted power per signal
def test_tracked_component_power_from_the_icd_split():
    # GPS L5: the ICD gives I5 and Q5 at -157.9 dBW each (IS-GPS-705J 3.3.1.6), the row the sum (-154.9)
    s = signals.signal("G", "5Q")
    assert s.min_power_dbw + s.component_db == pytest.approx(-157.9, abs=0.02)
    # Galileo E1-B + E1-C = -157 dBW, equal split: the pilot alone 3 dB less; E1X (both) the whole
    assert signals.signal("E", "1C").component_db == pytest.approx(-3.01, abs=0.01)
    assert signals.signal("E", "1X").component_db == 0.0
    # L1C 75 % pilot / 25 % data (IS-GPS-800J): -1.25 / -6.02 dB
    assert signals.signal("G", "1L").component_db == pytest.approx(10 * np.log10(0.75), abs=0.01)
    assert signals.signal("C", "1D").component_db == pytest.approx(10 * np.log10(0.25), abs=0.01)
    # the edge power the link budget starts from: ICD minimum + published margin + component
    p, el = rcn0.power_params("E", "1C")
    e1 = signals.signal("E", "1C")
    assert p == pytest.approx(e1.min_power_dbw + e1.power_margin_db - 3.01, abs=0.01) and el == 10.0


def test_signals_of_one_satellite_get_different_cn0():
    b = rcn0.LinkBudget(antenna="choke_ring")
    el = 60.0
    e1c, e5q, e7q, e8q, e6c = (float(_cn0("E", c, el, b)) for c in ("1C", "5Q", "7Q", "8Q", "6C"))
    # E5 AltBOC pilot carries both sidebands (ICD -152 dBW total): 3 dB above an E5a or E5b pilot;
    # E1 pilot (-160 dBW) below the E5a/E5b pilots (-158 dBW): not one C/N0 for all Galileo signals
    assert e8q - e5q == pytest.approx(3.0, abs=0.1)
    assert e5q - e1c > 1.5
    assert e5q == pytest.approx(e7q, abs=0.01) and e6c == pytest.approx(e5q, abs=0.01)   # equal ICD powers
    # BeiDou B1I (upper L band) and B2I/B3I (lower band: the choke ring's lower-band table)
    b1i, b2i = (float(_cn0("C", c, el, b, r=27906e3)) for c in ("2I", "7I"))
    assert b1i != pytest.approx(b2i, abs=0.1)
    # BeiDou B1I exceeds its conservative -163 dBW ICD minimum by several dB (POWER_MARGIN_DB): within 2 dB of
    # GPS L1 C/A, as receivers report (physics-anchors.md: B1I above L1 C/A on the PolaRx5 station)
    assert abs(b1i - float(_cn0("G", "1C", el, b))) < 2.0
    # GLONASS-M transmits L2 as strongly as L1
    assert float(_cn0("R", "2C", el, b)) == pytest.approx(float(_cn0("R", "1C", el, b)), abs=1.0)


def test_received_power_at_the_edge_and_shaped_satellite_beam():
    for sys_, code, r in (("G", "1C", R_GPS), ("E", "7Q", R_GAL), ("C", "2I", 42164e3)):
        s = signals.signal(sys_, code)
        rho = rcn0.slant_range_m(r, s.min_power_el_deg)
        want = s.min_power_dbw + s.power_margin_db + s.component_db
        assert rcn0.received_power_dbw(sys_, code, rho, s.min_power_el_deg) == pytest.approx(want, abs=1e-6)
    # zenith: the free-space gain (2.1 dB for GPS from 5 deg) mostly compensated by the satellite's shaped beam
    # (IS-GPS-200 figure 3.3-1: about 1 dB)
    edge = rcn0.received_power_dbw("G", "1C", rcn0.slant_range_m(R_GPS, 5.0), 5.0)
    zen = rcn0.received_power_dbw("G", "1C", rcn0.slant_range_m(R_GPS, 90.0), 90.0)
    assert 0.5 < zen - edge < 1.5


# ---------------------------------------------------------------- antenna classes
def test_antenna_class_roll_off():
    el = np.array([10.0, 90.0])
    roll = {p: np.diff(antenna.rhcp_gain_dbic(p, el))[0] for p in antenna.PATTERNS}
    # the choke ring rolls off steepest (10-13 dB from zenith to 10 deg), the helix least
    assert 10.0 <= roll["choke_ring"] <= 13.5
    assert roll["choke_ring"] > roll["patch"] > roll["helical"]
    # the lower L band of the choke ring: a slightly broader beam
    low = np.diff(antenna.rhcp_gain_dbic("choke_ring", el, 1.2276e9))[0]
    assert roll["choke_ring"] - 2.0 < low < roll["choke_ring"]
    # GPS L1 C/N0 with the choke ring: 15-20 dB from 5 deg to the zenith incl. the path (a real PolaRx5 with a
    # choke ring: about 17 dB, physics-anchors.md), the patch far less
    b_choke, b_patch = rcn0.LinkBudget(antenna="choke_ring"), rcn0.LinkBudget(antenna="patch")
    rise = np.diff(_cn0("G", "1C", [5.0, 90.0], b_choke))[0]
    assert 15.0 <= rise <= 20.0
    assert np.diff(_cn0("G", "1C", [5.0, 90.0], b_patch))[0] < rise - 3.0
    # zenith level: geodetic receivers report 50-53 dB-Hz for L1 C/A
    assert 50.0 <= float(_cn0("G", "1C", 90.0, b_choke)) <= 53.5
    with pytest.raises(ValueError, match="helix"):
        rcn0.LinkBudget(antenna="helix")


def test_receiver_antenna_class_feeds_the_link_budget_and_multipath():
    for ant in antenna.PATTERNS:
        cfg = ReceiverConfig(profile="geodetic", antenna=ant)
        assert cfg.link_budget.antenna == ant
        assert (cfg.mp_zenith_m, cfg.mp_low_m) == OPEN_SKY_MP_M[ant]
    # open-sky multipath: choke ring < helix < patch at every elevation
    el = np.array([10.0, 45.0, 90.0])
    s = {a: z + lo * np.exp(-el / 15.0) for a, (z, lo) in OPEN_SKY_MP_M.items()}
    assert np.all(s["choke_ring"] < s["helical"]) and np.all(s["helical"] < s["patch"])
    # a profile's own values win
    cfg = ReceiverConfig(profile="geodetic", mp_zenith_m=0.3)
    assert cfg.mp_zenith_m == 0.3 and cfg.mp_low_m == OPEN_SKY_MP_M["choke_ring"][1]


# ---------------------------------------------------------------- per-signal tables
TABLE = {"G1C": {"el_deg": [10.0, 50.0, 90.0], "cn0_dbhz": [38.0, 48.0, 51.0]}}


def test_cn0_table_replaces_the_link_budget_of_its_signal():
    b = rcn0.LinkBudget(antenna="choke_ring", cn0_table_dbhz=TABLE)
    plain = rcn0.LinkBudget(antenna="choke_ring")
    el = np.array([10.0, 30.0, 90.0, 5.0])
    rho = rcn0.slant_range_m(R_GPS, el)
    got = rcn0.cn0_dbhz(np.array(["G"] * 4), np.array(["1C"] * 4), rho, el, attenuation_db=np.array([0, 0, 12, 0]),
                        budget=b)
    # linear interpolation, held at the ends, the obstruction loss still subtracted, range not added again
    np.testing.assert_allclose(got, [38.0, 43.0, 51.0 - 12.0, 38.0])
    # other signals keep the link budget
    assert float(rcn0.cn0_dbhz("G", "2W", rho[1], 30.0, budget=b)) == pytest.approx(
        float(rcn0.cn0_dbhz("G", "2W", rho[1], 30.0, budget=plain)))


@pytest.mark.parametrize("row, match", [
    ({"el_deg": [10.0, 10.0], "cn0_dbhz": [40.0, 41.0]}, "increase strictly"),
    ({"el_deg": [10.0, 95.0], "cn0_dbhz": [40.0, 41.0]}, r"\[0, 90\]"),
    ({"el_deg": [10.0, 20.0], "cn0_dbhz": [40.0]}, "same length"),
    ({"el_deg": [10.0, 20.0], "cn0_dbhz": [40.0, float("nan")]}, "finite"),
    ({"el_deg": [10.0], "cn0": [40.0]}, "exactly"),
])
def test_cn0_table_validation_names_the_key(row, match):
    with pytest.raises(ValueError, match=match) as err:
        rcn0.LinkBudget(cn0_table_dbhz={"E5Q": row})
    assert "'E5Q'" in str(err.value) and "cn0_table_dbhz" in str(err.value)
    with pytest.raises(ValueError, match="'G7Q'"):
        rcn0.LinkBudget(cn0_table_dbhz={"G7Q": {"el_deg": [10.0], "cn0_dbhz": [40.0]}})


def test_code_multipath_table_replaces_the_formula_of_its_signal():
    table = {"E1C": {"el_deg": [10.0, 90.0], "sigma_m": [0.4, 0.04]}}
    cfg = ReceiverConfig(profile="geodetic", code_multipath_m=table)
    mp = CodeMultipath(cfg, np.random.default_rng(0))
    el = np.array([50.0, 50.0])
    s = mp.sigma_m(el, np.array(["E1C", "G1C"]))
    assert s[0] == pytest.approx(0.22)
    assert s[1] == pytest.approx(cfg.mp_zenith_m + cfg.mp_low_m * np.exp(-50.0 / 15.0))
    # the values drawn are sigma(el) times a unit-variance state
    x = mp.values_m(np.array(["E05"] * 1), np.array(["1C"]), np.array([10.0]), 0.0)
    assert abs(x[0]) < 0.4 * 6
    with pytest.raises(ValueError, match="'G1C'.*>= 0"):
        ReceiverConfig(profile="geodetic", code_multipath_m={"G1C": {"el_deg": [10.0], "sigma_m": [-0.1]}})
    with pytest.raises(ValueError, match="code_multipath_m"):
        ReceiverConfig(profile="geodetic", code_multipath_m={"G1C": {"el_deg": [30.0, 20.0], "sigma_m": [1, 2]}})


# ---------------------------------------------------------------- noise from the loop parameters
def test_loop_parameters_are_receiver_fields_with_the_old_defaults():
    cfg = ReceiverConfig(profile={"G": ["1C"]})
    # the DLL's integration time; the PLL's loop is the tracking's (its carrier noise and its cycle slips)
    assert (cfg.dll_t_int_s, cfg.tracking.pll_bn_hz, cfg.tracking.pll_t_int_s) == (0.02, 15.0, 0.001)
    with pytest.raises(ValueError, match="dll_t_int_s"):
        ReceiverConfig(profile={"G": ["1C"]}, dll_t_int_s=0.0)


def test_dll_noise_with_a_finite_front_end():
    # physics-anchors.md (Kaplan eq. 5.23, B_n = 1 Hz, D = 0.5, T = 20 ms): 1.5 m at 40 dB-Hz, 0.46 m at 50;
    # a front end wide enough (b = 20 chip rates >= pi / D) leaves them unchanged
    for cn0, want in ((40.0, 1.5), (50.0, 0.46)):
        assert noise.dll_sigma_m(cn0, 293.05, 1.0, 0.5, 0.02, 20.0) == pytest.approx(want, rel=0.03)
    # the narrow correlator's gain stops at D = 1 / b: below it the spacing no longer matters
    b = 16e6 / 1.023e6
    s = [noise.dll_sigma_m(45.0, 293.05, 0.25, d, 0.02, b) for d in (0.02, 0.05, 1.0 / b, 0.1, np.pi / b, 0.5)]
    assert s[0] == pytest.approx(s[1]) and s[1] == pytest.approx(s[2], rel=1e-6)
    assert s[2] < s[3] < s[4] < s[5]
    # continuous at D = pi / b (both sides)
    assert noise.dll_sigma_m(45.0, 293.05, 0.25, np.pi / b * (1 - 1e-9), 0.02, b) == pytest.approx(
        noise.dll_sigma_m(45.0, 293.05, 0.25, np.pi / b, 0.02, b), rel=1e-6)
    # 10.23 Mchip/s behind 16 MHz: b = 1.56, any spacing <= 0.64 chip gives the 1/b noise
    assert noise.dll_sigma_m(45.0, 29.3, 0.25, 0.1, 0.02, 16e6 / 10.23e6) == pytest.approx(
        noise.dll_sigma_m(45.0, 29.3, 0.25, 0.5, 0.02, 16e6 / 10.23e6))
    # BOC(1,1)-family codes: 1/sqrt(3) of BPSK of the same chip rate
    assert noise.code_sigma_m("E", "1C", 45.0) == pytest.approx(noise.code_sigma_m("G", "1C", 45.0) / np.sqrt(3))


def _epochs(cfg: ReceiverConfig, n: int = 40):
    """The receiver's observations of four GPS satellites on exact circular orbits, every 30 s."""
    rcv = Receiver(cfg)
    for k in range(n):
        t = GnssTime(1_300_000_000 + 30 * k, 0.0)
        pos, vel, acc = ORB.ecef(np.full(4, 30.0 * k))
        m = len(pos)
        st = SatelliteStates(t=t, sv=np.array(["G01", "G02", "G03", "G04"]), pos_ecef_m=pos, vel_ecef_mps=vel,
                             acc_ecef_mps2=acc, clock_bias_s=np.zeros(m), clock_drift_sps=np.zeros(m),
                             relativistic_s=np.zeros(m), tgd_s=np.zeros(m), health=np.zeros(m, dtype=int),
                             iode=np.zeros(m, dtype=int), age_s=np.zeros(m), glo_channel=np.zeros(m, dtype=int),
                             source="synthetic")
        yield rcv.epoch(t, RX, st)


def test_receiver_code_noise_follows_its_dll_bandwidth():
    """The engine takes the profile's loop parameters: quartering B_n halves the code thermal noise."""

    def code_minus_phase(bn):
        cfg = ReceiverConfig(profile={"G": ["1C"]}, antenna="choke_ring", dll_bn_hz=bn, mp_zenith_m=0.0,
                             mp_low_m=0.0, seed=3, elevation_mask_deg=0.0, cn0_noise_db=0.0)
        out = [o.pseudorange_m - o.carrier_phase_cyc * 299792458.0 / 1575.42e6 - 2 * o.iono_model_m
               for o in _epochs(cfg)]
        d = np.diff(np.array(out), axis=0)           # epoch differences: the constant ambiguity drops out
        d = d[np.isfinite(d)]
        return 1.4826 * np.median(np.abs(d - np.median(d)))      # robust: a cycle slip is an outlier

    lo, hi = code_minus_phase(0.25), code_minus_phase(1.0)
    assert hi > 0.05 and lo / hi == pytest.approx(0.5, rel=0.2), (lo, hi)


def test_cn0_scatter_grows_with_the_multipath_and_has_the_receivers_resolution():
    cfg = ReceiverConfig(profile="geodetic")
    mp = CodeMultipath(cfg, np.random.default_rng(0))
    f = mp.fading_scale(np.array([90.0, 15.0, 5.0]))
    # the choke ring's envelope sigma_mp(el) / sigma_mp(90): 1 at the zenith, x4.2 at 15 deg, x7.3 at 5 deg
    env = 0.05 + 0.45 * np.exp(-np.array([6.0, 1.0, 1.0 / 3.0]))
    np.testing.assert_allclose(f, env / env[0], rtol=1e-9)
    assert f[1] == pytest.approx(4.2, abs=0.05) and f[2] == pytest.approx(7.3, abs=0.05)
    # the output resolution: 0.25 dB steps (a Septentrio SBF record), whole dB-Hz (u-blox UBX-RXM-RAWX)
    for res in (0.25, 1.0):
        cfg = ReceiverConfig(profile={"G": ["1C"]}, antenna="choke_ring", cn0_resolution_db=res, seed=3,
                             elevation_mask_deg=0.0)
        cn0 = np.concatenate([o.cn0_dbhz for o in _epochs(cfg, 5)])
        assert len(cn0) and np.all(np.abs(cn0 / res - np.round(cn0 / res)) < 1e-9)
    with pytest.raises(ValueError, match="cn0_resolution_db"):
        ReceiverConfig(profile={"G": ["1C"]}, cn0_resolution_db=-0.25)
