"""Every gnss_sim parameter, once: name, type, default, unit, range, meaning.

One configuration file drives both the ROS launch and the offline tools.  It
is an ordinary ROS 2 parameter file::

    /**:                       # shared by every gnss_sim node
      ros__parameters:
        systems: GRE
    gnss_sim_receiver:         # one node's own parameters
      ros__parameters:
        profile: single_frequency

``launch/sim.launch.py`` hands that file to the nodes; ``gnss-sim run`` and
``gnss-sim simulate --config`` read it through :func:`load_config`, so a user
never writes a setting twice.  ``config/gnss_sim.yaml`` lists every parameter
with its default; a test keeps it equal to this table.

This module is ROS-free: the nodes turn the table into parameter descriptors.
"""
from __future__ import annotations

import datetime as _dt
import difflib
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from gnss_sim_ros2.core.demo import DEMO_START
from gnss_sim_ros2.core.multipath.lms import LMS_ENVIRONMENTS
from gnss_sim_ros2.core.vocabulary import (
    EPHEMERIS_SOURCES,
    IONOSPHERE_MODELS,
    MULTIPATH_MODES,
    PRESET_NAMES,
    SYSTEMS,
    TRACKING_STARTS,
    TROPOSPHERE_MODELS,
    check_systems,
)

#: ROS node names (the keys of a parameter file)
NODE_NAMES = {
    "ephemeris": "gnss_sim_ephemeris",
    "visibility": "gnss_sim_visibility",
    "receiver": "gnss_sim_receiver",
    "trajectory": "gnss_sim_trajectory_player",
    "rtk": "gnss_sim_rtk",
    "quality_map": "gnss_sim_quality_map",
}
SHARED_KEY = "/**"


@dataclass(frozen=True)
class Param:
    name: str
    default: Any
    description: str
    choices: tuple = ()
    min: float | None = None
    max: float | None = None
    #: element type for an empty list default ("string" or "double")
    item_type: str = ""
    #: further check of the value: returns it normalised or raises ValueError naming ``where``
    check_value: Callable[[Any, str], Any] | None = None
    #: a shared parameter that must have one value in the whole graph (refused in a node's section);
    #: False: a node's section may narrow it (e.g. the receiver tracks fewer systems than served)
    shared_only: bool = True

    @property
    def kind(self) -> str:
        if isinstance(self.default, bool):
            return "bool"
        if isinstance(self.default, int):
            return "integer"
        if isinstance(self.default, float):
            return "double"
        if isinstance(self.default, str):
            return "string"
        if isinstance(self.default, list):
            item = self.item_type or ("double" if self.default and isinstance(self.default[0], float) else "string")
            return f"{item}_array"
        raise TypeError(f"parameter {self.name}: unsupported default {self.default!r}")

    def check(self, value, where: str):
        """Validated (and type-normalised) value; ValueError naming the parameter and ``where``."""
        kind = self.kind
        bad = ValueError(f"{where}: parameter '{self.name}' must be {kind}, got {value!r}"
                         + (_yaml_bool_hint(value, self.choices) if kind.startswith("string") else ""))
        if kind == "bool":
            if not isinstance(value, bool):
                raise bad
        elif kind == "integer":
            if isinstance(value, bool) or not isinstance(value, int):
                raise bad
            if not -2**63 <= value < 2**63:        # a ROS 2 integer parameter is an int64 (rcl_interfaces)
                raise ValueError(f"{where}: parameter '{self.name}' is {value}; an integer parameter is 64-bit "
                                 f"(-2**63..2**63-1)")
        elif kind == "double":
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise bad
            value = _as_double(value, where, self.name)
            if not math.isfinite(value):
                raise ValueError(f"{where}: parameter '{self.name}' is {value!r}; a finite number is needed")
        elif kind == "string":
            if not isinstance(value, str):
                raise bad
        else:
            if not isinstance(value, (list, tuple)):
                raise bad
            if kind == "double_array":
                if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
                    raise bad
                value = [_as_double(v, where, self.name) for v in value]
                if not all(math.isfinite(v) for v in value):
                    raise ValueError(f"{where}: parameter '{self.name}' = {value!r}: every number must be finite")
            elif not all(isinstance(v, str) for v in value):
                raise bad
            value = list(value)
        if self.choices and value not in self.choices:
            raise ValueError(f"{where}: parameter '{self.name}' is {value!r}; expected one of {list(self.choices)}")
        if self.min is not None and value < self.min:
            raise ValueError(f"{where}: parameter '{self.name}' is {value!r}; minimum is {self.min}")
        if self.max is not None and value > self.max:
            raise ValueError(f"{where}: parameter '{self.name}' is {value!r}; maximum is {self.max}")
        if self.check_value is not None:
            value = self.check_value(value, f"{where}: parameter '{self.name}'")
        return value


def _as_double(value, where: str, name: str) -> float:
    """float(value); an integer beyond a double's range (1e308) is refused naming the parameter."""
    try:
        return float(value)
    except OverflowError:
        raise ValueError(f"{where}: parameter '{name}' is an integer of {len(str(abs(value)))} digits; "
                         f"too large for a double") from None


def _yaml_bool_hint(value, choices) -> str:
    """The hint for a string parameter given a boolean: YAML 1.1 (PyYAML, ROS 2 parameter files) reads an unquoted
    yes/no/on/off/true/false as one (YAML 1.1 bool type, https://yaml.org/type/bool.html); '' for other values."""
    flags = [v for v in (value if isinstance(value, (list, tuple)) else [value]) if isinstance(v, bool)]
    if not flags:
        return ""
    words = ("on", "yes", "true") if flags[0] else ("off", "no", "false")
    word = next((f"'{w}'" for w in words if w in (choices or ()) or not choices), "the word")
    return f" (YAML 1.1 reads an unquoted {' / '.join(words)} as a boolean: write {word} in quotes)"


def _check_box_size(value: list, where: str) -> list:
    """3 positive box dimensions [m] (length, width, height of an obstacle's box)."""
    if len(value) != 3 or not all(v > 0 for v in value):
        raise ValueError(f"{where} = {value!r}: needs 3 positive numbers [m] (length along x, width along y, "
                         f"height along z of the obstacle's frame)")
    return value


#: the span of GNSS time this simulator supports: the GPS epoch to the end of the leap-second table's use
SUPPORTED_SPAN = (_dt.datetime(1980, 1, 6), _dt.datetime(2100, 1, 1))


def _check_scenario(value: str, where: str) -> str:
    """A threat scenario file read and validated (core/threats/scenario.py), kept as its absolute path; empty:
    none."""
    if not value:
        return value
    from gnss_sim_ros2.core.threats.scenario import load_scenario

    try:
        return load_scenario(value).source
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def _check_profile(value: str, where: str) -> str:
    """A receiver profile loaded and validated (core/receiver/profiles.py): a built-in name as it is, a file as
    an absolute path (a run's params.yaml then works from any folder)."""
    from gnss_sim_ros2.core.receiver.profiles import is_path, load_profile

    try:
        prof = load_profile(value)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    return prof.path if is_path(value) else value


#: largest |component| of world_offset_enu_m [m]
MAX_WORLD_OFFSET_M = 1000.0


def _check_sky_mask(value: str, where: str) -> str:
    """A sky mask CSV read and checked (core/visibility/sky_mask.py: errors name the file and line), kept as its
    absolute path; empty: none."""
    if not value:
        return value
    from pathlib import Path

    from gnss_sim_ros2.core.visibility.sky_mask import read_sky_mask

    try:
        read_sky_mask(value)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None      # ``where`` names the parameter (Param.check)
    return str(Path(value).resolve())


def _check_frame_id(value: str, where: str) -> str:
    """A TF frame id: not empty, no whitespace, no leading '/' (tf2 refuses it: "frame_id should not start with
    a '/'", tf2 BufferCore::validateFrameId)."""
    if not value or value.startswith("/") or any(c.isspace() for c in value):
        raise ValueError(f"{where} is {value!r}: a TF frame id is a non-empty name without whitespace and without "
                         f"a leading '/'")
    return value


def _check_optional_frame_id(value: str, where: str) -> str:
    """'' (none) or a TF frame id (:func:`_check_frame_id`)."""
    return value and _check_frame_id(value, where)


def _check_marker_name(value: str, where: str) -> str:
    """A RINEX MARKER NAME: printable ASCII of at most 60 characters (RINEX 3.05 table A2, format A60); no '/' or
    '\\' either: its first 4 characters start the file names (rinex_name)."""
    bad = next((c for c in value if not " " <= c <= "~" or c in "/\\"), None)
    if bad is not None or len(value) > 60:
        why = f"character {bad!r}" if bad is not None else f"{len(value)} characters"
        raise ValueError(f"{where} is {value!r}: {why}; a RINEX marker name is printable ASCII of at most 60 "
                         f"characters, without / or \\")
    if not value[:4].strip() or " " in value[:4]:       # '' wrote XXXX00XXX_..., ' A' a file name with a space
        raise ValueError(f"{where} is {value!r}: the RINEX file names start with its first 4 characters (RINEX 3.05 "
                         f"section 4.1: the 4-character site name), which must not be empty or hold a space")
    return value


def check_iso_time(value: str, where: str) -> str:
    from gnss_sim_ros2.core.time import GnssTime

    try:
        t = GnssTime.from_iso(value)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None
    d = t.to_datetime()
    if not SUPPORTED_SPAN[0] <= d < SUPPORTED_SPAN[1]:
        raise ValueError(f"{where} is {value!r}: outside the supported span "
                         f"{SUPPORTED_SPAN[0]:%Y-%m-%d} .. {SUPPORTED_SPAN[1]:%Y-%m-%d}")
    return value


#: the longest simulated span [s]: ephemerides are prepared for the whole span up front (synthetic records, one
#: downloaded navigation file per day, the GLONASS slots of the RINEX header), a month at most
MAX_DURATION_S = 31 * 86400.0
#: the most epochs one run takes (duration_s x rate_hz): a RINEX observation file takes about 7.6 kB per epoch
#: (geodetic profile, GRECJI: 274 MB for 36001 epochs) and the offline run about 1.3 kB of memory per epoch (peak
#: RSS 175 MB at 3600 epochs, 216 MB at 36000): 1e6 epochs, e.g. a day at 10 Hz, ~7.6 GB of RINEX
MAX_EPOCHS = 1_000_000
#: the most robots one fleet visibility / receiver node serves (the fleet layout: graph.py)
MAX_FLEET_ROBOTS = 64

#: how a static antenna position is given (parameters antenna_position_type, base_position_type)
POSITION_TYPES = ("world", "llh", "ecef")


def check_position(value: list, kind: str, name: str, where: str) -> list:
    """A static antenna position of ``kind`` (POSITION_TYPES): 3 numbers; llh and ecef within the receivers the
    simulator models (core/frames.py check_receiver_position, the one rule for parameters, options and path
    files), else ValueError naming ``name`` and ``where``."""
    if len(value) != 3:
        raise ValueError(f"{where}: parameter '{name}' needs 3 numbers ({kind}), got {value!r}")
    if kind in ("llh", "ecef"):
        from gnss_sim_ros2.core.frames import check_receiver_position

        check_receiver_position(value, kind, f"{where}: parameter '{name}' = {value!r} ({kind})")
    return value


SHARED = [
    Param("systems", SYSTEMS, "GNSS systems simulated, RINEX letters: G GPS, R GLONASS, E Galileo, C BeiDou, "
          "J QZSS, I NavIC; a node's section may narrow it", check_value=check_systems, shared_only=False),
    Param("start_time", DEMO_START, "GNSS (GPS) time of the first epoch, ISO 8601; with "
          "time_mapping=offset the ROS time 0 maps to it", check_value=check_iso_time),
    Param("rate_hz", 1.0, "epoch rate [Hz]", min=0.001, max=100.0),
    Param("elevation_mask_deg", 10.0, "elevation mask [deg]: satellites below are neither cast nor tracked",
          min=-5.0, max=90.0),
    Param("world_frame", "world", "TF frame of the Gazebo world (ENU at spherical_coordinates)",
          check_value=_check_frame_id),
    Param("antenna_frame", "gnss_antenna", "TF frame of the receiver antenna phase centre",
          check_value=_check_frame_id),
    Param("antenna2_frame", "", "TF frame of a second antenna on the robot: with gnss-sim run --rtk / rtk:=true a "
          "second rover receiver there and rtkrcv in moving-base mode give the heading (/gnss/rtk/heading); "
          "empty: none", check_value=_check_optional_frame_id),
    Param("seed", 1, "seed of every random process (noise, clock, ambiguities)", min=0, shared_only=False),
    Param("output_dir", "gnss_sim_output", "folder of the RINEX observation/navigation (and NMEA) files; "
          "empty: none written"),
    Param("marker_name", "GSIM", "RINEX marker name (its first 4 characters start the file names)",
          check_value=_check_marker_name),
    Param("preset", "balanced", "fidelity preset: default values of the model switches",
          choices=PRESET_NAMES),
]

#: the fleet layout's nodes (gnss-sim run --layout fleet, composed:=fleet): one visibility and one receiver node
#: serving robots 0..N-1 (their frames robot<k>/..., topics /robot<k>/gnss/...; one robot: the root's)
FLEET_ROBOTS = Param("fleet_robots", 1, "robots this node serves in the fleet layout (gnss-sim run --layout fleet, "
                     "composed:=fleet; set by the layout): one cast of every robot's antenna per epoch, one receiver "
                     "chain per robot (seed + k, frames robot<k>/..., topics /robot<k>/gnss/...), every robot's TF "
                     "from one player in one message per tick; 1 in the other layouts", min=1, max=MAX_FLEET_ROBOTS)

NODE_PARAMS: dict[str, list[Param]] = {
    "ephemeris": [
        Param("source", "synthetic", "where orbits come from", choices=EPHEMERIS_SOURCES),
        Param("nav_files", [], "RINEX 2/3/4 navigation files (source broadcast; gz/Z/crx accepted)",
              item_type="string"),
        Param("sp3_files", [], "SP3 precise orbit files (source sp3)", item_type="string"),
        Param("clk_files", [], "RINEX clock files to go with the SP3 files", item_type="string"),
        Param("download_cache_dir", "", "cache of downloaded navigation files (source download); "
              "empty: ~/.cache/gnss_sim"),
        Param("time_mapping", "offset", "ROS time -> GNSS time: offset (ROS time 0 = start_time; simulated "
              "clocks) or utc (ROS stamps are UNIX UTC)", choices=("offset", "utc")),
        Param("duration_s", 600.0, "simulated span [s] for which ephemerides are prepared; at most 31 days and "
              "1e6 epochs at rate_hz (MAX_DURATION_S, MAX_EPOCHS)", min=1.0, max=MAX_DURATION_S),
    ],
    "visibility": [
        Param("world_file", "", "Gazebo SDF world (exported to a mesh on configure); empty: the demo courtyard"),
        Param("mesh_file", "", "mesh exported by `gnss-sim export-world` (overrides world_file)"),
        Param("materials_file", "", "YAML of material classes by name pattern"),
        Param("use_visuals", False, "export visual instead of collision geometry"),
        Param("keep_dynamic_models", False, "also take the world's non-static models (robots, movable objects) "
              "as static obstacles; default: only static models block"),
        Param("strict_world", True, "a world whose scene would lack geometry it names (a model:// or mesh not "
              "found, an uncached Fuel model) is an error naming the model and why; false: a partial world, each "
              "missing part skipped with a warning (gnss-sim --allow-partial)"),
        # at most 256: the blocked fraction in steps of 0.4 %; memory grows ~1.2 MB per ray for a block of 300
        # epochs (simulate, courtyard: peak RSS 335 MB at 8 rays, 378 MB at 64, 611 MB at 256)
        Param("fresnel_rays", -1, "rays over the first Fresnel zone per satellite (0 off; -1 from preset; at most "
              "256)", min=-1, max=256),
        Param("multipath", "", "reflections from the scene (core/multipath): off, nlos (blocked satellites "
              "only), full (every satellite), auto (full for an antenna with walls within multipath_range_m at "
              "that epoch, off elsewhere at no cost: core/presets.py); empty: from preset (balanced: auto)",
              choices=("", *MULTIPATH_MODES)),
        Param("multipath_range_m", 100.0, "facets farther than this from the antenna reflect nothing [m]",
              min=1.0, max=2000.0),
        Param("multipath_max_paths", 3, "reflected paths kept per satellite (the strongest)", min=1, max=10),
        Param("multipath_bounces", 2, "with multipath on: 1 single bounces, 2 also double bounces between facing "
              "walls", min=1, max=2),
        Param("multipath_diffraction", False, "with multipath on: blocked satellites diffracted over the nearest roof "
              "or wall edge (ITU-R P.526 knife edge) are received weakened"),
        Param("multipath_scattering", False, "with multipath on: diffuse scattering from the walls (effective "
              "roughness, Lambertian, S = 0.4) adds paths to the specular ones"),
        Param("tf_timeout_s", 5.0, "wall-clock seconds after which an epoch whose antenna transform TF lacks is "
              "dropped (and `gnss-sim run` fails, naming the frames): counted once TF has reached the epoch's "
              "stamp without the frame, or while no node publishes /tf; a TF source that is alive but behind "
              "(a loaded machine) is waited for (tf_tree.FrameWait)", min=0.1, max=600.0),
        Param("sky_mask_csv", "", "a measured sky mask (CSV azimuth_deg,elevation_deg; docs/USER_GUIDE.md, Sky "
              "masks) as the scene of a static antenna instead of a world or mesh: a satellite under it is blocked; "
              "the antenna is antenna_position (llh or ecef) or the static position of `gnss-sim simulate`; "
              "empty: none", check_value=_check_sky_mask),
        Param("world_offset_enu_m", [], "a known georeference error applied on purpose: the world moved by east, "
              "north, up [m] against the Earth (3 numbers; what is placed in ECEF/geodetic sits at its world "
              "position minus it; `gnss-sim compare --fit-offset` reports (e, n): apply [-e, -n, 0]); logged when "
              "set; empty: none", item_type="double"),
        Param("antenna_position", [], "a static antenna (3 numbers in antenna_position_type) instead of "
              "antenna_frame looked up in TF, e.g. a base station; empty: from TF", item_type="double"),
        Param("antenna_position_type", "world", "what antenna_position holds: world (x, y, z in world_frame [m]), "
              "llh (latitude [deg], longitude [deg], ellipsoidal height [m]) or ecef (WGS 84 [m])",
              choices=POSITION_TYPES),
        Param("obstacle_frames", [], "TF frames of moving obstacles (other robots' base_link): a box of "
              "obstacle_box_size_m stands on each, looked up in world_frame at each epoch's stamp and blocking "
              "satellites on top of the static scene; a frame under the antenna_frame's prefix (robot<k>/) is the "
              "robot's own body and is left out", item_type="string"),
        Param("obstacle_box_size_m", [1.0, 0.7, 0.4], "size of an obstacle_frames box [m]: length along the frame's "
              "x, width along y, height along z, its base centred on the frame's origin",
              check_value=_check_box_size),
        Param("obstacle_models", [], "Gazebo models that move (cars, buses, people): their poses from "
              "obstacle_pose_topic, a box of obstacle_model_size_m on each", item_type="string"),
        Param("obstacle_model_size_m", [4.5, 1.8, 1.5], "size of an obstacle_models box (and of a gnss-sim simulate "
              "--obstacle-path box) [m]: length, width, height, base centred on the model's origin",
              check_value=_check_box_size),
        Param("obstacle_pose_topic", "", "tf2_msgs/TFMessage topic of the models' poses in world_frame (ros_gz_bridge "
              "of /world/<name>/dynamic_pose/info; child_frame_id = model name); empty: no model obstacles"),
        FLEET_ROBOTS,
    ],
    "receiver": [
        Param("profile", "geodetic", "receiver profile (signals, antenna, front end, loops, thresholds, noise): a "
              "built-in name (`gnss-sim profile list`) or a profile YAML file (docs/PROFILES.md), relative to the "
              "working directory; a file is kept as its absolute path",
              check_value=_check_profile),
        Param("noise", True, "receiver errors on (noise, clock wander, SISRE, ionosphere error, hardware code biases); "
              "off: an ideal receiver with the deterministic models"),
        Param("ionosphere", "", "true ionosphere (empty: from preset; auto: NeQuick-G where Galileo coefficients "
              "are given, else Klobuchar)", choices=("", *IONOSPHERE_MODELS)),
        Param("troposphere", "", "troposphere model (empty: from preset)", choices=("", *TROPOSPHERE_MODELS)),
        Param("write_nmea_file", False, "also write the NMEA sentences to output_dir/gnss_sim.nmea"),
        Param("smoothing_s", 100.0, "carrier smoothing window of the code the receiver's own fix uses (Hatch "
              "filter, RTCA DO-229) [s]; 0: raw code. RINEX and observations keep the raw code", min=0.0,
              max=3600.0),
        Param("rtcm", False, "publish each epoch as RTCM3 (station, MSM observations) on `rtcm` "
              "(std_msgs/UInt8MultiArray), e.g. for the rtk node or an outside RTK engine"),
        Param("rtcm_msm", 7, "RTCM3 MSM type: 7 (full resolution, Doppler) or 4", choices=(4, 7)),
        Param("rtcm_station_id", 0, "RTCM3 reference station id (DF003)", min=0, max=4095),
        Param("rtcm_tcp_port", 0, "with rtcm: also serve the RTCM3 stream on this TCP port to every client that "
              "connects (RTKLIB tcpcli, str2str, an NTRIP server); 0: none", min=0, max=65535),
        Param("rtcm_tcp_host", "127.0.0.1", "address the RTCM3 TCP server listens on (0.0.0.0: every interface)"),
        Param("cn0_acquire_dbhz", -1.0, "C/N0 above which a signal is acquired [dB-Hz]; -1: the profile's "
              "(geodetic 33, ublox 22)", min=-1.0, max=70.0),
        Param("cn0_lose_dbhz", -1.0, "C/N0 below which a signal is lost [dB-Hz]; -1: the profile's "
              "(geodetic 28, ublox 16)", min=-1.0, max=70.0),
        Param("tracking_start", "", "how the recording starts: warm (the receiver has long been running: tracks "
              "above the loss threshold at the first epoch are locked, no loss-of-lock or half-cycle flag) or cold "
              "(switched on at the first epoch: every track acquired then, flagged); empty: the profile's "
              "(tracking.start, default warm)", choices=("", *TRACKING_STARTS)),
        Param("scenario", "", "threat scenario file (YAML, docs/SCENARIOS.md): timed jammers, spoofers and receiver "
              "faults (core/threats), relative to the working directory, kept as its absolute path; empty: none",
              check_value=_check_scenario),
        Param("spoof_capture_margin_db", 3.0, "a scenario spoofer's counterfeit captures a signal (the receiver "
              "tracks it) when its power exceeds the authentic signal's by this margin [dB]; otherwise both "
              "interfere (docs/SCENARIOS.md; 3 dB: a design value above the 0 dB limit of an aligned counterfeit)",
              min=0.0, max=30.0),
        Param("scenario_world", "", "the scene of the scenario's jammers and spoofers in the receiver node: an SDF "
              "world or a mesh of `gnss-sim export-world` whose spherical_coordinates place world-frame positions "
              "and whose walls lie between transmitter and antenna, as offline; empty: the visibility node's "
              "mesh_file or world_file (the configuration copies it; the demo courtyard when both are empty)"),
        Param("lms_environment", "off", "land-mobile-satellite channel layered on the scene's rays (Perez-Fontan "
              "et al. 2001 3-state chain in ITU-R P.681's environment classes, Loo fading, DLR echo delays; "
              "core/multipath/lms.py): on satellites with a "
              "clear line of sight, shadowed / blocked states and a diffuse echo (what a 3D model lacks: street "
              "furniture, vehicles, trees). A choice about the world, not found in its geometry: off (default; a "
              "world that models its detail, as the demo courtyard), auto (a city model of building blocks only, as "
              "the Hong Kong one: per epoch from the share of satellites its buildings block: under 15 % nothing, "
              "else suburban or urban) or a class (docs/VALIDATION.md)", choices=LMS_ENVIRONMENTS),
        FLEET_ROBOTS,
    ],
    "trajectory": [
        Param("trajectory_file", "", "CSV t_s,e_m,n_m,u_m[,yaw_deg] in the world frame; empty: waypoints"),
        Param("waypoints", [], "flat list t_s,e_m,n_m,u_m,... (empty with no file: the demo path)",
              item_type="double"),
        Param("base_frame", "base_link", "robot frame the player moves", check_value=_check_frame_id),
        Param("antenna_offset_m", [0.0, 0.0, 0.5], "antenna position in base_frame [m] (static TF)"),
        Param("antenna2_offset_m", [-1.0, 0.0, 0.5], "with antenna2_frame: the second antenna's position in "
              "base_frame [m] (static TF; default 1 m behind the first)"),
        Param("publish_rate_hz", 20.0, "TF publish rate [Hz]", min=0.1, max=1000.0),
        Param("loop", False, "restart the path at its end"),
        Param("time_offset_s", 0.0, "path time at ROS time 0 [s]: the robot starts this far along its path "
              "(a convoy's robot k: k * convoy_spacing_s)", min=-1e6, max=1e6),
        Param("convoy_spacing_s", 5.0, "with several robots (gnss-sim run --robots N, robots:=N) on one path: "
              "robot k runs k times this far ahead of robot 0 along it [s of path time] (the demo path: 1 m/s)",
              min=0.0, max=3600.0),
        Param("robot_trajectory_files", [], "with several robots: one path CSV per robot (robot k takes entry k, "
              "no convoy offset); empty: the convoy along trajectory_file / waypoints / the demo path",
              item_type="string"),
        FLEET_ROBOTS,
    ],
    "rtk": [
        Param("rtkrcv_path", "", "RTKLIB rtkrcv executable; empty: rtkrcv on PATH (Debian package rtklib)"),
        Param("rtkrcv_conf", "", "a user's rtkrcv options file, kept as it is except the stream and output format "
              "options the node owns; empty: the generated RTK setup"),
        Param("rtk_systems", "", "systems RTK uses (pos1-navsys of the generated setup); empty: systems"),
        Param("rtk_mode", "kinematic", "positioning mode of the generated setup: kinematic, static, or movingbase "
              "(heading from two antennas of the robot)", choices=("kinematic", "static", "movingbase")),
        Param("rtk_frequencies", 2, "carrier frequencies of the generated setup (pos1-frequency: 1 l1, 2 l1+2, "
              "3 l1+2+3)", min=1, max=3),
        Param("rtk_ratio_threshold", 3.0, "ambiguity ratio test threshold of the generated setup (pos2-arthres)",
              min=1.0, max=100.0),
        Param("nav_files", [], "RINEX navigation files whose ephemerides the node sends to rtkrcv (its input stream 3) "
              "at the simulated time, for RTCM3 streams without ephemeris messages; empty: those of the streams",
              item_type="string"),
        Param("rtkrcv_clock", "auto", "rtkrcv's clock: simulated (started under faketime at the simulated time: RTCM3 "
              "carries times of week, RTKLIB takes the week from the clock), system, or auto (simulated when the "
              "simulated time is more than an hour from the system clock)", choices=("auto", "simulated", "system")),
        Param("autostart", True, "start rtkrcv on activate (else through the start service)"),
        Param("time_mapping", "offset", "ROS time <-> GNSS time of the stamps: offset (ROS time 0 = start_time) or utc",
              choices=("offset", "utc")),
        Param("base_position", [0.0, 21.0, 25.5], "the simulated base station's antenna (gnss-sim run --rtk, "
              "rtk:=true), 3 numbers in base_position_type; default: 0.5 m above the roof of the demo courtyard's "
              "north wing (open sky); a base sees the rover's ionosphere, troposphere and satellite errors",
              item_type="double"),
        Param("base_position_type", "world", "what base_position holds: world (x, y, z in world_frame [m]), llh "
              "(latitude [deg], longitude [deg], ellipsoidal height [m]) or ecef (WGS 84 [m])",
              choices=POSITION_TYPES),
        Param("base_seed", -1, "seed of the base receiver's own errors (noise, clock, multipath); -1: the "
              "receiver's seed + 1", min=-1),
        Param("base_marker_name", "BASE", "RINEX marker name of the base station (its files go to output_dir/base)",
              check_value=_check_marker_name),
        Param("base_rtcm_tcp_port", 0, "serve the base station's RTCM3 on this TCP port; 0: none", min=0,
              max=65535),
    ],
}


def _same_as(key: str, *names: str) -> list[Param]:
    """Rows of node ``key``'s table that another node takes as they are (one description, one check)."""
    rows = {p.name: p for p in NODE_PARAMS[key]}
    return [rows[n] for n in names]


#: the GNSS-quality layer for Nav2 (nodes/quality_map_node.py, launch argument quality_map:=true): the scene, the
#: profile and the ephemeris source are the visibility, receiver and ephemeris nodes' (graph.node_parameters
#: copies them from their sections)
NODE_PARAMS["quality_map"] = [
    *_same_as("visibility", "world_file", "mesh_file", "materials_file", "keep_dynamic_models", "strict_world"),
    *_same_as("receiver", "profile"),
    *_same_as("ephemeris", "source", "nav_files", "sp3_files", "clk_files", "download_cache_dir", "time_mapping",
              "duration_s"),
    Param("grid_step_m", 2.0, "cell size of the GNSS-quality occupancy grid over the world's bounds [m]",
          min=0.1, max=1000.0),
    Param("antenna_height_m", 1.5, "antenna height above the ground (the highest surface under a cell or pose) [m]",
          min=0.0, max=100.0),
    Param("refresh_period_s", 60.0, "the grid is recomputed when the (ROS) clock has moved this far [s]: the sky "
          "moves about 0.5 deg a minute; also the RTK indicator's continuity step", min=1.0, max=86400.0),
    Param("lookahead_s", 0.0, "the grid shows the quality this far ahead of the clock [s] (0: now)", min=0.0,
          max=86400.0),
    Param("max_accuracy_m", 10.0, "grid value mapping (core/planning/costmap.py): RTK indicator 0, no fix 100, "
          "otherwise 1 + 98 x min(1, expected horizontal accuracy / this) [m]", min=0.01, max=1000.0),
]


@dataclass
class Config:
    """Parameters of every node after defaults < shared (``/**``) < node sections."""

    values: dict[str, dict[str, Any]] = field(default_factory=dict)
    source: str = "<defaults>"

    def node(self, key: str) -> dict[str, Any]:
        """Shared + own parameters of one node (``ephemeris``, ``visibility``, ``receiver``, ``trajectory``)."""
        return dict(self.values[key])

    def ros_parameter_file_dict(self) -> dict:
        """The same configuration as a ROS 2 parameter file dict (every value explicit)."""
        return {NODE_NAMES[k]: {"ros__parameters": v} for k, v in self.values.items()}


def params_of(key: str) -> list[Param]:
    return SHARED + NODE_PARAMS[key]


def param(key: str, name: str) -> Param:
    """The table's row of parameter ``name`` of node ``key`` (``/**``: a shared one): a command-line option
    takes its choices and range from it instead of writing them again."""
    for p in SHARED if key == SHARED_KEY else params_of(key):
        if p.name == name:
            return p
    raise KeyError(f"no parameter {name!r} in section {key!r}")


def defaults() -> Config:
    return Config({k: {p.name: p.default for p in params_of(k)} for k in NODE_PARAMS})


SHARED_ONLY_NAMES = frozenset(p.name for p in SHARED if p.shared_only)


def apply_params(target: dict, section: dict, specs: dict[str, Param], where: str, options: dict | None = None):
    for name, value in (section or {}).items():
        if name not in specs:
            if name in SHARED_ONLY_NAMES:
                raise ValueError(f"{where}: parameter '{name}' is shared by every node (one value for the whole "
                                 f"graph): set it under '{SHARED_KEY}', not in one node's section")
            hint = difflib.get_close_matches(name, specs, n=1)
            extra = f" (did you mean '{hint[0]}'?)" if hint else ""
            raise ValueError(f"{where}: unknown parameter '{name}'{extra}")
        here = f"option {options[name]}" if options and name in options else where
        target[name] = specs[name].check(value, here)


def validate_node(key: str, values: dict, where: str, options: dict[str, str] | None = None) -> dict:
    """Every parameter of node ``key`` checked by the table, then the rules between parameters.

    The one validation path: :func:`load_config` (``config --check``, ``simulate``, ``run``, the launch
    file) and the nodes' configure call it.  Returns the normalised values.  ``options``: {param: command-line
    option}, so that a rule names the option the user typed.
    """
    out = {p.name: p.check(values[p.name] if p.name in values else p.default, where) for p in params_of(key)}

    def named(name):
        return f"option {options[name]} (parameter '{name}')" if options and name in options else f"parameter '{name}'"

    if key == "ephemeris":
        n_epochs = math.floor(out["duration_s"] * out["rate_hz"] + 1e-9) + 1
        if n_epochs > MAX_EPOCHS:
            raise ValueError(f"{where}: {named('duration_s')} = {out['duration_s']:g} s at {named('rate_hz')} = "
                             f"{out['rate_hz']:g} Hz is {n_epochs:.3g} epochs; a run takes at most {MAX_EPOCHS:.0e} "
                             f"(about 7.6 kB of RINEX and 1.3 kB of memory each, MAX_EPOCHS in "
                             f"gnss_sim_ros2/parameters.py): give a shorter span or a lower rate, or split the run")
    if key == "receiver":
        from gnss_sim_ros2.core.receiver.profiles import load_profile
        from gnss_sim_ros2.core.receiver.tracking import TrackingConfig

        tr = TrackingConfig(**load_profile(out["profile"]).value("tracking", {}))   # -1: the profile's threshold
        acq = out["cn0_acquire_dbhz"] if out["cn0_acquire_dbhz"] >= 0 else tr.acquisition_cn0_dbhz
        lose = out["cn0_lose_dbhz"] if out["cn0_lose_dbhz"] >= 0 else tr.tracking_cn0_dbhz
        if lose > acq:
            raise ValueError(f"{where}: parameter 'cn0_lose_dbhz' ({lose}) exceeds 'cn0_acquire_dbhz' ({acq}; -1 "
                             f"means the profile's): a signal would be lost above the level at which it is acquired")
    if key == "visibility" and out["antenna_position"]:
        check_position(out["antenna_position"], out["antenna_position_type"], "antenna_position", where)
    if key == "visibility" and out["world_offset_enu_m"]:
        off = out["world_offset_enu_m"]
        if len(off) != 3 or not all(math.isfinite(v) and abs(v) <= MAX_WORLD_OFFSET_M for v in off):
            raise ValueError(f"{where}: {named('world_offset_enu_m')} = {off!r} needs 3 numbers east, north, up [m], "
                             f"each within +-{MAX_WORLD_OFFSET_M:g} m (a georeference error is metres)")
    if key == "visibility" and out["sky_mask_csv"] and (out["world_file"] or out["mesh_file"]):
        scene = named("world_file" if out["world_file"] else "mesh_file")
        raise ValueError(f"{where}: {named('sky_mask_csv')} is the scene, but {scene} is set too: give one of them")
    if key == "visibility" and out["obstacle_models"] and not out["obstacle_pose_topic"]:
        raise ValueError(f"{where}: parameter 'obstacle_models' ({', '.join(out['obstacle_models'])}) needs "
                         f"parameter 'obstacle_pose_topic': the topic their poses come on")
    if key == "rtk":
        check_position(out["base_position"], out["base_position_type"], "base_position", where)
    if out["antenna2_frame"] and out["antenna2_frame"] == out["antenna_frame"]:
        raise ValueError(f"{where}: parameter 'antenna2_frame' ({out['antenna2_frame']!r}) is antenna_frame: the "
                         f"second antenna needs a frame of its own")
    if key == "trajectory" and len(out["antenna2_offset_m"]) != 3:
        raise ValueError(f"{where}: parameter 'antenna2_offset_m' needs 3 numbers (x, y, z in base_frame), "
                         f"got {out['antenna2_offset_m']!r}")
    if key == "trajectory" and len(out["antenna_offset_m"]) != 3:
        raise ValueError(f"{where}: parameter 'antenna_offset_m' needs 3 numbers (x, y, z in base_frame), "
                         f"got {out['antenna_offset_m']!r}")
    if key == "trajectory" and len(out["waypoints"]) % 4:
        raise ValueError(f"{where}: parameter 'waypoints' needs groups of 4 numbers t_s,e_m,n_m,u_m, got "
                         f"{len(out['waypoints'])} numbers")
    return out


def default_config_yaml() -> str:
    """The documented default parameter file (``config/gnss_sim.yaml``)."""
    import yaml

    lines = [
        "# gnss_sim parameters: one file for `ros2 launch gnss_sim sim.launch.py config:=...`,",
        "# `gnss-sim run --config ...` and `gnss-sim simulate --config ...`.",
        "# Every parameter with its default; delete what you do not change.",
        "# Generated from gnss_sim_ros2/parameters.py (`gnss-sim config`): keep them equal.",
        "",
    ]

    def emit(section: str, params: list[Param]):
        lines.append(f"{section}:")
        lines.append("  ros__parameters:")
        for p in params:
            extra = f" [{'|'.join(map(str, p.choices))}]" if p.choices else ""
            lines.append(f"    # {p.description}{extra}")
            value = yaml.safe_dump(p.default, default_flow_style=True).strip()
            if value.endswith("\n..."):
                value = value[:-4].strip()
            value = value.removesuffix("...").strip()
            lines.append(f"    {p.name}: {value}")
        lines.append("")

    emit("/**", SHARED)
    for key, params in NODE_PARAMS.items():
        emit(NODE_NAMES[key], params)
    return "\n".join(lines)
