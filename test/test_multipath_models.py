"""Multipath models against published closed forms and a canyon computed by hand."""
from __future__ import annotations

import numpy as np
import pytest
from multipath_scenes import canyon_scene

from gnss_sim_ros2.core.multipath import antenna, dll, fresnel
from gnss_sim_ros2.core.multipath.reflections import Facets, find_paths


# ---------------------------------------------------------------- ITU-R P.2040 / Fresnel
def test_p2040_concrete_at_l1():
    # P.2040-3 table 3: concrete a = 5.24, b = 0, c = 0.0462, d = 0.7822 -> sigma(1.57542 GHz)
    m = fresnel.material("concrete")
    sigma = 0.0462 * 1.57542 ** 0.7822
    assert m.conductivity_spm() == pytest.approx(sigma, rel=1e-12)
    eta = m.permittivity()
    assert eta.real == pytest.approx(5.24)
    assert -eta.imag == pytest.approx(17.98 * sigma / 1.57542, rel=1e-12)


def test_every_material_of_the_issue_is_in_the_table():
    for name in ("concrete", "brick", "glass", "metal", "wood", "ground"):
        eta = fresnel.material(name).permittivity()
        assert eta.real >= 1.0 and eta.imag <= 0.0
    with pytest.raises(ValueError, match="marble"):
        fresnel.material("marble")


def test_normal_incidence_closed_form_and_all_lhcp():
    for name in ("concrete", "glass", "brick", "wood", "ground"):
        eta = fresnel.material(name).permittivity()
        co, cross = fresnel.circular_coefficients(eta, 0.0)
        # |Gamma| at normal incidence = |(1 - sqrt(eta)) / (1 + sqrt(eta))| (both polarisations)
        expect = abs((1 - np.sqrt(eta)) / (1 + np.sqrt(eta)))
        assert abs(cross) == pytest.approx(expect, rel=1e-9)
        assert abs(co) < 1e-12


def test_grazing_incidence_stays_rhcp_and_passivity():
    inc = np.linspace(0.0, 89.99, 500)
    for name in fresnel.MATERIALS:
        eta = fresnel.material(name).permittivity()
        co, cross = fresnel.circular_coefficients(eta, inc)
        te, tm = fresnel.fresnel_te_tm(eta, inc)
        assert np.all(np.abs(te) <= 1 + 1e-9) and np.all(np.abs(tm) <= 1 + 1e-9)
        if name != "metal":          # a conductor reverses the handedness at every angle (next test)
            assert abs(co[-1]) > 0.99 and abs(cross[-1]) < 0.01


def test_brewster_angle_of_glass_is_where_co_equals_cross():
    # a lossless glass (eta' = 6.31): R_TM vanishes at arctan(sqrt(6.31)) = 68.3 deg from the normal
    theta_b = fresnel.brewster_deg(6.31)
    assert theta_b == pytest.approx(68.29, abs=0.01)
    _, tm = fresnel.fresnel_te_tm(6.31 + 0j, theta_b)
    assert abs(tm) < 1e-9
    co, cross = fresnel.circular_coefficients(6.31 + 0j, [theta_b - 20, theta_b, theta_b + 15])
    assert abs(abs(co[1]) - abs(cross[1])) < 1e-9
    assert abs(cross[0]) > abs(co[0]) and abs(co[2]) > abs(cross[2])   # LHCP above the Brewster elevation


def test_metal_reflects_everything_into_lhcp():
    eta = fresnel.material("metal").permittivity()
    co, cross = fresnel.circular_coefficients(eta, np.array([0.0, 30.0, 60.0]))
    assert np.all(np.abs(cross) > 0.999) and np.all(np.abs(co) < 0.01)


def test_class_names_map_to_materials():
    assert fresnel.material_for_class("office_glass") == "glass"
    assert fresnel.material_for_class("opaque") == fresnel.DEFAULT_MATERIAL


# ---------------------------------------------------------------- antenna
def test_antennas_reject_lhcp_and_signals_from_below():
    el = np.array([-30.0, 0.0, 30.0, 90.0])
    for pattern in antenna.PATTERNS:
        r, lhcp = antenna.gain_dbic(pattern, el)
        assert np.all(lhcp <= r) and r[3] > r[1] > r[0]
        assert r[3] - lhcp[3] >= 15.0                          # XPD at zenith
    rc, _ = antenna.gain_dbic("choke_ring", -30.0)
    rp, _ = antenna.gain_dbic("patch", -30.0)
    assert rc < rp                                              # the choke ring rejects ground bounces more
    with pytest.raises(ValueError, match="helix"):
        antenna.gain_dbic("helix", 10.0)


# ---------------------------------------------------------------- DLL envelope
def _one_reflection(delays, amp, phase, spacing, bandwidth=np.inf):
    n = len(delays)
    a = np.c_[np.ones(n), np.full(n, amp)]
    d = np.c_[np.zeros(n), delays]
    p = np.c_[np.zeros(n), np.full(n, phase)]
    return dll.tracking_error(a, d, p, spacing, bandwidth)


@pytest.mark.parametrize("spacing", [0.1, 1.0])
@pytest.mark.parametrize("in_phase", [True, False])
def test_envelope_matches_the_analytic_one(spacing, in_phase):
    """Tolerance 1e-6 chips (bisection to 2^-40 of the bracket) at infinite bandwidth."""
    delays = np.linspace(0.0, 1.5, 151)
    eps, _, _ = _one_reflection(delays, 0.5, 0.0 if in_phase else np.pi, spacing)
    ref = dll.analytic_envelope_chips(0.5, delays, spacing, in_phase)
    assert np.max(np.abs(eps - ref)) < 1e-6
    # the published bounds: |error| <= a d / 2 ... a / (1 - a) * delta, zero beyond 1 + d/2 chips
    assert np.all(np.abs(eps[delays > 1 + spacing / 2 + 1e-9]) < 1e-9)
    assert np.max(np.abs(eps)) == pytest.approx(0.5 * spacing / 2, rel=1e-6)


def test_finite_bandwidth_rounds_the_envelope_and_converges():
    delays = np.linspace(0.0, 1.5, 61)
    ref = dll.analytic_envelope_chips(0.5, delays, 1.0, True)
    wide, _, _ = _one_reflection(delays, 0.5, 0.0, 1.0, bandwidth=30.0)
    narrow, _, _ = _one_reflection(delays, 0.5, 0.0, 1.0, bandwidth=2.0)
    assert np.max(np.abs(wide - ref)) < 0.02                   # 30 chip rates: close to the ideal triangle
    assert np.max(np.abs(narrow - ref)) > 0.03                 # 2 chip rates: rounded
    # a narrow correlator is useless behind a narrow front end (Van Dierendonck 1992)
    n01, _, _ = _one_reflection(delays, 0.5, 0.0, 0.1, bandwidth=2.0)
    assert np.max(np.abs(n01)) > 3 * 0.5 * 0.1 / 2


def test_composite_phase_and_amplitude():
    # quadrature reflection at zero delay: phase atan(a), amplitude sqrt(1 + a^2)
    eps, theta, mag = _one_reflection(np.array([0.0]), 0.5, np.pi / 2, 0.5)
    assert theta[0] == pytest.approx(np.arctan(0.5), abs=1e-9)
    assert mag[0] == pytest.approx(np.hypot(1.0, 0.5), abs=1e-9)
    # no line of sight: the loop tracks the reflection itself
    eps, _, mag = dll.tracking_error(np.array([[0.0, 0.3]]), np.array([[0.0, 0.4]]), np.array([[0.0, 1.0]]), 0.5)
    assert eps[0] == pytest.approx(0.4, abs=1e-9) and mag[0] == pytest.approx(0.3, abs=1e-9)
    with pytest.raises(ValueError, match="spacing"):
        dll.tracking_error([[1.0]], [[0.0]], [[0.0]], 0.0)


# ---------------------------------------------------------------- two-wall canyon
def test_two_wall_canyon_excess_delay_by_hand():
    scene = canyon_scene()
    facets = Facets(scene.world)
    antenna_m = np.array([0.0, 0.0, 2.0])
    el = np.radians(30.0)
    u = np.array([np.cos(el), 0.0, np.sin(el)])             # satellite due east at 30 deg
    # line of sight: meets the east wall at z = 2 + 10 tan 30 = 7.8 m < 10 m: blocked
    assert scene.rays.occluded(antenna_m, u, tnear_m=1e-3)[0]
    paths = find_paths(scene, facets, antenna_m[None], u[None, None], max_range_m=50.0)
    ok = paths.valid[0, 0]
    assert ok.sum() == 1                                     # the ground bounce at x = 3.5 is blocked by the east wall
    # by hand: mirror image of the antenna in the west wall at x = -10; the reflection point on the wall is
    # R = (-5, 0, 2 + 5 tan 30); excess = |AR| + (A - R).u  = 2 d cos(el), d = 5 m
    r = np.array([-5.0, 0.0, 2.0 + 5.0 * np.tan(el)])
    by_hand = np.linalg.norm(r - antenna_m) + (antenna_m - r) @ u
    assert by_hand == pytest.approx(2 * 5.0 * np.cos(el), abs=1e-12)
    assert paths.excess_m[0, 0][ok][0] == pytest.approx(by_hand, abs=1e-6)
    # it arrives from the wall: elevation atan(2.887 / 5) = 30 deg, from the west
    assert paths.arrival_el_deg[0, 0][ok][0] == pytest.approx(30.0, abs=1e-6)
    # concrete (the default class) at 30 deg incidence from the normal (u.n = cos 30)
    co, cross = fresnel.circular_coefficients(fresnel.material("concrete").permittivity(), 30.0)
    assert abs(paths.gamma_cross[0, 0][ok][0]) == pytest.approx(abs(cross), rel=1e-9)


def test_open_sky_ground_bounce_and_nothing_in_range():
    scene = canyon_scene()
    facets = Facets(scene.world)
    antenna_m = np.array([0.0, 100.0, 1.5])
    el = np.radians(40.0)
    u = np.array([0.0, np.cos(el), np.sin(el)])             # due north, along the street: only the ground
    paths = find_paths(scene, facets, antenna_m[None], u[None, None], max_range_m=50.0)
    ok = paths.valid[0, 0]
    assert ok.sum() == 1
    assert paths.excess_m[0, 0][ok][0] == pytest.approx(2 * 1.5 * np.sin(el), abs=1e-6)
    assert paths.arrival_el_deg[0, 0][ok][0] == pytest.approx(-40.0, abs=1e-6)
    # ground class: medium dry ground, P.2040
    assert set(facets.material_name) == {"concrete", "ground"}
    far = find_paths(scene, facets, np.array([[0.0, 0.0, 500.0]]), u[None, None], max_range_m=50.0)
    assert not far.valid.any() and far.rays_cast == 0


# ---------------------------------------------------------------- knife-edge diffraction
def test_roof_edge_diffraction_by_hand():
    from gnss_sim_ros2.core.constants import C_MPS, F_L1_HZ
    from gnss_sim_ros2.core.multipath.diffraction import edge_loss_db, knife_edge_db

    scene = canyon_scene()
    antenna_m = np.array([0.0, 0.0, 2.0])
    el = np.arctan2(7.0, 10.0)                        # the ray meets the east wall (x = 10) at z = 9, 1 m below its top
    u = np.array([np.cos(el), 0.0, np.sin(el)])
    loss, nu, _ = edge_loss_db(scene.rays, antenna_m, u[None], C_MPS / F_L1_HZ, iterations=20)
    # by hand: the edge (10, 0, 10) at 12.81 m, seen 3.67 deg above the ray: h = |AE| sin(theta)
    edge = np.array([10.0, 0.0, 10.0]) - antenna_m
    theta = np.arctan2(8.0, 10.0) - el
    h = np.linalg.norm(edge) * np.sin(theta)
    nu_hand = h * np.sqrt(2.0 / (C_MPS / F_L1_HZ * np.linalg.norm(edge)))
    assert nu[0] == pytest.approx(nu_hand, rel=0.01)
    assert loss[0] == pytest.approx(float(knife_edge_db(nu_hand)), abs=0.1)
    assert 11.0 < loss[0] < 13.5
    # P.526 eq. (31) anchors: 6.0 dB at grazing (nu = 0), 0 below nu = -0.78
    assert float(knife_edge_db(0.0)) == pytest.approx(6.03, abs=0.01)
    assert float(knife_edge_db(-1.0)) == 0.0
    # deep behind the wall (nothing clear within 15 deg above): no edge
    deep = np.array([np.cos(0.2), 0.0, np.sin(0.2)])
    loss2, _, _ = edge_loss_db(scene.rays, np.array([0.0, 0.0, 2.0]), deep[None], C_MPS / F_L1_HZ, max_angle_deg=2.0)
    assert np.isnan(loss2[0])


def test_double_bounce_between_the_canyon_walls_by_hand():
    scene = canyon_scene()
    facets = Facets(scene.world)
    antenna_m = np.array([0.0, 0.0, 2.0])
    el = np.radians(30.0)
    u = np.array([np.cos(el), 0.0, np.sin(el)])
    single = find_paths(scene, facets, antenna_m[None], u[None, None], max_range_m=50.0)
    both = find_paths(scene, facets, antenna_m[None], u[None, None], max_range_m=50.0, bounces=2)
    assert single.valid.sum() == 1 and both.valid.sum() == 2
    ex = np.sort(both.excess_m[0, 0][both.valid[0, 0]])
    # satellite -> west wall (x = -5) -> east wall (x = 10) -> antenna: image of the antenna in the east wall at
    # x = 20, its image in the west wall at x = -30: excess = 30 cos(el); by the points: R2 = (-5, 0, 2 + 25 tan 30)
    # (below the 20 m top), R1 = (10, 0, 7.77) (below the 10 m top)
    r2 = np.array([-5.0, 0.0, 2.0 + 25.0 * np.tan(el)])
    r1 = r2 + 0.6 * (np.array([20.0, 0.0, 2.0]) - r2)
    by_hand = np.linalg.norm(r1 - antenna_m) + np.linalg.norm(r2 - r1) + (antenna_m - r2) @ u
    assert by_hand == pytest.approx(30.0 * np.cos(el), abs=1e-9)
    assert ex[0] == pytest.approx(10.0 * np.cos(el), abs=1e-6) and ex[1] == pytest.approx(by_hand, abs=1e-6)
    k = int(np.nanargmax(both.excess_m[0, 0]))
    # two bounces: mostly back to RHCP at these incidences (co co + x x)
    co, x = fresnel.circular_coefficients(fresnel.material("concrete").permittivity(), 30.0)
    assert both.gamma_co[0, 0, k] == pytest.approx(co * co + x * x, abs=1e-9)
    with pytest.raises(ValueError, match="bounces"):
        find_paths(scene, facets, antenna_m[None], u[None, None], bounces=3)


def test_bandlimited_correlation_closed_form_matches_the_integral():
    # R_B(tau) = int_{-B/2}^{B/2} sinc^2(f) cos(2 pi f tau) df / R_B(0), by quadrature at B = 2 chip rates
    f = np.linspace(-1.0, 1.0, 200001)
    w = np.sinc(f) ** 2
    tau = np.array([0.0, 0.25, 0.5, 1.0, 1.5])
    quad = np.array([np.trapezoid(w * np.cos(2 * np.pi * f * t), f) for t in tau])
    np.testing.assert_allclose(dll.correlation(tau, 2.0), quad / quad[0], atol=1e-5)
    np.testing.assert_allclose(dll.correlation(tau, 400.0), np.maximum(1 - np.abs(tau), 0), atol=3e-3)


# ---------------------------------------------------------------- diffuse scattering (effective roughness)
def _wall_scene():
    """One 20 x 20 m wall in the plane y = 10 facing the antenna at the origin (normal -y)."""
    from gnss_sim_ros2.core.scene.materials import MaterialTable
    from gnss_sim_ros2.core.scene.visibility import Scene
    from gnss_sim_ros2.core.scene.world_mesh import WorldMesh

    v = np.array([[-10.0, 10.0, -10.0], [10.0, 10.0, -10.0], [10.0, 10.0, 10.0], [-10.0, 10.0, 10.0]])
    t = np.array([[0, 1, 2], [0, 2, 3]])
    return Scene(WorldMesh(v, t, np.zeros(2, np.int16), MaterialTable()))


def test_a_lit_wall_scatters_s2_cos_theta_i_times_its_solid_angle_over_pi():
    from gnss_sim_ros2.core.multipath import scattering

    scene = _wall_scene()
    el = np.radians(30.0)
    u = np.array([[0.0, -np.cos(el), np.sin(el)]])         # behind the antenna: the wall faces the satellite
    s_idx, power, excess, arr_el, rays = scattering.lit_tiles(scene, Facets(scene.world), np.zeros(3), u)
    # on-axis rectangle of half-sides a = b at distance h: solid angle 4 asin(a b / sqrt((a^2+h^2)(b^2+h^2)))
    omega = 4.0 * np.arcsin(100.0 / 200.0)
    expected = scattering.S_WALL ** 2 * np.cos(np.radians(30.0)) * omega / np.pi
    print(f"{len(power)} tiles, scattered power {power.sum():.5f} against {expected:.5f}, {rays} rays")
    assert power.sum() == pytest.approx(expected, rel=0.03)
    assert np.all(s_idx == 0) and rays == 2 * len(power)
    # excess of each tile: |P - A| - (P - A).u >= 0; the wall's nearest point (0, 10, 0): 10 + 10 cos(30 deg)
    assert np.all(excess > 0)
    assert excess.min() == pytest.approx(10.0 + 10.0 * np.cos(el), abs=1.5)
    assert np.all(np.abs(arr_el) < 45.0 + 1e-9)
    # the satellite behind the wall lights its back only: nothing scattered to the antenna
    _, p2, _, _, _ = scattering.lit_tiles(scene, Facets(scene.world), np.zeros(3), -u)
    assert len(p2) == 0


def test_scattered_paths_of_a_blocked_satellite_in_the_canyon():
    from gnss_sim_ros2.core.multipath import scattering

    scene = canyon_scene()
    el = np.radians(40.0)
    u = np.array([[[np.cos(el), 0.0, np.sin(el)], [-np.cos(el), 0.0, np.sin(el)]]])   # east, west
    a = np.array([[0.0, 0.0, 2.0]])
    paths = scattering.scatter_paths(scene, Facets(scene.world), a, u, 0.19, paths=3)
    assert paths.valid[0].any(axis=1).all()                # both satellites light a wall the antenna sees
    amp = np.sqrt(np.abs(paths.gamma_co) ** 2 + np.abs(paths.gamma_cross) ** 2)[paths.valid]
    assert np.all(amp < 0.5) and np.all(paths.excess_m[paths.valid] > 0)
    assert paths.rays_cast > 0
