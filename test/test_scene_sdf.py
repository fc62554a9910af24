"""SDF world reading: poses, includes, meshes, geometry, materials, errors, export round trip.

Expected poses and extents are worked out by hand from the SDF pose rules
(R = Rz(yaw) Ry(pitch) Rx(roll); child pose composed onto its parent frame).
"""
from __future__ import annotations

import math
import re
import textwrap
import warnings

import numpy as np
import pytest

from gnss_sim_ros2.core import frames
from gnss_sim_ros2.core.constants import FOLIAGE_ATTENUATION_DB_PER_M
from gnss_sim_ros2.core.scene.georeference import SphericalCoordinates
from gnss_sim_ros2.core.scene.loader import load_sdf_world
from gnss_sim_ros2.core.scene.mesh_io import export_world, read_scene, sidecar_path
from gnss_sim_ros2.core.scene.scene_report import SceneWarning
from gnss_sim_ros2.core.scene.sdf_xml import SdfError

HEAD = '<?xml version="1.0"?>\n<sdf version="1.9" xmlns:gnss_sim="urn:gnss_sim">\n<world name="w">\n'
TAIL = "</world>\n</sdf>\n"


def static(body: str) -> str:
    """Every model made static (only static models are obstacles; test_world_loading covers the others)."""
    return re.sub(r'(<model name="[^"]*">)', r"\1<static>true</static>", body)


def write(path, body, head=HEAD, tail=TAIL):
    path.write_text(head + static(textwrap.dedent(body)) + tail)
    return path


def part_vertices(world, name):
    """Vertices of the triangles of one part (parts are appended in order)."""
    start = 0
    for p in world.parts:
        if p["name"] == name:
            tri = world.triangles[start:start + p["triangles"]]
            return world.vertices_m[np.unique(tri)]
        start += p["triangles"]
    raise KeyError(name)


def box(size):
    return f"<geometry><box><size>{size}</size></box></geometry>"


# ------------------------------------------------------------------ poses
def test_nested_model_pose_composition(tmp_path):
    w = write(tmp_path / "w.sdf", f"""
        <model name="A">
          <pose>10 0 0 0 0 1.5707963267948966</pose>
          <model name="B">
            <pose>2 0 0 0 0 0</pose>
            <link name="L">
              <pose>0 1 0 0 0 0</pose>
              <collision name="c"><pose>0 0 0.5 0 0 0</pose>{box("1 2 3")}</collision>
            </link>
          </model>
        </model>""")
    world = load_sdf_world(w)
    v = part_vertices(world, "A::B::L::c")
    # A at (10,0,0) yawed +90 deg: B's (2,0,0) -> (10,2,0); L's (0,1,0) in the yawed frame -> (-1,0,0) -> (9,2,0)
    np.testing.assert_allclose(v.mean(axis=0), [9.0, 2.0, 0.5], atol=1e-9)
    # yaw 90 swaps the x/y extents of the 1 x 2 x 3 box
    np.testing.assert_allclose(v.max(axis=0) - v.min(axis=0), [2.0, 1.0, 3.0], atol=1e-9)


def test_relative_to_frames_and_degrees(tmp_path):
    w = write(tmp_path / "w.sdf", f"""
        <model name="M">
          <pose degrees="true">0 0 0 0 0 90</pose>
          <link name="base"><pose>1 0 0 0 0 0</pose></link>
          <frame name="F" attached_to="base"><pose>0 2 0 0 0 0</pose></frame>
          <link name="L">
            <pose relative_to="F">0 0 3 0 0 0</pose>
            <collision name="c">{box("1 1 1")}</collision>
          </link>
          <link name="K">
            <pose relative_to="__model__">5 0 0 0 0 0</pose>
            <collision name="c"><pose relative_to="base">0 0 7 0 0 0</pose>{box("1 1 1")}</collision>
          </link>
        </model>""")
    world = load_sdf_world(w)
    # model yawed 90 deg: base at model (1,0,0) -> world (0,1,0); F = base + (0,2,0)_model -> world (-2,1,0);
    # L = F + (0,0,3)
    np.testing.assert_allclose(part_vertices(world, "M::L::c").mean(axis=0), [-2.0, 1.0, 3.0], atol=1e-9)
    # collision of K posed relative to base (a sibling link), not to K
    np.testing.assert_allclose(part_vertices(world, "M::K::c").mean(axis=0), [0.0, 1.0, 7.0], atol=1e-9)


def test_quaternion_pose(tmp_path):
    s = math.sqrt(0.5)
    w = write(tmp_path / "w.sdf", f"""
        <model name="M">
          <pose rotation_format="quat_xyzw">0 0 0 0 0 {s} {s}</pose>
          <link name="L"><collision name="c"><pose>3 0 0 0 0 0</pose>{box("1 1 1")}</collision></link>
        </model>""")
    # quaternion of a +90 deg yaw: x -> y
    np.testing.assert_allclose(part_vertices(load_sdf_world(w), "M::L::c").mean(axis=0), [0, 3, 0], atol=1e-9)


# ------------------------------------------------------------------ includes and meshes
OBJ_CUBE = """v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8
"""


def make_model(root, name, body):
    d = root / name
    (d / "meshes").mkdir(parents=True)
    (d / "model.config").write_text(textwrap.dedent(f"""\
        <?xml version="1.0"?>
        <model><name>{name}</name>
          <sdf version="1.6">old.sdf</sdf>
          <sdf version="1.9">model.sdf</sdf>
        </model>"""))
    (d / "model.sdf").write_text('<?xml version="1.0"?>\n<sdf version="1.9">\n' + static(textwrap.dedent(body))
                                 + "</sdf>\n")
    return d


def test_include_model_uri_with_overrides(tmp_path, monkeypatch):
    res = tmp_path / "models"
    d = make_model(res, "kiosk", """
        <model name="kiosk">
          <pose>100 100 100 0 0 0</pose>
          <link name="L"><collision name="c">
            <geometry><mesh><uri>model://kiosk/meshes/cube.obj</uri><scale>2 3 4</scale></mesh></geometry>
          </collision></link>
        </model>""")
    (d / "meshes" / "cube.obj").write_text(OBJ_CUBE)
    monkeypatch.setenv("GZ_SIM_RESOURCE_PATH", str(res))
    monkeypatch.delenv("IGN_GAZEBO_RESOURCE_PATH", raising=False)
    monkeypatch.delenv("GAZEBO_MODEL_PATH", raising=False)
    world_dir = tmp_path / "worlds"
    world_dir.mkdir()
    w = write(world_dir / "w.sdf", """
        <include><uri>model://kiosk</uri><name>kiosk_a</name><pose>5 0 0 0 0 0</pose></include>
        <include><uri>model://kiosk</uri><name>kiosk_b</name><pose degrees="true">0 5 0 0 0 90</pose></include>
        <include><uri>model://kiosk</uri></include>""")
    world = load_sdf_world(w)
    names = [p["name"] for p in world.parts]
    assert names == ["kiosk_a::L::c", "kiosk_b::L::c", "kiosk::L::c"]
    a = part_vertices(world, "kiosk_a::L::c")
    # unit cube [0,1]^3 scaled (2,3,4), include pose replaces the model's own pose
    np.testing.assert_allclose(a.min(axis=0), [5, 0, 0], atol=1e-9)
    np.testing.assert_allclose(a.max(axis=0), [7, 3, 4], atol=1e-9)
    b = part_vertices(world, "kiosk_b::L::c")
    # yaw 90: x -> y, y -> -x
    np.testing.assert_allclose(b.min(axis=0), [-3, 5, 0], atol=1e-9)
    np.testing.assert_allclose(b.max(axis=0), [0, 7, 4], atol=1e-9)
    c = part_vertices(world, "kiosk::L::c")
    np.testing.assert_allclose(c.min(axis=0), [100, 100, 100], atol=1e-9)


def test_include_found_next_to_world_file(tmp_path, monkeypatch):
    for var in ("GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "GAZEBO_MODEL_PATH"):
        monkeypatch.delenv(var, raising=False)
    make_model(tmp_path, "shed", f'<model name="shed"><link name="L"><collision name="c">{box("1 1 1")}'
                                 f'</collision></link></model>')
    w = write(tmp_path / "w.sdf", "<include><uri>model://shed</uri></include>")
    assert [p["name"] for p in load_sdf_world(w).parts] == ["shed::L::c"]


def test_stl_and_dae_meshes(tmp_path):
    import trimesh

    cube = trimesh.creation.box(extents=(1, 1, 1))
    cube.export(tmp_path / "cube.stl")
    (tmp_path / "cube.dae").write_bytes(trimesh.exchange.dae.export_collada(cube))
    w = write(tmp_path / "w.sdf", """
        <model name="M"><link name="L">
          <collision name="stl"><pose>10 0 0 0 0 0</pose>
            <geometry><mesh><uri>cube.stl</uri><scale>1 1 2</scale></mesh></geometry></collision>
          <collision name="dae"><pose>0 10 0 0 0 0</pose>
            <geometry><mesh><uri>file://""" + str(tmp_path / "cube.dae") + """</uri></mesh></geometry></collision>
        </link></model>""")
    world = load_sdf_world(w)
    s = part_vertices(world, "M::L::stl")
    np.testing.assert_allclose([s.min(axis=0), s.max(axis=0)], [[9.5, -0.5, -1], [10.5, 0.5, 1]], atol=1e-6)
    d = part_vertices(world, "M::L::dae")
    np.testing.assert_allclose([d.min(axis=0), d.max(axis=0)], [[-0.5, 9.5, -0.5], [0.5, 10.5, 0.5]], atol=1e-6)


# ------------------------------------------------------------------ geometry
def test_primitive_geometry_extents(tmp_path):
    w = write(tmp_path / "w.sdf", """
        <model name="M"><link name="L">
          <collision name="cyl"><geometry><cylinder><radius>1</radius><length>4</length></cylinder></geometry>
          </collision>
          <collision name="sph"><geometry><sphere><radius>2</radius></sphere></geometry></collision>
          <collision name="cap"><geometry><capsule><radius>0.5</radius><length>2</length></capsule></geometry>
          </collision>
          <collision name="ell"><geometry><ellipsoid><radii>1 2 3</radii></ellipsoid></geometry></collision>
          <collision name="pla"><geometry><plane><normal>0 0 1</normal><size>20 10</size></plane></geometry></collision>
          <collision name="pol"><geometry><polyline>
            <point>0 0</point><point>4 0</point><point>4 4</point><point>2 1</point><point>0 4</point>
            <height>3</height></polyline></geometry></collision>
        </link></model>""")
    world = load_sdf_world(w)

    def ext(name):
        v = part_vertices(world, "M::L::" + name)
        return v.min(axis=0), v.max(axis=0)

    np.testing.assert_allclose(ext("cyl")[1], [1, 1, 2], atol=1e-9)
    np.testing.assert_allclose(ext("sph")[1], [2, 2, 2], atol=1e-9)
    np.testing.assert_allclose(ext("cap")[1][2], 1.5, atol=1e-9)        # half length + radius
    np.testing.assert_allclose(ext("ell")[1], [1, 2, 3], atol=1e-9)
    np.testing.assert_allclose(ext("pla")[0], [-10, -5, 0], atol=1e-9)
    np.testing.assert_allclose(ext("pla")[1], [10, 5, 0], atol=1e-9)
    np.testing.assert_allclose(ext("pol")[0], [0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(ext("pol")[1], [4, 4, 3], atol=1e-9)
    # the non-convex polyline prism is closed and holds the polygon's area x height:
    # area = 16 - triangle (0,4),(4,4),(2,1) = 16 - 6 = 10 -> volume 30
    import trimesh

    start = sum(p["triangles"] for p in world.parts[:5])
    tri = world.triangles[start:start + world.parts[5]["triangles"]]
    m = trimesh.Trimesh(world.vertices_m, tri, process=True)
    assert m.is_watertight
    assert m.volume == pytest.approx(30.0, abs=1e-9)


def test_visuals_instead_of_collisions(tmp_path):
    w = write(tmp_path / "w.sdf", f"""
        <model name="M"><link name="L">
          <collision name="c">{box("1 1 1")}</collision>
          <visual name="v"><pose>0 0 9 0 0 0</pose>{box("1 1 1")}</visual>
        </link></model>""")
    assert [p["name"] for p in load_sdf_world(w).parts] == ["M::L::c"]
    vis = load_sdf_world(w, use_visuals=True)
    assert [p["name"] for p in vis.parts] == ["M::L::v"]
    assert vis.vertices_m[:, 2].mean() == pytest.approx(9.0)


# ------------------------------------------------------------------ georeference
def test_spherical_coordinates_and_heading(tmp_path):
    w = write(tmp_path / "w.sdf", """
        <spherical_coordinates>
          <surface_model>EARTH_WGS84</surface_model>
          <latitude_deg>50.0764</latitude_deg><longitude_deg>14.4179</longitude_deg>
          <elevation>250</elevation><heading_deg>90</heading_deg>
        </spherical_coordinates>
        <model name="M"><link name="L"><collision name="c">""" + box("1 1 1") + "</collision></link></model>")
    sph = load_sdf_world(w).spherical_coordinates
    assert (sph.latitude_deg, sph.longitude_deg, sph.elevation_m, sph.heading_deg) == (50.0764, 14.4179, 250, 90)
    # gz-math ECEF->LOCAL: local = Rz(-heading) ENU, so with heading 90 the world +x axis points north
    ecef = sph.world_to_ecef(np.array([[100.0, 0, 0], [0, 100.0, 0]]))
    enu = frames.ecef_to_enu(ecef, 50.0764, 14.4179, 250)
    np.testing.assert_allclose(enu, [[0, 100, 0], [-100, 0, 0]], atol=1e-6)
    np.testing.assert_allclose(sph.ecef_to_world(ecef), [[100, 0, 0], [0, 100, 0]], atol=1e-6)


# ------------------------------------------------------------------ materials
def test_material_default_contract_tag_and_yaml(tmp_path):
    body = f"""
        <model name="Oak_Tree_3"><link name="L"><collision name="c">{box("1 1 1")}</collision></link></model>
        <model name="hall"><link name="hedge_row"><collision name="c">{box("1 1 1")}</collision></link>
          <link name="wall"><collision name="c">{box("1 1 1")}</collision></link></model>
        <model name="kiosk">
          <gnss_sim:material>foliage</gnss_sim:material>
          <link name="L"><collision name="c">{box("1 1 1")}</collision>
            <collision name="glass"><gnss_sim:material attenuation_db_per_m="4.5">glass</gnss_sim:material>
              {box("1 1 1")}</collision></link></model>
        <model name="tree_dead"><link name="L"><gnss_sim:material>opaque</gnss_sim:material>
          <collision name="c">{box("1 1 1")}</collision></link></model>
    """
    w = write(tmp_path / "w.sdf", body)
    world = load_sdf_world(w)
    cls = {p["name"]: p["class"] for p in world.parts}
    assert cls == {"Oak_Tree_3::L::c": "foliage", "hall::hedge_row::c": "foliage", "hall::wall::c": "opaque",
                   "kiosk::L::c": "foliage", "kiosk::L::glass": "glass", "tree_dead::L::c": "opaque"}
    table = {c.name: c.attenuation_db_per_m for c in world.materials.classes}
    assert table["foliage"] == FOLIAGE_ATTENUATION_DB_PER_M and table["glass"] == 4.5 and table["opaque"] is None

    y = tmp_path / "materials.yaml"
    y.write_text(textwrap.dedent("""\
        classes:
          foliage: {attenuation_db_per_m: 2.5}
          wood: {attenuation_db_per_m: null}
        rules:
          - {pattern: "hall::wall*", class: foliage}
          - {pattern: "oak_*", class: wood}
        """))
    world = load_sdf_world(w, materials_yaml=y)
    cls = {p["name"]: p["class"] for p in world.parts}
    assert cls["hall::wall::c"] == "foliage" and cls["Oak_Tree_3::L::c"] == "wood"
    assert cls["hall::hedge_row::c"] == "foliage"          # no rule matches: the default contract
    assert {c.name: c.attenuation_db_per_m for c in world.materials.classes}["foliage"] == 2.5


# ------------------------------------------------------------------ errors
def test_error_missing_mesh_names_file_line_and_uri(tmp_path):
    w = write(tmp_path / "w.sdf", """
        <model name="M"><link name="L"><collision name="c">
          <geometry><mesh><uri>meshes/missing.stl</uri></mesh></geometry>
        </collision></link></model>""")
    with pytest.raises(SdfError) as e:
        load_sdf_world(w, strict=True)
    msg = str(e.value)
    assert "w.sdf:" in msg and "<uri>" in msg and "missing.stl" in msg
    assert ":6:" in msg   # the <uri> line: 3 header lines, blank line, model line, geometry line


def test_error_unknown_model_uri(tmp_path, monkeypatch):
    monkeypatch.setenv("GZ_SIM_RESOURCE_PATH", str(tmp_path / "nowhere"))
    w = write(tmp_path / "w.sdf", "<include><uri>model://no_such_model</uri></include>")
    with pytest.raises(SdfError, match=r"model://no_such_model.*GZ_SIM_RESOURCE_PATH"):
        load_sdf_world(w, strict=True)
    w = write(tmp_path / "w2.sdf", "<include><uri>https://fuel.gazebosim.org/x</uri></include>")
    with pytest.raises(SdfError, match="network URI"):
        load_sdf_world(w, strict=True)


def test_error_malformed_xml_and_bad_elements(tmp_path):
    w = tmp_path / "bad.sdf"
    w.write_text('<?xml version="1.0"?>\n<sdf version="1.9">\n<world name="w">\n<model name="M">\n</world>\n</sdf>\n')
    with pytest.raises(SdfError, match=r"bad.sdf.*line 5"):
        load_sdf_world(w)
    w = write(tmp_path / "pose.sdf", f'<model name="M"><pose>1 2 3</pose><link name="L"><collision name="c">'
                                     f'{box("1 1 1")}</collision></link></model>')
    with pytest.raises(SdfError, match=r"pose.sdf:4: <pose>.*6"):
        load_sdf_world(w, strict=True)
    w = write(tmp_path / "rel.sdf", f'<model name="M"><link name="L"><pose relative_to="nope">0 0 0 0 0 0</pose>'
                                    f'<collision name="c">{box("1 1 1")}</collision></link></model>')
    with pytest.raises(SdfError, match=r"unknown frame 'nope'"):
        load_sdf_world(w, strict=True)
    w = write(tmp_path / "geo.sdf", '<model name="M"><link name="L"><collision name="c">'
                                    '<geometry><torus/></geometry></collision></link></model>')
    with pytest.raises(SdfError, match=r"geo.sdf:4: <torus>.*geometry <torus> is not supported"):
        load_sdf_world(w, strict=True)
    w = write(tmp_path / "mat.sdf", f'<model name="M"><gnss_sim:material>jelly</gnss_sim:material><link name="L">'
                                    f'<collision name="c">{box("1 1 1")}</collision></link></model>')
    with pytest.raises(SdfError, match=r"mat.sdf:4: <material>.*unknown material class 'jelly'"):
        load_sdf_world(w, strict=True)
    w = write(tmp_path / "cyc.sdf", f"""
        <model name="M">
          <frame name="a" attached_to="b"/><frame name="b" attached_to="a"/>
          <link name="L"><pose relative_to="a"/><collision name="c">{box("1 1 1")}</collision></link></model>""")
    with pytest.raises(SdfError, match="cycle"):
        load_sdf_world(w, strict=True)


def test_missing_heightmap_image_is_one_warning_naming_the_part(tmp_path):
    w = write(tmp_path / "w.sdf", '<model name="M"><link name="L"><collision name="c"><geometry><heightmap>'
                                  '<uri>x.png</uri></heightmap></geometry></collision></link></model>'
                                  f'<model name="N"><link name="L"><collision name="c">{box("1 1 1")}</collision>'
                                  '</link></model>')
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        world = load_sdf_world(w)
    msgs = [str(r.message) for r in rec if issubclass(r.category, SceneWarning)]
    assert len(msgs) == 1 and "M::L::c" in msgs[0] and "x.png" in msgs[0]
    assert len(world.triangles) == 12 and world.report["skipped"][0]["part"] == "M::L::c"


# ------------------------------------------------------------------ export round trip
def test_export_and_read_scene_round_trip(tmp_path):
    world = export_world(_repo_world(), tmp_path / "c.ply")
    back = read_scene(tmp_path / "c.ply")
    np.testing.assert_array_equal(back.vertices_m, world.vertices_m)
    np.testing.assert_array_equal(back.triangles, world.triangles)
    np.testing.assert_array_equal(back.material, world.material)
    assert [c.name for c in back.materials.classes] == ["opaque", "foliage"]
    assert back.spherical_coordinates == SphericalCoordinates(50.0764, 14.4179, 250.0, 0.0)
    assert sidecar_path(tmp_path / "c.ply").is_file()
    # a viewer-level reader (trimesh) sees the same triangles
    import trimesh

    m = trimesh.load(tmp_path / "c.ply", process=False)
    assert len(m.faces) == len(world.triangles)


def _repo_world():
    from pathlib import Path

    return Path(__file__).resolve().parents[1] / "worlds" / "courtyard.sdf"


@pytest.mark.parametrize("lat, lon, h, heading", [(22.3, 114.2, 50.0, 0.0), (-33.9, 151.2, 3.0, 37.5),
                                                  (89.9, -179.0, -20.0, 90.0), (0.0, 0.0, 0.0, -180.0)])
def test_world_to_ecef_terms_kept_follow_the_fields(lat, lon, h, heading):
    """world_to_ecef keeps its rotation and origin between calls: the same bits as the ENU route computed afresh,
    for a point and arrays, and again after a field changes."""
    from gnss_sim_ros2.core import frames
    from gnss_sim_ros2.core.scene.georeference import SphericalCoordinates

    rng = np.random.default_rng(7)
    sc = SphericalCoordinates(lat, lon, h, heading)

    def afresh(p):
        return frames.enu_to_ecef(np.asarray(p, dtype=float) @ sc.rotation_enu0_from_world().T, sc.latitude_deg,
                                  sc.longitude_deg, sc.elevation_m)

    for shape in [(3,), (5, 3), (2, 4, 3)]:
        p = rng.normal(size=shape) * 1e3
        got = sc.world_to_ecef(p)
        assert got.shape == shape and got.tobytes() == afresh(p).tobytes()
    assert sc.world_from_ecef_t().tobytes() == sc.rotation_world_from_ecef().T.tobytes()
    sc.latitude_deg, sc.heading_deg = lat / 2.0, heading + 10.0
    p = rng.normal(size=(4, 3))
    assert sc.world_to_ecef(p).tobytes() == afresh(p).tobytes()
    assert sc.world_from_ecef_t().tobytes() == sc.rotation_world_from_ecef().T.tobytes()
    assert not sc.world_from_ecef_t().flags.writeable            # kept and shared: read-only
    assert sc == SphericalCoordinates(lat / 2.0, lon, h, heading + 10.0)     # the kept terms are not a field
