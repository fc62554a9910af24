"""Jamming through the one receiver chain (core/threats): the C/N0 drop of each signal against the closed form
computed here from the ICD spectra (not by the simulator's functions), a wall's loss, loss of lock and the fix."""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.frames import ecef_to_geodetic, enu_to_ecef
from gnss_sim_ros2.core.multipath.antenna import rhcp_gain_dbic
from gnss_sim_ros2.core.scene.georeference import SphericalCoordinates
from gnss_sim_ros2.core.scene.materials import MaterialTable
from gnss_sim_ros2.core.scene.visibility import Scene
from gnss_sim_ros2.core.scene.world_mesh import WorldMesh
from gnss_sim_ros2.core.simulation import run_simulation, setup_from_config
from gnss_sim_ros2.core.trajectory import Trajectory

LAT, LON, H = 50.0758, 14.4179, 250.0
F_L1 = 1575.42e6
K_BOLTZMANN, T_SYS = 1.380649e-23, 290.0          # CODATA 2018; the link budget's reference noise temperature
D_M = 200.0                                       # jammer 200 m east of the antenna, at its height (elevation 0)
CHOKE_RING_FRONT_END_HZ = 16.0e6                  # geodetic profile: choke ring antenna, 16 MHz front end


# ---------------------------------------------------------------- the closed form, from the ICD spectra
def _bpsk(fc):
    return lambda f: np.sinc(f / fc) ** 2 / fc                    # sin(pi x)/(pi x), unit power


def _sine_boc(fs, fc):
    """Sine BOC(fs, fc), 2 fs / fc even (Betz 2001, Navigation 48(4), eq. 6), unit power."""
    def g(f):
        f = np.where(f == 0.0, 1e-3, f)
        return fc * (np.sin(np.pi * f / fc) * np.tan(np.pi * f / (2 * fs)) / (np.pi * f)) ** 2
    return g


def _mboc(f):
    """MBOC(6,1,1/11) (Galileo OS SIS ICD 2.3.3: CBOC on E1-B + E1-C): 10/11 BOC(1,1) + 1/11 BOC(6,1)."""
    return 10 / 11 * _sine_boc(1.023e6, 1.023e6)(f) + 1 / 11 * _sine_boc(6.138e6, 1.023e6)(f)


#: (system, RINEX code) -> PSD: IS-GPS-200 (C/A, P(Y) and L2C BPSK), IS-GPS-705 (L5 BPSK(10)), Galileo OS SIS ICD
#: (E1 CBOC, E5a/E5b BPSK(10)), E6 SIS ICD (BPSK(5)); E5 AltBOC(15,10) has its first nulls 25.6 MHz out: outside
SPECTRUM = {("G", "1C"): _bpsk(1.023e6), ("G", "2W"): _bpsk(10.23e6), ("G", "2L"): _bpsk(1.023e6),
            ("G", "5Q"): _bpsk(10.23e6), ("E", "1C"): _mboc, ("E", "5Q"): _bpsk(10.23e6),
            ("E", "7Q"): _bpsk(10.23e6), ("E", "6C"): _bpsk(5.115e6)}


def _kappa(system, code, carrier_hz, center_hz, bandwidth_hz, fe_hz=CHOKE_RING_FRONT_END_HZ):
    """Betz (ION NTM 2001): kappa = int G_s G_j df over the front end, both of unit power there."""
    f = np.linspace(-fe_hz / 2, fe_hz / 2, 400_001)
    if system == "E" and code == "8Q":
        return 0.0                                      # a jammer at L1 is 400 MHz away
    g = SPECTRUM[(system, code)](f)
    g = g / np.trapezoid(g, f)
    df = center_hz - carrier_hz
    if bandwidth_hz == 0:
        return float(np.interp(df, f, g, left=0.0, right=0.0))
    gj = np.where(np.abs(f - df) <= bandwidth_hz / 2, 1.0 / bandwidth_hz, 0.0)
    return float(np.trapezoid(g * gj, f))


def _expected_drop_db(system, code, carrier_hz, eirp_dbw, center_hz, bandwidth_hz, extra_loss_db=0.0):
    fsl = 20 * math.log10(4 * math.pi * D_M * center_hz / 299792458.0)
    j_dbw = eirp_dbw - fsl + float(rhcp_gain_dbic("choke_ring", 0.0, carrier_hz)) - extra_loss_db
    n0 = K_BOLTZMANN * T_SYS
    return 10 * math.log10(1 + 10 ** (j_dbw / 10) * _kappa(system, code, carrier_hz, center_hz, bandwidth_hz) / n0)


# ---------------------------------------------------------------- runs
def _jammer_llh():
    x = enu_to_ecef(np.array([D_M, 0.0, 0.0]), LAT, LON, H)
    return [float(v) for v in ecef_to_geodetic(*x)]


def _scenario(tmp_path, name, position, position_type, eirp_dbw, bandwidth_hz, start_s=0.0, end_s=1e9,
              center_hz=F_L1):
    p = tmp_path / f"{name}.yaml"
    p.write_text(f"version: 1\nevents:\n  - type: jammer\n    name: {name}\n    position: {list(position)}\n"
                 f"    position_type: {position_type}\n    eirp_dbw: {eirp_dbw}\n    center_hz: {center_hz}\n"
                 f"    bandwidth_hz: {bandwidth_hz}\n    start_s: {start_s}\n    end_s: {end_s}\n")
    return str(p)


def _run(tmp_path, name, scenario="", trajectory=None, scene=None, duration_s=3.0, profile="geodetic",
         systems="GE"):
    last = {}                 # the last epoch's signals: (sv, code) -> (C/N0 [dB-Hz], carrier [Hz])

    def observer(t, ecef, obs, sol):
        last.clear()
        last.update({(sv, code): (c, f) for sv, code, c, f in zip(obs.sv.tolist(), obs.code.tolist(),
                                                                 obs.cn0_dbhz.tolist(), obs.frequency_hz.tolist())})

    cfg = load_config(overrides={"/**": {"systems": systems}, "receiver": {"noise": False, "profile": profile,
                                                                          "scenario": scenario}})
    traj = trajectory or Trajectory.static([LAT, LON, H], "geodetic")
    setup = setup_from_config(cfg, tmp_path / name, traj, duration_s=duration_s, interval_s=1.0, scene=scene,
                              observer=observer)
    res = run_simulation(setup)
    return last, res


def _drops(base, jammed):
    """(sv, code) -> (C/N0 drop [dB], carrier [Hz]) of the signals tracked in both runs."""
    common = sorted(set(base) & set(jammed))
    assert len(common) > 20
    return {k: (base[k][0] - jammed[k][0], base[k][1]) for k in common}


@pytest.fixture(scope="module")
def open_sky(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("open")
    base, _ = _run(tmp, "base")
    return tmp, base


@pytest.mark.parametrize("bandwidth_hz", [0.0, 2.0e6])
def test_cn0_drop_of_each_signal_is_the_closed_form(open_sky, bandwidth_hz):
    tmp, base = open_sky
    eirp = -38.0
    jammed, _ = _run(tmp, f"j{bandwidth_hz:.0f}",
                     _scenario(tmp, "jam", _jammer_llh(), "llh", eirp, bandwidth_hz))
    checked = 0
    for (sv, code), (drop, carrier) in _drops(base, jammed).items():
        want = _expected_drop_db(sv[0], code, carrier, eirp, F_L1, bandwidth_hz)
        assert drop == pytest.approx(want, abs=1.0), (sv, code, drop, want)
        checked += want > 3.0
    assert checked >= 5          # the L1 signals dropped by several dB, the others untouched (both checked)


def _wall_scene(loss_db):
    mats = MaterialTable()
    wall = mats.declare("wall", loss_db / 0.5)                     # 0.5 m thick
    x0, x1, y0, y1, z0, z1 = 100.0, 100.5, -60.0, 60.0, -60.0, 60.0
    v = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], dtype=float)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                  [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    world = WorldMesh(v, f, np.full(len(f), wall, np.int16), mats, SphericalCoordinates(LAT, LON, H))
    return Scene(world)


def test_the_same_jammer_behind_a_wall_drops_cn0_less_by_the_walls_loss(tmp_path, open_sky):
    _, base_open = open_sky
    eirp, loss = -38.0, 6.0
    scene = _wall_scene(loss)
    at = Trajectory.static([0.0, 0.0, 0.0], "world")
    base, _ = _run(tmp_path, "wall_base", trajectory=at, scene=scene)
    jammed, _ = _run(tmp_path, "wall_jam", _scenario(tmp_path, "jam", [D_M, 0.0, 0.0], "world", eirp, 0.0),
                     trajectory=at, scene=scene)
    open_jammed, _ = _run(tmp_path, "open_jam", _scenario(tmp_path, "jam2", _jammer_llh(), "llh", eirp, 0.0))
    open_drop = _drops(base_open, open_jammed)
    n_l1 = 0
    for (sv, code), (drop, carrier) in _drops(base, jammed).items():
        want = _expected_drop_db(sv[0], code, carrier, eirp, F_L1, 0.0, extra_loss_db=loss)
        assert drop == pytest.approx(want, abs=1.0), (sv, code, drop, want)
        if (sv, code) in open_drop and open_drop[(sv, code)][0] > 3.0:
            assert drop < open_drop[(sv, code)][0] - 2.0
            n_l1 += 1
    assert n_l1 >= 3


def test_past_the_threshold_signals_are_lost_the_fix_goes_and_comes_back(tmp_path):
    # a single-frequency receiver, a 20 MHz wide jammer over L1/E1 from 10 s to 20 s: 1 W at 200 m
    scn = _scenario(tmp_path, "ppd", _jammer_llh(), "llh", 0.0, 20.0e6, start_s=10.0, end_s=20.0)
    _, res = _run(tmp_path, "lose", scn, duration_s=40.0, profile="single_frequency", systems="GE")
    with open(res.fix_path, newline="") as f:
        rows = list(csv.DictReader(f))
    status = [r["status"] for r in rows]
    labels = [r["active_events"] for r in rows]
    assert labels[:10] == [""] * 10 and labels[10:20] == ["ppd"] * 10 and set(labels[20:]) == {""}
    assert set(status[:10]) == {"fix"}
    assert set(status[11:20]) == {"no_fix"} and {int(r["n_sats"]) for r in rows[11:20]} == {0}
    assert status[-1] == "fix"                         # reacquired through the acquisition threshold
