"""What the receiver makes of reflected paths: NLOS tracking, envelope code error, composite C/N0, profiles."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gnss_sim_ros2.core import constants as k
from gnss_sim_ros2.core.ephemeris.provider import open_ephemeris
from gnss_sim_ros2.core.multipath import dll
from gnss_sim_ros2.core.multipath.composite import reflection_amplitudes
from gnss_sim_ros2.core.multipath.reflections import ScenePaths
from gnss_sim_ros2.core.receiver.config import ReceiverConfig
from gnss_sim_ros2.core.receiver.engine import Receiver
from gnss_sim_ros2.core.time import GnssTime
from gnss_sim_ros2.core.vocabulary import VisibilityState

RX = np.array([-2418000.0, 5385000.0, 2405000.0])     # near Hong Kong
T0 = GnssTime.from_iso("2019-04-28T05:00:00")


@pytest.fixture(scope="module")
def provider(tmp_path_factory):
    prov, _ = open_ephemeris("synthetic", T0, 300.0, "GC", workdir=tmp_path_factory.mktemp("eph"))
    return prov


def _paths(n, rows, excess_m, amp_cross, el_deg):
    p = ScenePaths.empty(1, n, 2)
    p = p.take(0)
    for r in rows:
        p.excess_m[r, 0] = excess_m
        p.gamma_cross[r, 0] = amp_cross
        p.arrival_el_deg[r, 0] = el_deg[r]
    return p


def _rx(profile="ublox_m8t", **kw):
    return Receiver(ReceiverConfig(profile=profile, systems="GC", noise=False, **kw))


def test_nlos_only_pseudorange_carries_the_excess_delay_and_weaker_cn0(provider):
    st = provider.states(T0, systems="GC")
    a = _rx()
    ref = a.epoch(T0, RX, st)
    el = ref.sat_el_deg
    row = int(np.argmax(el))                       # the highest satellite
    sv = ref.sat_sv[row]
    srow = int(np.flatnonzero(np.asarray(st.sv) == sv)[0])
    vis = np.zeros(len(st), np.int64)
    vis[srow] = int(VisibilityState.REFLECTED_ONLY)
    from gnss_sim_ros2.core.frames import az_el_from_ecef

    _, el_all, _ = az_el_from_ecef(RX, st.pos_ecef_m)
    paths = _paths(len(st), [srow], 37.5, 0.6, el_all)
    b = _rx()
    obs = b.epoch(T0, RX, st, vis, np.zeros(len(st)), multipath=paths)
    j_ref = np.flatnonzero(ref.sv == sv)[0]
    j = np.flatnonzero(obs.sv == sv)[0]
    assert obs.pseudorange_m[j] - ref.pseudorange_m[j_ref] == pytest.approx(37.5, abs=1e-3)
    # carrier phase follows the reflected path (excess + coefficient phase within half a wavelength)
    lam = k.C_MPS / obs.frequency_hz[j]
    dphi_m = (obs.carrier_phase_cyc[j] - ref.carrier_phase_cyc[j_ref]) * lam
    assert abs(dphi_m - 37.5) <= lam / 2 + 1e-6
    amp, _ = reflection_amplitudes(np.array([0j]), np.array([0.6 + 0j]), np.array([el_all[srow]]),
                                   np.array(el_all[srow]), "patch")
    # both C/N0 are reported in the profile's steps (cn0_resolution_db: 0.25 dB for the geodetic profile)
    step_db = b.cfg.cn0_resolution_db
    assert obs.cn0_dbhz[j] - ref.cn0_dbhz[j_ref] == pytest.approx(20 * np.log10(amp[0]), abs=step_db + 1e-6)
    assert obs.cn0_dbhz[j] < ref.cn0_dbhz[j_ref] - 10       # LHCP rejection of the patch + |Gamma|
    others = ref.sv != sv
    np.testing.assert_allclose(obs.pseudorange_m[obs.sv != sv], ref.pseudorange_m[others], atol=1e-9)
    # REFLECTED_ONLY without paths (a caller with the state only): not tracked
    c = _rx()
    obs_c = c.epoch(T0, RX, st, vis, np.zeros(len(st)))
    assert sv not in set(obs_c.sv)


def test_los_plus_reflection_code_error_is_the_envelope(provider):
    st = provider.states(T0, systems="G")
    from gnss_sim_ros2.core.frames import az_el_from_ecef

    _, el_all, _ = az_el_from_ecef(RX, st.pos_ecef_m)
    srow = int(np.argmax(el_all))
    excess = 0.3 * k.C_MPS / 1.023e6                       # 0.3 C/A chips
    paths = _paths(len(st), [srow], excess, 0.9, el_all)
    a, b = _rx(), _rx()
    r0 = a.epoch(T0, RX, st)
    r1 = b.epoch(T0, RX, st, np.zeros(len(st), np.int64), np.zeros(len(st)), multipath=paths)
    sv = st.sv[srow]
    d_code = r1.pseudorange_m[r1.sv == sv][0] - r0.pseudorange_m[r0.sv == sv][0]
    amp, ph = reflection_amplitudes(np.array([0j]), np.array([0.9 + 0j]), np.array([el_all[srow]]),
                                    np.array(el_all[srow]), "patch")
    lam = k.C_MPS / k.F_L1_HZ
    phase = ph[0] + 2 * np.pi * excess / lam
    cfg = b.cfg
    eps, _, _ = dll.tracking_error([[1.0, amp[0]]], [[0.0, 0.3]], [[0.0, phase]], cfg.dll_spacing_chips,
                                   cfg.frontend_bandwidth_hz / 1.023e6)
    assert d_code == pytest.approx(eps[0] * k.C_MPS / 1.023e6, abs=1e-6)
    assert abs(d_code) > 0.01


def test_hysteresis_keeps_a_weak_reflection_only_once_tracked(provider):
    st = provider.states(T0, systems="G")
    from gnss_sim_ros2.core.frames import az_el_from_ecef

    _, el_all, _ = az_el_from_ecef(RX, st.pos_ecef_m)
    srow = int(np.argmax(el_all))
    sv = st.sv[srow]
    probe = _rx()
    free = probe.epoch(T0, RX, st).cn0_dbhz
    cn0_free = free[probe.epoch(T0 + 1.0, RX, st).sv == sv][0]
    tr = probe.cfg.tracking
    target = 0.5 * (tr.acquisition_cn0_dbhz + tr.tracking_cn0_dbhz)   # between the two thresholds
    unit, _ = reflection_amplitudes(np.array([0j]), np.array([1.0 + 0j]), np.array([el_all[srow]]),
                                    np.array(el_all[srow]), "patch")
    g = 10 ** ((target - cn0_free) / 20) / unit[0]
    assert 0 < g < 1
    vis = np.zeros(len(st), np.int64)
    vis[srow] = int(VisibilityState.REFLECTED_ONLY)
    paths = _paths(len(st), [srow], 20.0, g, el_all)
    kept = _rx()
    kept.epoch(T0, RX, st)                                               # acquired in line of sight
    obs = kept.epoch(T0 + 1.0, RX, st, vis, np.zeros(len(st)), multipath=paths)
    assert sv in set(obs.sv)
    # a receiver switched on now (a cold start: a warm one finds every signal above the loss threshold locked)
    tracking = dataclasses.replace(probe.cfg.tracking, start="cold")
    fresh = _rx(tracking=tracking)
    obs = fresh.epoch(T0, RX, st, vis, np.zeros(len(st)), multipath=paths)
    assert sv not in set(obs.sv)                                        # too weak to acquire


def test_profiles_f9p_drops_beidou_geo_and_m8t_is_single_frequency(provider):
    st = provider.states(T0, systems="GC")
    geo = {s for s in st.sv if s in {"C01", "C02", "C03", "C04", "C05", "C59", "C60", "C61"}}
    assert geo, "the synthetic constellation has BeiDou GEOs"
    f9p = Receiver(ReceiverConfig(profile="ublox_f9p", systems="GC", noise=False)).epoch(T0, RX, st)
    assert not geo & set(f9p.sv)
    assert set(f9p.code[np.char.startswith(f9p.sv.astype(str), "G")]) == {"1C", "2L"}
    m8t = Receiver(ReceiverConfig(profile="ublox_m8t", systems="GC", noise=False)).epoch(T0, RX, st)
    assert geo & set(m8t.sv)
    assert set(m8t.code) == {"1C", "2I"}
    cfg = ReceiverConfig(profile="ublox_m8t")
    assert (cfg.dll_spacing_chips, cfg.antenna, cfg.tracking.acquisition_cn0_dbhz) == (0.5, "patch", 22.0)
    geod = ReceiverConfig(profile="geodetic")
    # the geodetic profile's narrow correlator and 0.25 Hz DLL (profiles/geodetic.yaml, issue 26); its acquisition
    # threshold where the PolaRx5 of ESBC starts its tracks (issue 27, test_geodetic_thresholds)
    assert (geod.dll_spacing_chips, geod.dll_bn_hz, geod.tracking.acquisition_cn0_dbhz) == (0.1, 0.25, 20.5)
    with pytest.raises(ValueError, match="antenna"):
        ReceiverConfig(antenna="dipole")
