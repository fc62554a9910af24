"""One parameter path: the offline run (``gnss-sim simulate``, core/simulation.py) builds its receiver chain and its
visibility options from the parameters the receiver and visibility nodes get from the same configuration, every
parameter of the table included, so a parameter cannot be dropped offline without this test failing."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from gnss_sim_ros2 import graph
from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.receiver.chain import ChainSettings
from gnss_sim_ros2.core.scene.demo_world import demo_world_path
from gnss_sim_ros2.core.simulation import chain_settings, setup_from_config, visibility_options
from gnss_sim_ros2.core.visibility import VisibilityOptions
from gnss_sim_ros2.parameters import SHARED, SHARED_KEY, params_of

REPO = Path(__file__).resolve().parents[1]

#: values the generic rule below would make invalid (a rule between parameters, a format, a file that must exist)
OTHER_VALUES = {"start_time": "2025-06-02T11:00:00", "systems": "GE", "cn0_lose_dbhz": 20.0,
                "antenna_position": [1.0, 2.0, 3.0], "profile": "ublox_f9p",
                "scenario": str(REPO / "config" / "scenarios" / "courtyard_threats.yaml"),
                "obstacle_models": ["bus"]}
#: parameters another one must accompany (rules between parameters of the table)
PARTNERS = {"obstacle_models": {"obstacle_pose_topic": "/world/demo/dynamic_pose/info"}}


def other_value(p, tmp_path=None):
    """A valid value of parameter ``p`` other than its default (files it names written under ``tmp_path``)."""
    if p.name == "sky_mask_csv":
        mask = tmp_path / "mask.csv"
        mask.write_text("azimuth_deg,elevation_deg\n" + "".join(f"{a},{15 + a % 20}\n" for a in range(0, 360, 10)))
        return str(mask)
    if p.name in OTHER_VALUES:
        return OTHER_VALUES[p.name]
    if p.choices:
        return next(c for c in p.choices if c != p.default)
    if isinstance(p.default, bool):
        return not p.default
    if isinstance(p.default, (int, float)):
        step = 1 if isinstance(p.default, int) else 0.5
        return next(v for v in (p.default + step, p.default - step)
                    if (p.min is None or v >= p.min) and (p.max is None or v <= p.max))
    if isinstance(p.default, list):
        if p.item_type == "string" or (p.default and isinstance(p.default[0], str)):
            return [*p.default, "other"]
        return [v + 1.0 for v in p.default] or [1.0, 2.0, 3.0]
    return p.default + "_other"


def node_params(cfg, key: str) -> dict:
    """The parameters the node ``key`` of the graph gets from ``cfg`` (what `gnss-sim run` and the launch give it)."""
    [spec] = [s for s in graph.nodes() if s.key == key]
    return graph.node_parameters(cfg, spec)


def config_with(key: str, p, value):
    """The default configuration with ``p`` (of node ``key``) set to ``value``, and a world given (a node loads the
    demo courtyard for none, as the offline run does along the player's path; a sky mask is the scene instead, of
    a static antenna)."""
    if p.name == "sky_mask_csv":
        overrides = {"visibility": {"antenna_position": [22.3, 114.17, 10.0], "antenna_position_type": "llh"}}
    else:
        overrides = {"visibility": {"world_file": str(demo_world_path())}}
    overrides.setdefault(SHARED_KEY if p in SHARED else key, {})[p.name] = value
    overrides.setdefault(key, {}).update(PARTNERS.get(p.name, {}))
    return load_config(None, overrides)


CASES = [(key, p) for key in ("receiver", "visibility") for p in params_of(key)]


@pytest.mark.parametrize(("key", "p"), CASES, ids=[f"{k}.{p.name}" for k, p in CASES])
def test_every_parameter_reaches_the_offline_chain_as_the_node_gets_it(tmp_path, key, p):
    value = other_value(p, tmp_path)
    cfg = config_with(key, p, value)
    rcv, vis = node_params(cfg, "receiver"), node_params(cfg, "visibility")
    assert (rcv if key == "receiver" else vis)[p.name] == value          # the node gets the value set
    setup = setup_from_config(cfg, tmp_path / "out")
    # the parameters the offline chain and visibility step are built from: the nodes' own, every one
    assert setup.receiver_params == rcv
    assert setup.visibility_params == vis
    # and what is built from them: as the node builds it, writing into the run's folder with the ephemeris at hand
    node_chain = ChainSettings.from_params({**rcv, "output_dir": str(Path(setup.out_dir))}, have_ephemeris=True)
    assert repr(chain_settings(setup)) == repr(node_chain)
    assert visibility_options(setup) == VisibilityOptions.from_params(vis)


def test_a_parameter_set_on_a_setup_reaches_the_chain(tmp_path):
    """SimulationSetup.with_params sets a parameter in each node holding it; an unknown name is an error."""
    setup = setup_from_config(load_config(), tmp_path).with_params(cn0_acquire_dbhz=40.0, multipath="full",
                                                                   elevation_mask_deg=15.0)
    assert chain_settings(setup).receiver.tracking.acquisition_cn0_dbhz == 40.0
    assert visibility_options(setup).multipath == "full"
    assert chain_settings(setup).solver.elevation_mask_deg == visibility_options(setup).mask_deg == 15.0
    assert dataclasses.replace(setup).ephemeris_params["elevation_mask_deg"] == 15.0
    with pytest.raises(ValueError, match="'multipath_rays'.*no node"):
        setup.with_params(multipath_rays=3)


def test_a_profile_file_reaches_the_offline_chain_as_the_node_gets_it(tmp_path, monkeypatch):
    """A profile given as a file (relative to the working directory): the receiver node and the offline run get
    the same absolute path and build the same chain from it (the file's values in the receiver configuration)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "rx.yaml").write_text("gnss_sim_profile: 1\nsignals: {G: [1C, 2L], E: [1C]}\nantenna: choke_ring\n"
                                      "dll_bn_hz: 0.125\n"
                                      "tracking: {acquisition_cn0_dbhz: 31.0, tracking_cn0_dbhz: 26.0}\n")
    cfg = load_config(None, {"receiver": {"profile": "rx.yaml"}, "visibility": {"world_file": str(demo_world_path())}})
    rcv = node_params(cfg, "receiver")
    assert rcv["profile"] == str(tmp_path / "rx.yaml")
    setup = setup_from_config(cfg, tmp_path / "out")
    assert setup.receiver_params == rcv
    node_chain = ChainSettings.from_params({**rcv, "output_dir": str(Path(setup.out_dir))}, have_ephemeris=True)
    offline = chain_settings(setup)
    assert repr(offline) == repr(node_chain)
    r = offline.receiver
    assert r.profile == {"G": ["1C", "2L"], "E": ["1C"]} and (r.antenna, r.dll_bn_hz) == ("choke_ring", 0.125)
    assert (r.tracking.acquisition_cn0_dbhz, r.tracking.tracking_cn0_dbhz) == (31.0, 26.0)
