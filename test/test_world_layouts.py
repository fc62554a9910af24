"""Worlds as Gazebo reads them, the same way in every front end (issue 25).

* The most common published layout -- a ``<model name="x">`` without links wrapping an ``<include>`` of a
  model whose own ``model.sdf`` says ``<static>true</static>`` (the AWS RoboMaker worlds, the Hong Kong city
  world of ``../shared/data/hk-tst-city-model``) -- keeps every building: the models with geometry in the
  scene are counted against the static models with collision geometry of the world, found here by an
  independent walk of the SDF (xml.etree, SDFormat's static rule: a model is static when its own or its
  include's ``<static>`` is true or it sits in a static model).
* A world whose ``model://`` cannot be found stops ``export-world``, ``skyplot`` and ``simulate --world``
  with rc 2 and one error naming the world, the model and why; ``--allow-partial`` runs with a warning.
* ``gz::`` prefixed element and attribute names load (gz-sim's ``sensors.sdf``).
* An OBJ with a NaN vertex and a zero-area triangle: those are dropped with a warning naming the file and
  the count; the rest of the scene still blocks.
"""
from __future__ import annotations

import gzip
import os
import shutil
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from gnss_sim_ros2.cli import main
from gnss_sim_ros2.core.scene.loader import load_sdf_world
from gnss_sim_ros2.core.scene.mesh_files import DroppedTrianglesWarning
from gnss_sim_ros2.core.scene.scene_report import LeftOutWarning, SceneWarning
from gnss_sim_ros2.core.visibility import VisibilityOptions, load_scene

REPO = Path(__file__).resolve().parents[1]
SHARED_WORLDS = Path(os.environ.get("GNSS_SIM_SHARED_WORLDS", REPO.parent / "shared" / "worlds"))
#: the shared models that are buildings (static in their own model.sdf), included AWS-style below
BUILDINGS = ("school", "post_office", "police_station", "parking_garage", "telephone_pole", "pine_tree")
SPHERICAL = ("<spherical_coordinates><surface_model>EARTH_WGS84</surface_model><latitude_deg>22.3</latitude_deg>"
             "<longitude_deg>114.17</longitude_deg><elevation>0</elevation><heading_deg>0</heading_deg>"
             "</spherical_coordinates>")


@pytest.fixture(autouse=True)
def _no_model_paths(monkeypatch):
    for var in ("GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "GAZEBO_MODEL_PATH", "SDF_PATH"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HOME", "/nonexistent-home")         # no ~/.gazebo/models, no ~/.gz/fuel


# ------------------------------------------------------------------ the independent walk of a world
def _true(el) -> bool:
    return el is not None and (el.text or "").strip().lower() in ("1", "true")


def _model_file(uri: str, model_dirs: list[Path]) -> Path:
    name = uri[len("model://"):].split("/")[0]
    for d in model_dirs:
        folder = d / name
        if (folder / "model.config").is_file():
            sdf = ET.parse(folder / "model.config").getroot().findall("sdf")
            if sdf:
                return folder / sdf[-1].text.strip()
        if (folder / "model.sdf").is_file():
            return folder / "model.sdf"
    raise AssertionError(f"{uri} not in {model_dirs}")


def static_collisions(world_file: Path, model_dirs: list[Path]) -> dict[str, list[str]]:
    """{scoped model name: [scoped link::collision names]} of the static models with collision geometry."""
    out: dict[str, list[str]] = {}

    def walk(model, name: str, static: bool):
        cols = [f"{name}::{link.get('name')}::{c.get('name')}" for link in model.findall("link")
                for c in link.findall("collision") if c.find("geometry") is not None]
        if static and cols:
            out[name] = cols
        for sub in model.findall("model"):
            walk(sub, f"{name}::{sub.get('name')}", static or _true(sub.find("static")))
        for inc in model.findall("include"):
            walk_include(inc, name, static)

    def walk_include(inc, prefix: str, static: bool):
        root = ET.parse(_model_file(inc.findtext("uri").strip(), model_dirs)).getroot()
        model = root if root.tag == "model" else root.find("model")
        if model is None:                                   # a light (model://sun)
            return
        name = (inc.findtext("name") or model.get("name")).strip()
        own = inc.find("static") if inc.find("static") is not None else model.find("static")
        walk(model, f"{prefix}::{name}" if prefix else name, static or _true(own))

    world = ET.parse(world_file).getroot().find("world")
    for m in world.findall("model"):
        walk(m, m.get("name"), _true(m.find("static")))
    for inc in world.findall("include"):
        walk_include(inc, "", False)
    return out


def models_in_scene(parts: list[dict], expected: dict[str, list[str]]) -> set[str]:
    """The expected models of which the scene holds geometry; every part must belong to one of them."""
    names = [p["name"] for p in parts]
    found = set()
    for model, cols in expected.items():
        if any(n == c or n.startswith(c + "::") for c in cols for n in names):
            found.add(model)
    stray = [n for n in names if not any(n == c or n.startswith(c + "::") for cols in expected.values() for c in cols)]
    assert stray == [], f"parts of no static model of the world: {stray}"
    return found


# ------------------------------------------------------------------ worlds
@pytest.fixture(scope="module")
def shared_models() -> Path:
    models = SHARED_WORLDS / "models"
    if not all((models / n / "model.sdf").is_file() for n in BUILDINGS):
        pytest.skip(f"real Gazebo models folder {models} is absent (it exists beside the clone in CI only)")
    return models


@pytest.fixture(scope="module")
def hk_city(shared_data, tmp_path_factory) -> Path:
    """The Hong Kong city model and its world, copied with the gzipped terrain unpacked (its README)."""
    src = shared_data / "hk-tst-city-model"
    if not (src / "worlds" / "hong_kong_city_only.world").is_file():
        pytest.skip(f"the Hong Kong city model {src} is absent (it exists beside the clone in CI only)")
    dst = tmp_path_factory.mktemp("hk")
    for sub in ("models", "worlds"):
        shutil.copytree(src / sub, dst / sub)
    for gz in (dst / "models").rglob("*.dae.gz"):
        with gzip.open(gz) as fin, open(gz.with_suffix(""), "wb") as fout:
            shutil.copyfileobj(fin, fout)
    return dst


def aws_layout_world(path: Path, models: list[str], extra: str = "") -> Path:
    """A world written as the AWS RoboMaker worlds are: each model a link-less ``<model>`` wrapping an
    ``<include>`` (``<pose frame=''>`` after it, as they write it); the second copy of the first model says
    ``<static> true </static>`` on the wrapper (their CookingBench)."""
    body = [f"<model name='{m}_{k:03d}'><include><uri>model://{m}</uri></include>"
            f"<pose frame=''>{40 * k} {10 * (k % 2)} 0 0 0 {0.3 * k}</pose></model>" for k, m in enumerate(models)]
    body.append(f"<model name='{models[0]}_again'><include><uri>model://{models[0]}</uri></include>"
                f"<pose frame=''>0 -60 0 0 0 0</pose><static> true </static></model>")
    path.write_text(f"<?xml version='1.0'?>\n<sdf version='1.6'><world name='default'>{SPHERICAL}\n"
                    + "\n".join(body) + extra + "\n</world></sdf>\n")
    return path


def _ball(models: Path) -> None:
    """A model that moves (no <static>): AWS's Ball_01."""
    d = models / "ball"
    d.mkdir(parents=True, exist_ok=True)
    (d / "model.sdf").write_text("<?xml version='1.0'?><sdf version='1.6'><model name='ball'><link name='link'>"
                                 "<collision name='collision'><geometry><sphere><radius>0.2</radius></sphere>"
                                 "</geometry></collision></link></model></sdf>")


def _load(world: Path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)                  # nothing skipped
        warnings.simplefilter("ignore", LeftOutWarning)
        warnings.simplefilter("ignore", DroppedTrianglesWarning)      # zero-area triangles of the meshes
        return load_scene(str(world), options=VisibilityOptions(**kw)).world


# ------------------------------------------------------------------ every building in the scene
def test_aws_layout_keeps_every_static_model(shared_models, tmp_path, monkeypatch):
    models = tmp_path / "models"
    _ball(models)
    monkeypatch.setenv("GAZEBO_MODEL_PATH", os.pathsep.join([str(shared_models), str(models)]))
    w = aws_layout_world(tmp_path / "small_house.world", list(BUILDINGS) + ["ball"])
    expected = static_collisions(w, [shared_models, models])
    assert len(expected) == len(BUILDINGS) + 1 and not any(m.startswith("ball") for m in expected)
    world = _load(w)
    assert models_in_scene(world.parts, expected) == set(expected)
    # the ball moves: left out on purpose and said so, not lost
    assert [it["part"] for it in world.report["left_out"]] == [f"ball_{len(BUILDINGS):03d}::ball"]
    assert world.report["skipped"] == []


def test_hong_kong_city_world_keeps_its_buildings(hk_city, monkeypatch):
    monkeypatch.setenv("GZ_SIM_RESOURCE_PATH", str(hk_city / "models"))
    w = hk_city / "worlds" / "hong_kong_city_only.world"
    expected = static_collisions(w, [hk_city / "models"])
    assert list(expected) == ["hong_kong::hk_city"]
    world = _load(w)
    assert models_in_scene(world.parts, expected) == set(expected)
    assert world.report["left_out"] == []
    # a ray along a street at 1.5 m height hits a wall within the city's extent (E -613..613, N -724..724 m)
    scene = load_scene(str(w))
    t = scene.rays.hit_distance(np.array([[0.0, 0.0, 1.5]]), np.array([[1.0, 0.0, 0.0]]))
    assert np.isfinite(t[0]) and t[0] < 613


# ------------------------------------------------------------------ one failure for every front end
def _house_world(tmp_path: Path) -> Path:
    """A small world of our own (no shared data): a wrapper model around model://house (a static box), a
    ground plane."""
    house = tmp_path / "models" / "house"
    house.mkdir(parents=True)
    (house / "model.sdf").write_text("<?xml version='1.0'?><sdf version='1.6'><model name='house'><static>true"
                                     "</static><link name='l'><collision name='c'><geometry><box><size>4 4 6</size>"
                                     "</box></geometry></collision></link></model></sdf>")
    w = tmp_path / "town.sdf"
    w.write_text(f"<?xml version='1.0'?><sdf version='1.6'><world name='town'>{SPHERICAL}<model name='house_1'>"
                 "<include><uri>model://house</uri></include><pose>10 0 0 0 0 0</pose></model>"
                 "<model name='ground'><static>true</static><link name='l'><collision name='c'><geometry><plane>"
                 "<normal>0 0 1</normal><size>100 100</size></plane></geometry></collision></link></model>"
                 "</world></sdf>")
    return w


@pytest.fixture(params=["own", "hong_kong"])
def world_without_models(request, tmp_path):
    """(world file, model named in the error, folder that would hold it)."""
    if request.param == "own":
        w = _house_world(tmp_path)
        return w, "house_1", tmp_path / "models"
    hk = request.getfixturevalue("hk_city")
    return hk / "worlds" / "hong_kong_city_only.world", "hong_kong", hk / "models"


def _commands(w: Path, tmp_path: Path) -> dict[str, list[str]]:
    return {
        "export-world": ["export-world", str(w), "--out", str(tmp_path / "x.ply")],
        "skyplot": ["skyplot", "--world", str(w), "--at", "0,0,1.5", "--time", "2022-01-01T00:05:00", "--synthetic",
                    "--csv", str(tmp_path / "sky.csv")],
        "simulate": ["simulate", "--world", str(w), "--position", "22.3,114.17,10", "--duration", "5",
                     "--synthetic", "--out", str(tmp_path / "sim")],
    }


def test_missing_model_path_stops_every_front_end(world_without_models, tmp_path, capsys):
    w, model, _ = world_without_models
    for name, argv in _commands(w, tmp_path).items():
        assert main(argv) == 2, name
        err = capsys.readouterr().err
        assert f"world {w}: cannot load {model}" in err, (name, err)
        assert "cannot find 'model://" in err and "GZ_SIM_RESOURCE_PATH" in err, (name, err)
        assert "--allow-partial" in err and "Traceback" not in err, (name, err)
        assert len(err.strip().splitlines()) == 1, (name, err)
    assert not (tmp_path / "x.ply").exists() and not (tmp_path / "sky.csv").exists()


def test_allow_partial_runs_with_a_warning(world_without_models, tmp_path, capsys):
    w, model, _ = world_without_models
    commands = _commands(w, tmp_path)
    export = commands.pop("export-world") + ["--allow-partial"]
    for name, argv in commands.items():
        assert main(argv + ["--allow-partial"]) == 0, name
        err = capsys.readouterr().err            # one warning line naming the part and why (cli.route_messages)
        assert f"gnss-sim {name}: warning: skipped {model}" in err and "cannot find 'model://" in err, (name, err)
    assert (tmp_path / "sky.csv").is_file()
    # export-world lists the skipped part in its report (and a mesh of nothing is still no mesh)
    rc = main(export)
    out, err = capsys.readouterr()
    if model == "house_1":
        assert rc == 0 and "skipped: 1" in out and "house_1::model://house: " in out, (out, err)
    else:
        assert rc == 2 and "no collision geometry loaded" in err, err


def test_with_the_model_path_every_front_end_runs(world_without_models, tmp_path, monkeypatch, capsys):
    w, _, models = world_without_models
    monkeypatch.setenv("GZ_SIM_RESOURCE_PATH", str(models))
    for name, argv in _commands(w, tmp_path).items():
        with warnings.catch_warnings():
            warnings.simplefilter("error", SceneWarning)
            warnings.simplefilter("ignore", DroppedTrianglesWarning)
            assert main(argv) == 0, (name, capsys.readouterr().err)
    capsys.readouterr()


def test_run_and_its_visibility_node_stop_the_same_way(tmp_path):
    """`gnss-sim run`: the visibility node loads the world through the same load_scene and fails on configure."""
    pytest.importorskip("rclpy", reason="rclpy is not installed (run make test, or source ROS 2)")
    pytest.importorskip("gnss_sim_msgs", reason="gnss_sim_msgs is not built (run make test)")
    import subprocess
    import sys

    w = _house_world(tmp_path)
    env = {k: v for k, v in os.environ.items() if k != "ROS_DOMAIN_ID"}
    cmd = [sys.executable, "-m", "gnss_sim_ros2.cli", "run", "--world", str(w), "--duration", "2", "--no-record",
           "--quiet"]
    r = subprocess.run(cmd + ["--out", str(tmp_path / "a")], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode != 0
    assert f"configure failed: node gnss_sim_visibility: world {w}: cannot load house_1" in r.stderr
    assert "--allow-partial" in r.stderr and "Traceback" not in r.stderr
    r = subprocess.run(cmd + ["--out", str(tmp_path / "b"), "--allow-partial"], capture_output=True, text=True,
                       timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    assert "skipped house_1::model://house" in r.stderr


def test_strict_world_parameter_and_node_options():
    from gnss_sim_ros2.parameters import defaults, param

    p = param("visibility", "strict_world")
    assert p.default is True and "--allow-partial" in p.description
    assert VisibilityOptions.from_params(defaults().node("visibility")).strict_world is True
    assert VisibilityOptions().strict_world is True


# ------------------------------------------------------------------ gz:: names
def test_gz_double_colon_names_load(tmp_path):
    w = tmp_path / "sensors_like.sdf"
    w.write_text('<?xml version="1.0" ?>\n<!-- gz-sim examples/worlds/sensors.sdf style -->\n<sdf version="1.6">\n'
                 '<world name="sensors">\n'
                 '<plugin filename="gz-sim-forcetorque-system" name="gz::sim::systems::ForceTorque">\n'
                 '  <gz::system_priority>10</gz::system_priority>\n</plugin>\n'
                 '<plugin filename="gz-sim-imu-system" name="gz::sim::systems::Imu" gz::system_priority="5"/>\n'
                 '<model name="ground_plane"><static>true</static><link name="link"><collision name="collision">'
                 '<geometry><plane><normal>0 0 1</normal><size>100 100</size></plane></geometry></collision>'
                 '</link></model>\n<model name="sensors_box"><link name="link"><collision name="c"><geometry>'
                 '<box><size>0.1 0.1 0.1</size></box></geometry></collision></link></model>\n</world>\n</sdf>\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LeftOutWarning)
        world = load_sdf_world(w, strict=True)
    assert [p["name"] for p in world.parts] == ["ground_plane::link::collision"]
    assert [it["part"] for it in world.report["left_out"]] == ["sensors_box"]


def test_gz_sim_sensors_world(tmp_path):
    f = SHARED_WORLDS / "gz-sim" / "sensors.sdf"
    if not f.is_file():
        pytest.skip(f"{f} is absent (gz-sim examples/worlds/sensors.sdf is not in ../shared/worlds)")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LeftOutWarning)
        world = load_sdf_world(f, strict=True)
    assert "ground_plane::link::collision" in [p["name"] for p in world.parts]


# ------------------------------------------------------------------ bad triangles
def test_nan_vertex_obj_is_dropped_and_the_rest_blocks(tmp_path, capsys):
    obj = tmp_path / "wall.obj"
    # a wall at x = 5 m (2 triangles), a triangle with a NaN corner, a zero-area one (two corners equal)
    obj.write_text("v 5 -10 0\nv 5 10 0\nv 5 10 20\nv 5 -10 20\nv 0 0 nan\nv 1 0 0\nv 1 1 0\nv 2 2 2\n"
                   "f 1 2 3\nf 1 3 4\nf 5 6 7\nf 8 8 6\n")
    w = tmp_path / "walls.sdf"
    w.write_text(f"<?xml version='1.0'?><sdf version='1.9'><world name='w'>{SPHERICAL}"
                 "<model name='wall'><static>true</static><link name='l'><collision name='c'><geometry><mesh>"
                 "<uri>wall.obj</uri></mesh></geometry></collision></link></model>"
                 "<model name='post'><static>true</static><pose>0 8 0 0 0 0</pose><link name='l'>"
                 "<collision name='c'><geometry><box><size>1 1 4</size></box></geometry></collision></link></model>"
                 "</world></sdf>")
    with pytest.warns(DroppedTrianglesWarning, match=rf"{obj}: dropped 2 of 4 triangles .*1 with a NaN.*1 degenerate"):
        scene = load_scene(str(w))
    assert len(scene.world.triangles) == 2 + 12
    assert np.all(np.isfinite(scene.world.vertices_m))
    assert scene.world.report["dropped"][0]["file"] == str(obj)
    o = np.array([[0.0, 0.0, 1.0]])
    d = np.array([[1.0, 0.0, 0.0], [1.0, 0.2, 0.3], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    assert scene.rays.occluded(o, d).tolist() == [True, True, True, False]   # wall, wall, post, open
    # export-world says so in its report, and writes the rest
    assert main(["export-world", str(w), "--out", str(tmp_path / "walls.ply")]) == 0
    out = capsys.readouterr().out
    assert f"dropped 2 of 4 triangles of {obj}" in out and "14 triangles" in out


def test_zero_area_triangles_alone_are_dropped_without_a_warning(tmp_path):
    """Zero-area triangles (1,150 in each of the Hong Kong city's meshes) lose no geometry: counted in the
    scene report, no warning a user must read at every load."""
    import warnings

    from gnss_sim_ros2.core.scene.mesh_files import SubMesh, drop_bad_triangles

    v = np.array([[5, -10, 0], [5, 10, 0], [5, 10, 20], [2, 2, 2]], dtype=float)
    faces = np.array([[0, 1, 2], [3, 3, 1]])
    with warnings.catch_warnings():
        warnings.simplefilter("error", DroppedTrianglesWarning)
        subs, info = drop_bad_triangles([SubMesh("m", v, faces, ["m"])], tmp_path / "m.dae")
    assert info["degenerate"] == 1 and info["non_finite"] == 0 and info["triangles"] == 1
    assert [len(s.faces) for s in subs] == [1]
