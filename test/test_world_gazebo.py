"""Real Gazebo worlds load as Gazebo loads them (issue 15 acceptance).

Every world of ``../shared/worlds/gz-sim`` exports; those that include Fuel models read them from a
Fuel cache laid out in a temp folder (``GZ_FUEL_CACHE_PATH``) from ``../shared/worlds/models`` and
generated rasters; a world of our own includes every shared model.  Expected triangle counts come
from sources independent of the loader: trimesh's own COLLADA reader for the meshes, (n-1)^2 * 2 for
an n x n heightmap, and the primitive tessellations (plane 2, box 12, cylinder 4 * 32 sections,
icosphere 1280).
"""
from __future__ import annotations

import os
import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from gnss_sim_ros2.core.scene.loader import load_sdf_world
from gnss_sim_ros2.core.scene.mesh_io import export_world, read_scene
from gnss_sim_ros2.core.scene.scene_report import LeftOutWarning, SceneWarning

REPO = Path(__file__).resolve().parents[1]
SHARED_WORLDS = Path(os.environ.get("GNSS_SIM_SHARED_WORLDS", REPO.parent / "shared" / "worlds"))
PLANE, BOX, CYLINDER, SPHERE = 2, 12, 128, 1280
FUEL_HEIGHTMAP_N = {1: 9, 3: 17}       # version -> samples per side of the generated fortress heightmap
BOWL_N, VOLCANO_N = 33, 21


@pytest.fixture(scope="module")
def shared_worlds() -> Path:
    if not (SHARED_WORLDS / "gz-sim").is_dir() or not (SHARED_WORLDS / "models").is_dir():
        pytest.skip(f"real Gazebo worlds folder {SHARED_WORLDS} is absent (it exists beside the clone in CI only)")
    return SHARED_WORLDS


def dae_triangles(path) -> int:
    """Triangles of a COLLADA file by trimesh's reader (not the loader's pycollada walk), without those of zero
    area by trimesh's own measure (the loader drops them: the parking garage has one)."""
    import logging

    import trimesh

    logging.getLogger("trimesh").setLevel(logging.CRITICAL)     # textures were removed from the shared models
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = trimesh.load(str(path), process=False)
    return sum(int(np.count_nonzero(scene.geometry[g].area_faces > 0)) for _, g in
               (scene.graph[n] for n in scene.graph.nodes_geometry))


def _copy_model(src: Path, dst: Path, relative: bool, static: bool | None = None):
    """A shared model folder copied into a Fuel version folder; ``relative``: model:// mesh URIs made relative."""
    shutil.copytree(src, dst)
    sdf = dst / "model.sdf"
    sdf.chmod(0o644)
    text = sdf.read_text()
    if relative:
        text = text.replace(f"model://{src.name}/", "")
    if static is False:
        text = re.sub(r"<static>\s*true\s*</static>", "", text)
    sdf.write_text(text)


def _write_png(path: Path, n: int, bits: int = 8):
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    yy, xx = np.mgrid[0:n, 0:n]
    r2 = ((xx - (n - 1) / 2) ** 2 + (yy - (n - 1) / 2) ** 2) / ((n - 1) / 2) ** 2
    full = 255 if bits == 8 else 65535
    arr = np.clip(r2, 0, 1) * full                      # a bowl: 0 at the centre, full at the rim
    Image.fromarray(arr.astype(np.uint8 if bits == 8 else np.uint16)).save(path)


def _model(dst: Path, name: str, body: str):
    dst.mkdir(parents=True, exist_ok=True)
    (dst / "model.config").write_text(f'<?xml version="1.0"?><model><name>{name}</name>'
                                      f'<sdf version="1.9">model.sdf</sdf></model>')
    (dst / "model.sdf").write_text(f'<?xml version="1.0"?><sdf version="1.9">{body}</sdf>')


@pytest.fixture(scope="module")
def fuel_cache(shared_worlds, tmp_path_factory) -> Path:
    """A local Fuel cache holding every Fuel URI of the gz-sim worlds, in Fuel's layout
    CACHE/fuel.gazebosim.org/<owner>/models/<name>/<version>/ (names mostly lower case, as Fuel
    writes them; two in other cases to check the case-insensitive match)."""
    from PIL import Image

    models = shared_worlds / "models"
    root = tmp_path_factory.mktemp("fuel")
    srv = root / "fuel.gazebosim.org"
    _model(srv / "mingfei/models/actor/1", "actor",
           '<actor name="actor"><skin><filename>meshes/walk.dae</filename></skin></actor>')
    # Backpack: version 1 a box, version 2 the school: the latest version is taken
    _model(srv / "openrobotics/models/backpack/1", "backpack",
           '<model name="backpack"><static>true</static><link name="l"><collision name="c"><geometry><box>'
           '<size>1 1 1</size></box></geometry></collision></link></model>')
    _copy_model(models / "school", srv / "openrobotics/models/backpack/2", relative=True)
    _copy_model(models / "telephone_pole", srv / "openrobotics/models/double pendulum with base/1", relative=False,
                static=False)
    _copy_model(models / "police_station", srv / "openrobotics/models/gazebo - relative paths/1", relative=True)
    _model(srv / "openrobotics/models/actor - relative paths/1", "actor",
           '<actor name="actor"><skin><filename>meshes/walk.dae</filename></skin></actor>')
    radio = srv / "openrobotics/models/radio/4/meshes"
    radio.mkdir(parents=True)
    shutil.copy(models / "post_office/meshes/post_office.dae", radio / "Radio.dae")
    for version, n in FUEL_HEIGHTMAP_N.items():
        _write_png(srv / f"openrobotics/models/fortress heightmap/{version}/materials/textures/fortress_heightmap.png",
                   n)
    # Electrical Box: the URI says owner "openrobotics"; this cache spells it "OpenRobotics"
    _copy_model(models / "parking_garage", srv / "OpenRobotics/models/electrical box/1", relative=True)
    bowl = srv / "chapulina/models/heightmap bowl/1"
    _write_png(bowl / "materials/textures/bowl.png", BOWL_N, bits=16)
    _model(bowl, "Heightmap Bowl", '<model name="heightmap_bowl"><static>true</static><link name="link">'
           '<collision name="collision"><geometry><heightmap><uri>materials/textures/bowl.png</uri>'
           '<size>20 20 5</size><pos>0 0 -2</pos></heightmap></geometry></collision></link></model>')
    volcano = srv / "jennuine/models/volcano/1"
    (volcano / "dem").mkdir(parents=True)
    yy, xx = np.mgrid[0:VOLCANO_N, 0:VOLCANO_N]
    dem = 2000.0 + 30.0 * np.exp(-((xx - 10.0) ** 2 + (yy - 10.0) ** 2) / 20.0)
    Image.fromarray(dem.astype(np.float32), mode="F").save(volcano / "dem" / "volcano.tif")
    _model(volcano, "Volcano", '<model name="volcano"><static>true</static><link name="link">'
           '<collision name="collision"><geometry><heightmap><uri>dem/volcano.tif</uri>'
           '<size>100 100 30</size></heightmap></geometry></collision></link></model>')
    return root


@pytest.fixture
def gazebo_env(fuel_cache, shared_worlds, monkeypatch):
    for var in ("GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "SDF_PATH", "AMENT_PREFIX_PATH",
                "ROS_PACKAGE_PATH"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("GZ_FUEL_CACHE_PATH", str(fuel_cache))
    monkeypatch.setenv("GAZEBO_MODEL_PATH", str(shared_worlds / "models"))
    return shared_worlds


def _expected_gz_sim(models: Path) -> dict[str, tuple[int, list[str]]]:
    """world -> (triangles, names of the parts left out); all opaque."""
    fortress = (FUEL_HEIGHTMAP_N[3] - 1) ** 2 * 2        # tip = version 3
    return {
        "actor.sdf": (PLANE, ["demo_actor", "box", "actor_talking", "actor_walking"]),
        "default.sdf": (PLANE, []),
        "dem_volcano.sdf": ((VOLCANO_N - 1) ** 2 * 2, ["sphere"]),
        "diff_drive_skid.sdf": (PLANE, ["vehicle_blue"]),
        "fuel.sdf": (PLANE + dae_triangles(models / "school/meshes/school.dae")
                     + 2 * BOX                                  # police station: two collision boxes
                     + dae_triangles(models / "post_office/meshes/post_office.dae") + fortress,
                     ["Double pendulum", "Actor Test"]),
        "grid.sdf": (PLANE, []),
        "heightmap.sdf": ((BOWL_N - 1) ** 2 * 2, ["sphere_red", "sphere_green", "sphere_blue", "sphere_yellow"]),
        "import_mesh.sdf": (PLANE + dae_triangles(models / "parking_garage/meshes/parking_garage.dae"), []),
        "levels.sdf": (None, ["vehicle_red", "vehicle_blue"]),
        "lights.sdf": (PLANE, ["box", "cylinder", "sphere"]),
        "nested_model.sdf": (PLANE, ["model_00", "model_00::model_01"]),   # each moves: neither is static
        "polylines.sdf": (PLANE, ["triangle", "pentagon", "cube", "letter"]),
        "sky.sdf": (PLANE + BOX, ["box", "cylinder", "sphere"]),
        "visibility.sdf": (PLANE + 2 * BOX, ["box", "cylinder", "sphere"]),
    }


def _static_box_collisions(path: Path) -> int:
    from lxml import etree

    # the file has "--" in a comment (which Gazebo accepts): a recovering parse for this count
    world = etree.parse(str(path), etree.XMLParser(recover=True)).getroot().find("world")
    n = 0
    for m in world.findall("model"):
        if (m.findtext("static") or "").strip() == "true":
            assert all(c.find("geometry/box") is not None for c in m.iter("collision"))
            n += len(list(m.iter("collision")))
    return n


def test_every_gz_sim_world_exports(gazebo_env, tmp_path):
    models = gazebo_env / "models"
    expected = _expected_gz_sim(models)
    worlds = sorted(p.name for p in (gazebo_env / "gz-sim").glob("*.sdf"))
    assert worlds == sorted(expected), "a world was added to ../shared/worlds/gz-sim: add its expectation here"
    for name in worlds:
        with warnings.catch_warnings():
            warnings.simplefilter("error", SceneWarning)            # nothing may be skipped
            warnings.simplefilter("ignore", LeftOutWarning)         # robots are left out: asserted below
            world = export_world(gazebo_env / "gz-sim" / name, tmp_path / (name + ".ply"), strict=True)
        tri, left_out = expected[name]
        if name == "levels.sdf":   # box collisions of the static models, counted from the XML
            tri = BOX * _static_box_collisions(gazebo_env / "gz-sim" / name)
        assert len(world.triangles) == tri, name
        assert world.class_counts() == {"opaque": tri, "foliage": 0}, name
        assert sorted(it["part"] for it in world.report["left_out"]) == sorted(left_out), name
        assert world.report["skipped"] == [], name
        back = read_scene(tmp_path / (name + ".ply"))
        assert back.report["triangles"]["opaque"] == tri


def test_fuel_picks_latest_version_and_matches_case(gazebo_env, fuel_cache, tmp_path):
    from gnss_sim_ros2.core.scene.uris import fuel_model_dir

    d, sub, _ = fuel_model_dir("https://fuel.gazebosim.org/1.0/OpenRobotics/models/Backpack")
    assert d == fuel_cache / "fuel.gazebosim.org/openrobotics/models/backpack/2" and sub == ""
    d, _, _ = fuel_model_dir("https://fuel.gazebosim.org/1.0/OpenRobotics/models/Backpack/1")
    assert d.name == "1"
    d, sub, _ = fuel_model_dir("https://fuel.gazebosim.org/1.0/openrobotics/models/Electrical%20Box/tip/files/model.sdf")
    assert d == fuel_cache / "fuel.gazebosim.org/OpenRobotics/models/electrical box/1" and sub == "model.sdf"
    # a model that is not cached: one warning naming the include and the cache folder; strict: an error
    w = tmp_path / "w.sdf"
    w.write_text('<sdf version="1.9"><world name="w"><include><name>crate</name>'
                 '<uri>https://fuel.gazebosim.org/1.0/someone/models/Crate</uri></include>'
                 '<model name="g"><static>true</static><link name="l"><collision name="c"><geometry><box>'
                 '<size>1 1 1</size></box></geometry></collision></link></model></world></sdf>')
    with pytest.warns(SceneWarning, match=r"crate: .*not in the local Fuel cache.*someone/models/crate"):
        world = load_sdf_world(w)
    assert len(world.triangles) == BOX
    with pytest.raises(ValueError, match=r"world .*w\.sdf: cannot load crate: .*--allow-partial"):
        load_sdf_world(w, strict=True)


def own_world(path: Path, body: str, head: str = '<sdf version="1.9">') -> Path:
    path.write_text(f'<?xml version="1.0"?>\n{head}\n<world name="own">\n{body}\n</world>\n</sdf>\n')
    return path


def test_own_world_with_every_shared_model(gazebo_env, tmp_path):
    models = gazebo_env / "models"
    names = sorted(p.name for p in models.iterdir() if (p / "model.config").is_file())
    assert set(names) >= {"school", "post_office", "police_station", "parking_garage", "telephone_pole",
                          "pine_tree", "sun", "ground_plane"}
    body = "\n".join(f"<include><uri>model://{n}</uri><pose>{40 * k} 0 0 0 0 0</pose></include>"
                     for k, n in enumerate(names))
    w = own_world(tmp_path / "all.sdf", body)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        world = export_world(w, tmp_path / "all.ply", strict=True)
    by_part = {p["name"]: p for p in world.parts}
    assert [by_part[f"police_station::link::collision_{k}"]["triangles"] for k in ("main", "landing")] == [BOX] * 2
    for n in ("school", "post_office", "parking_garage"):
        assert by_part[f"{n}::link::collision"]["triangles"] == dae_triangles(models / n / "meshes" / f"{n}.dae")
        assert by_part[f"{n}::link::collision"]["class"] == "opaque"
    assert by_part["telephone_pole::link::collision_pole"]["triangles"] == CYLINDER
    assert by_part["telephone_pole::link::collision_cross"]["triangles"] == BOX
    assert by_part["ground_plane::link::collision"]["triangles"] == PLANE
    # the pine's collision is its whole mesh: the Branch node is foliage (made a closed crown), Bark opaque
    assert by_part["pine_tree::link::collision::Bark"]["class"] == "opaque"
    branch = by_part["pine_tree::link::collision::Branch"]
    assert branch["class"] == "foliage" and branch["crown_volumes"] == 1 and branch["source_triangles"] == 540
    assert [it["part"] for it in world.report["left_out"]] == ["model://sun"]
    counts = world.class_counts()
    assert counts["foliage"] == branch["triangles"]
    assert counts["opaque"] == sum(p["triangles"] for p in world.parts if p["class"] == "opaque")
    assert len(world.triangles) == counts["opaque"] + counts["foliage"]
    # the parking garage (COLLADA in inches) is about 60 m long, not 2400
    garage = [i for i, p in enumerate(world.parts) if p["name"].startswith("parking_garage")]
    assert garage


def test_mesh_file_read_once_for_many_includes(gazebo_env, tmp_path):
    body = "\n".join(f"<include><uri>model://school</uri><name>s{k}</name><pose>{50 * k} 0 0 0 0 0</pose></include>"
                     for k in range(30))
    world = load_sdf_world(own_world(tmp_path / "many.sdf", body))
    assert world.report["mesh_files_read"] == 1 and world.report["mesh_cache_hits"] == 29
    assert len(world.triangles) == 30 * dae_triangles(gazebo_env / "models/school/meshes/school.dae")


# ------------------------------------------------------------------ population
def _pop(name: str, dist: str, extra: str, count: int = 0, region: str = '<box><size>20 10 0</size></box>') -> str:
    mc = f"<model_count>{count}</model_count>" if count else ""
    return (f'<population name="{name}"><pose>100 200 0 0 0 0</pose>{mc}{region}'
            f'<distribution><type>{dist}</type>{extra}</distribution>'
            f'<model name="post"><static>true</static><link name="l"><collision name="c"><geometry>'
            f'<cylinder><radius>0.1</radius><length>2</length></cylinder></geometry></collision></link>'
            f'</model></population>')


def _centres(world) -> np.ndarray:
    out, start = [], 0
    for p in world.parts:
        tri = world.triangles[start:start + p["triangles"]]
        v = world.vertices_m[np.unique(tri)]
        out.append(0.5 * (v.min(axis=0) + v.max(axis=0)))
        start += p["triangles"]
    return np.array(out)


def test_population_grid_random_uniform(tmp_path):
    w = own_world(tmp_path / "grid.sdf", _pop("orchard", "grid", "<rows>4</rows><cols>5</cols><step>3 2 0</step>"))
    world = load_sdf_world(w)
    assert len(world.parts) == 20 and len(world.triangles) == 20 * CYLINDER
    c = _centres(world)
    # Gazebo Classic CreatePosesGrid: from the population pose, +x per column, +y per row
    np.testing.assert_allclose(sorted(set(np.round(c[:, 0], 6))), [100, 103, 106, 109, 112], atol=1e-9)
    np.testing.assert_allclose(sorted(set(np.round(c[:, 1], 6))), [200, 202, 204, 206], atol=1e-9)

    w = own_world(tmp_path / "random.sdf", _pop("cans", "random", "", count=25))
    a, b = load_sdf_world(w, seed=7), load_sdf_world(w, seed=7)
    ca = _centres(a)
    np.testing.assert_array_equal(ca, _centres(b))                      # seeded: the same every time
    assert not np.allclose(ca, _centres(load_sdf_world(w, seed=8)))
    assert len(ca) == 25
    assert np.all(np.abs(ca[:, 0] - 100) <= 10) and np.all(np.abs(ca[:, 1] - 200) <= 5)

    w = own_world(tmp_path / "uniform.sdf", _pop("even", "uniform", "", count=10,
                                                region="<cylinder><radius>10</radius><length>0</length></cylinder>"))
    cu = _centres(load_sdf_world(w))
    d = np.linalg.norm(cu[:, None, :2] - cu[None, :, :2], axis=-1) + np.eye(10) * 1e9
    assert len(cu) == 10 and np.all(np.hypot(cu[:, 0] - 100, cu[:, 1] - 200) <= 10)
    assert d.min() > 3.0          # evenly spread: 10 random points in a 10 m disc would often be closer


def test_population_of_pine_trees_is_foliage(gazebo_env, tmp_path):
    body = ('<population name="pines"><pose>0 0 0 0 0 0</pose><distribution><type>grid</type><rows>2</rows>'
            '<cols>3</cols><step>8 8 0</step></distribution><include><uri>model://pine_tree</uri></include>'
            '</population>')
    world = load_sdf_world(own_world(tmp_path / "pines.sdf", body))
    fol = [p for p in world.parts if p["class"] == "foliage"]
    assert len(fol) == 6 and all(p["crown_volumes"] == 1 for p in fol)


# ------------------------------------------------------------------ heightmap
def test_heightmap_png_heights_and_placement(tmp_path):
    n = 17
    _write_png(tmp_path / "hm.png", n, bits=16)
    body = ('<model name="terrain"><static>true</static><link name="l"><collision name="c"><geometry><heightmap>'
            '<uri>hm.png</uri><size>32 16 4</size><pos>1 2 -1</pos></heightmap></geometry></collision></link>'
            '</model>')
    world = load_sdf_world(own_world(tmp_path / "hm.sdf", body))
    assert len(world.triangles) == (n - 1) ** 2 * 2 and world.class_counts()["opaque"] == len(world.triangles)
    v = world.vertices_m
    np.testing.assert_allclose([v[:, 0].min(), v[:, 0].max(), v[:, 1].min(), v[:, 1].max()], [-15, 17, -6, 10])
    # bowl: the centre sample at pos z, the corners at pos z + size z
    centre = v[np.argmin(np.hypot(v[:, 0] - 1, v[:, 1] - 2))]
    assert centre[2] == pytest.approx(-1.0, abs=1e-9)
    assert v[:, 2].max() == pytest.approx(3.0, abs=1e-3)


def test_dem_without_size_is_a_clear_skip(tmp_path):
    from PIL import Image

    Image.fromarray(np.full((5, 5), 100.0, np.float32), mode="F").save(tmp_path / "d.tif")
    body = ('<model name="dem"><static>true</static><link name="l"><collision name="c"><geometry><heightmap>'
            '<uri>d.tif</uri></heightmap></geometry></collision></link></model>')
    with pytest.raises(ValueError, match=r"dem::l::c: .*DEM d.tif.*give <size>"):
        load_sdf_world(own_world(tmp_path / "dem.sdf", body), strict=True)


# ------------------------------------------------------------------ partial worlds, XML, URIs
def test_partial_world_skips_with_one_warning_each_and_reports(tmp_path, monkeypatch):
    monkeypatch.delenv("GZ_SIM_RESOURCE_PATH", raising=False)
    body = ('<model name="ok"><static>true</static><link name="l"><collision name="c"><geometry><box><size>1 1 1'
            '</size></box></geometry></collision></link></model>'
            '<model name="person"><static>true</static><link name="l"><collision name="c"><geometry><mesh>'
            '<uri>meshes/person_standing.dae</uri></mesh></geometry></collision>'
            '<collision name="feet"><geometry><sphere><radius>0.2</radius></sphere></geometry></collision></link>'
            '</model><include><uri>model://nowhere_model</uri></include>'
            '<road name="main"><width>7</width><point>0 0 0</point><point>10 0 0</point></road>')
    w = own_world(tmp_path / "partial.sdf", body)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        world = export_world(w, tmp_path / "partial.ply")
    msgs = [str(r.message) for r in rec if issubclass(r.category, SceneWarning)]
    assert len(msgs) == 2
    # includes are resolved first (they name frames), then the models
    assert "model://nowhere_model" in msgs[0]
    assert "person::l::c" in msgs[1] and "person_standing.dae" in msgs[1]
    assert len(world.triangles) == BOX + SPHERE                       # the rest of the person is kept
    report = read_scene(tmp_path / "partial.ply").report
    assert [s["part"] for s in report["skipped"]] == ["model://nowhere_model", "person::l::c"]
    assert [s["part"] for s in report["left_out"]] == ["<road name='main'>"]         # flat, a visual in Gazebo
    with pytest.raises(ValueError, match=r"partial\.sdf: cannot load model://nowhere_model: .*cannot find.*also "
                                         r"cannot load person::l::c.*--allow-partial"):
        load_sdf_world(w, strict=True)


def test_lenient_xml_like_sdformat(tmp_path):
    w = tmp_path / "lenient.sdf"
    w.write_text('<?xml version="1.0"?>\n<!-- a comment -- with double hyphens -->\n<sdf version="1.9">\n'
                 '<world name="w"><gz:plugin filename="x" gz:name="y"/>\n'
                 '<model name="m"><static>true</static><link name="l"><collision name="c"><geometry>\n'
                 '<box><size>1 1 1</size></box></geometry></collision></link></model></world></sdf>\n')
    assert len(load_sdf_world(w).triangles) == BOX
    w.write_text('<?xml version="1.0"?>\n<!-- ok -->\n<sdf version="1.9">\n<world name="w">\n<model>\n</world></sdf>')
    with pytest.raises(ValueError, match=r"lenient.sdf: malformed SDF/XML.*line 5"):
        load_sdf_world(w)


def test_file_package_and_sdf_path_uris(tmp_path, monkeypatch):
    import trimesh

    for var in ("GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "GAZEBO_MODEL_PATH", "ROS_PACKAGE_PATH"):
        monkeypatch.delenv(var, raising=False)
    prefix = tmp_path / "install" / "robot_worlds"
    (prefix / "share" / "robot_worlds" / "meshes").mkdir(parents=True)
    trimesh.creation.box(extents=(1, 1, 1)).export(prefix / "share" / "robot_worlds" / "meshes" / "crate.stl")
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix))
    sdfp = tmp_path / "sdf_models"
    (sdfp / "pole" / "meshes").mkdir(parents=True)
    trimesh.creation.cylinder(radius=0.1, height=3, sections=8).export(sdfp / "pole" / "meshes" / "pole.obj")
    monkeypatch.setenv("SDF_PATH", str(sdfp))
    # an AWS-style world: file://models/... relative to the world's folder
    (tmp_path / "worlds" / "models" / "rack").mkdir(parents=True)
    trimesh.creation.box(extents=(2, 2, 2)).export(tmp_path / "worlds" / "models" / "rack" / "rack.glb")

    def m(name, uri):
        return (f'<model name="{name}"><static>true</static><link name="l"><collision name="c"><geometry><mesh>'
                f'<uri>{uri}</uri></mesh></geometry></collision></link></model>')

    w = own_world(tmp_path / "worlds" / "uris.sdf", m("crate", "package://robot_worlds/meshes/crate.stl")
                  + m("pole", "model://pole/meshes/pole.obj") + m("rack", "file://models/rack/rack.glb"))
    world = load_sdf_world(w, strict=True)
    assert [p["triangles"] for p in world.parts] == [BOX, 4 * 8, BOX]
    with pytest.raises(ValueError, match=r"network URI .*never fetched"):
        load_sdf_world(own_world(tmp_path / "net.sdf", m("x", "https://example.com/x.stl")), strict=True)


def test_submesh_with_center_and_non_static(gazebo_env, tmp_path):
    body = ('<model name="pine_parts"><static>true</static><link name="l">'
            '<visual name="branch"><geometry><mesh><uri>model://pine_tree/meshes/pine_tree.dae</uri>'
            '<submesh><name>Branch</name><center>true</center></submesh></mesh></geometry></visual>'
            '<visual name="bark"><geometry><mesh><uri>model://pine_tree/meshes/pine_tree.dae</uri>'
            '<submesh><name>Bark</name></submesh></mesh></geometry></visual></link></model>'
            '<model name="robot"><link name="l"><visual name="v"><geometry><box><size>1 1 1</size></box></geometry>'
            '</visual></link></model>')
    w = own_world(tmp_path / "sub.sdf", body)
    with pytest.warns(LeftOutWarning, match=r"left out 1 non-static model\(s\) \(robot\).*keep_dynamic"):
        world = load_sdf_world(w, use_visuals=True)
    by = {p["name"]: p for p in world.parts}
    assert by["pine_parts::l::bark"]["triangles"] == 136 and by["pine_parts::l::bark"]["class"] == "opaque"
    assert by["pine_parts::l::branch"]["class"] == "foliage" and by["pine_parts::l::branch"]["source_triangles"] == 540
    crown = world.vertices_m[np.unique(world.triangles[:by["pine_parts::l::branch"]["triangles"]])]
    np.testing.assert_allclose(0.5 * (crown.min(axis=0) + crown.max(axis=0)), 0.0, atol=1e-6)   # centred
    assert "robot" not in {p["name"].split("::")[0] for p in world.parts}
    kept = load_sdf_world(w, use_visuals=True, keep_dynamic=True)
    assert len(kept.triangles) == len(world.triangles) + BOX


def test_new_primitives_extents(tmp_path):
    def m(name, geom):
        return (f'<model name="{name}"><static>true</static><link name="l"><collision name="c"><geometry>{geom}'
                f'</geometry></collision></link></model>')

    w = own_world(tmp_path / "prims.sdf", m("cone", "<cone><radius>2</radius><length>4</length></cone>")
                  + m("caps", "<capsule><radius>0.5</radius><length>2</length></capsule>")
                  + m("ell", "<ellipsoid><radii>1 2 3</radii></ellipsoid>"))
    world = load_sdf_world(w)
    start = 0
    ext = {}
    for p in world.parts:
        v = world.vertices_m[np.unique(world.triangles[start:start + p["triangles"]])]
        ext[p["name"].split("::")[0]] = (v.min(axis=0), v.max(axis=0))
        start += p["triangles"]
    np.testing.assert_allclose(ext["cone"], [[-2, -2, -2], [2, 2, 2]], atol=1e-9)       # centred (gz-common)
    np.testing.assert_allclose(ext["caps"][1], [0.5, 0.5, 1.5], atol=1e-3)
    np.testing.assert_allclose(ext["ell"][1], [1, 2, 3], atol=1e-3)


def test_own_orchard_world(tmp_path):
    world = export_world(REPO / "worlds" / "orchard.sdf", tmp_path / "orchard.ply", strict=True)
    crowns = [p for p in world.parts if p["name"].endswith("::crown::collision")]
    trunks = [p for p in world.parts if p["name"].endswith("::trunk::collision")]
    assert len(crowns) == len(trunks) == 24 and all(p["class"] == "foliage" for p in crowns)
    # plane + barn box + roof prism (4-gon: 2 + 2 caps + 8 sides) + 24 x (cylinder + icosphere)
    assert world.class_counts() == {"opaque": PLANE + BOX + 12 + 24 * CYLINDER, "foliage": 24 * SPHERE}
    c = _centres(load_sdf_world(REPO / "worlds" / "orchard.sdf"))
    crown_c = c[[i for i, p in enumerate(world.parts) if p["name"].endswith("::crown::collision")]]
    np.testing.assert_allclose(sorted(set(crown_c[:, 0].round(6))), [0, 5, 10, 15], atol=1e-9)
    np.testing.assert_allclose(sorted(set(crown_c[:, 1].round(6))), [-15, -9, -3, 3, 9, 15], atol=1e-9)
    np.testing.assert_allclose(crown_c[:, 2], 3.2, atol=1e-9)


def test_saved_state_places_the_models(tmp_path):
    body = ('<model name="crate"><static>true</static><pose>0 0 0.5 0 0 0</pose><link name="l"><collision name="c">'
            '<geometry><box><size>1 1 1</size></box></geometry></collision></link></model>'
            '<state world_name="own"><sim_time>12 0</sim_time><model name="crate"><pose>10 -4 0.5 0 0 1.5707963'
            '</pose><link name="l"><pose>10 -4 0.5 0 0 1.5707963</pose></link></model></state>')
    world = load_sdf_world(own_world(tmp_path / "state.sdf", body), strict=True)
    np.testing.assert_allclose(_centres(world)[0], [10, -4, 0.5], atol=1e-6)


def test_model_uri_inside_a_cached_fuel_model_is_the_model_itself(tmp_path, monkeypatch):
    import trimesh

    for var in ("GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "GAZEBO_MODEL_PATH", "SDF_PATH"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("GZ_FUEL_CACHE_PATH", str(tmp_path / "cache"))
    d = tmp_path / "cache/fuel.gazebosim.org/someone/models/crate/3"
    _model(d, "Crate", '<model name="crate"><static>true</static><link name="l"><collision name="c"><geometry>'
           '<mesh><uri>model://Crate/meshes/crate.stl</uri></mesh></geometry></collision></link></model>')
    (d / "meshes").mkdir()
    trimesh.creation.box(extents=(1, 1, 1)).export(d / "meshes" / "crate.stl")
    w = own_world(tmp_path / "crate.sdf", "<include><uri>https://fuel.gazebosim.org/1.0/someone/models/Crate</uri>"
                                          "</include>")
    assert len(load_sdf_world(w, strict=True).triangles) == BOX


def test_polyline_inside_another_is_a_hole(tmp_path):
    import trimesh

    def ring(pts):
        return "<polyline>" + "".join(f"<point>{x} {y}</point>" for x, y in pts) + "<height>3</height></polyline>"

    body = ('<model name="block"><static>true</static><link name="l"><collision name="c"><geometry>'
            + ring([(0, 0), (10, 0), (10, 10), (0, 10)]) + ring([(3, 3), (3, 7), (7, 7), (7, 3)])
            + '</geometry></collision></link></model>')
    world = load_sdf_world(own_world(tmp_path / "yard.sdf", body), strict=True)
    assert len(world.parts) == 1
    m = trimesh.Trimesh(world.vertices_m, world.triangles)
    assert m.is_watertight and m.volume == pytest.approx((100 - 16) * 3)
    from gnss_sim_ros2.core.scene.visibility import STATE_BLOCKED, STATE_VISIBLE, Scene

    s = Scene(world)
    r = s.visibility(np.array([[5.0, 5.0, 0.5], [1.0, 1.0, 0.5]]), az_deg=[0.0], el_deg=[89.0])
    assert list(r.state[:, 0]) == [STATE_VISIBLE, STATE_BLOCKED]          # the courtyard is open to the sky


def test_export_world_command_report_strict_and_keep_dynamic(tmp_path, capsys):
    from gnss_sim_ros2.cli import main

    body = ('<model name="robot"><link name="l"><collision name="c"><geometry><box><size>1 1 1</size></box>'
            '</geometry></collision></link></model>'
            '<model name="shed"><static>true</static><link name="l"><collision name="c"><geometry><mesh>'
            '<uri>shed.obj</uri></mesh></geometry></collision><collision name="floor"><geometry><box>'
            '<size>3 3 0.1</size></box></geometry></collision></link></model>')
    w = own_world(tmp_path / "cli.sdf", body)
    # strict by default: the scene would lack the shed's mesh
    assert main(["export-world", str(w), "--out", str(tmp_path / "c.ply")]) == 2
    err = capsys.readouterr().err
    assert "error: world " in err and "cannot load shed::l::c: " in err and "shed.obj" in err
    assert "--allow-partial" in err and "Traceback" not in err
    assert not (tmp_path / "c.ply").exists()
    assert main(["export-world", str(w), "--out", str(tmp_path / "a.ply"), "--allow-partial"]) == 0
    out = capsys.readouterr().out
    assert "12 triangles" in out and "skipped: 1" in out and "shed::l::c: " in out and "shed.obj" in out
    assert "left out: 1" in out and "robot: not static" in out
    assert main(["export-world", str(w), "--out", str(tmp_path / "b.ply"), "--keep-dynamic", "--allow-partial"]) == 0
    assert "24 triangles" in capsys.readouterr().out
    # --strict (the default now) is still accepted
    assert main(["export-world", str(w), "--out", str(tmp_path / "c.ply"), "--strict"]) == 2
    assert "cannot load shed::l::c: " in capsys.readouterr().err
    assert main(["export-world", str(w), "--out", str(tmp_path / "c.ply"), "--strict", "--allow-partial"]) == 2
    assert "options --strict and --allow-partial contradict" in capsys.readouterr().err


def test_demo_world_path(monkeypatch):
    from gnss_sim_ros2.core.scene import demo_world

    assert demo_world.demo_world_path() == REPO / "worlds" / "courtyard.sdf"
    monkeypatch.setattr(demo_world, "DEMO_WORLD_NAME", "no_such_demo.sdf")
    with pytest.raises(ValueError, match=r"demo world worlds/no_such_demo.sdf was not found.*give a world"):
        demo_world.demo_world_path()


SKINNED_DAE = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><unit name="centimeter" meter="0.01"/><up_axis>Z_UP</up_axis></asset>
  <library_geometries>
    <geometry id="body-mesh" name="body">
      <mesh>
        <source id="body-pos">
          <float_array id="body-pos-array" count="12">0 0 0 100 0 0 0 100 0 0 0 100</float_array>
          <technique_common>
          <accessor source="#body-pos-array" count="4" stride="3">
            <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
          </accessor></technique_common>
        </source>
        <vertices id="body-vtx"><input semantic="POSITION" source="#body-pos"/></vertices>
        <triangles count="4">
          <input semantic="VERTEX" source="#body-vtx" offset="0"/>
          <p>0 2 1 0 1 3 0 3 2 1 2 3</p>
        </triangles>
      </mesh>
    </geometry>
  </library_geometries>
  <library_controllers>
    <controller id="body-skin" name="skin">
      <skin source="#body-mesh">
        <bind_shape_matrix>1 0 0 0 0 1 0 0 0 0 1 50 0 0 0 1</bind_shape_matrix>
        <source id="joints"><Name_array id="joints-array" count="1">root</Name_array>
          <technique_common>
          <accessor source="#joints-array" count="1" stride="1">
            <param name="JOINT" type="name"/></accessor>
          </technique_common></source>
        <source id="binds"><float_array id="binds-array" count="16">1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1</float_array>
          <technique_common>
          <accessor source="#binds-array" count="1" stride="16">
            <param name="TRANSFORM" type="float4x4"/></accessor>
          </technique_common></source>
        <source id="weights"><float_array id="weights-array" count="1">1</float_array>
          <technique_common>
          <accessor source="#weights-array" count="1" stride="1">
            <param name="WEIGHT" type="float"/></accessor>
          </technique_common></source>
        <joints><input semantic="JOINT" source="#joints"/><input semantic="INV_BIND_MATRIX" source="#binds"/></joints>
        <vertex_weights count="4">
          <input semantic="JOINT" source="#joints" offset="0"/><input semantic="WEIGHT" source="#weights" offset="1"/>
          <vcount>1 1 1 1</vcount><v>0 0 0 0 0 0 0 0</v>
        </vertex_weights>
      </skin>
    </controller>
  </library_controllers>
  <library_visual_scenes>
    <visual_scene id="Scene" name="Scene">
      <node id="root" name="root" type="JOINT"/>
      <node id="Person" name="Person" type="NODE">
        <instance_controller url="#body-skin"><skeleton>#root</skeleton></instance_controller>
      </node>
    </visual_scene>
  </library_visual_scenes>
  <scene><instance_visual_scene url="#Scene"/></scene>
</COLLADA>
"""


def test_skinned_collada_mesh_in_its_bind_pose(tmp_path):
    """A person mesh with a skin controller (citysim's people): a tetrahedron of 1 m (in cm units) bound
    0.5 m up by its bind_shape_matrix."""
    (tmp_path / "person.dae").write_text(SKINNED_DAE)
    body = ('<model name="person"><static>true</static><link name="l"><collision name="c"><geometry><mesh>'
            '<uri>person.dae</uri></mesh></geometry></collision></link></model>')
    world = load_sdf_world(own_world(tmp_path / "people.sdf", body), strict=True)
    assert len(world.triangles) == 4
    np.testing.assert_allclose([world.vertices_m.min(axis=0), world.vertices_m.max(axis=0)],
                               [[0, 0, 0.5], [1, 1, 1.5]], atol=1e-9)
