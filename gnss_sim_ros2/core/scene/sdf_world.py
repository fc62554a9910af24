"""Names kept for code that imports the SDF reader from here; the reader is split by concept:

:mod:`.georeference` (``<spherical_coordinates>``), :mod:`.materials` (classes and name rules),
:mod:`.sdf_xml` (lenient XML, poses), :mod:`.uris` (model://, Fuel, file://, package://),
:mod:`.primitives` (shapes, heightmaps), :mod:`.mesh_files` (mesh files, submeshes, cache),
:mod:`.foliage` (crown volumes), :mod:`.population`, :mod:`.scene_report` and :mod:`.loader`.
"""
from __future__ import annotations

from .georeference import SphericalCoordinates
from .loader import load_sdf_world
from .materials import FOLIAGE_NAME_KEYWORDS, GNSS_SIM_SDF_NS, MaterialClass, MaterialTable, load_materials_yaml
from .scene_report import SceneWarning
from .sdf_xml import SdfError, parse_pose
from .uris import RESOURCE_PATH_VARS, model_sdf_path, resource_dirs
from .world_mesh import WorldMesh

__all__ = ["FOLIAGE_NAME_KEYWORDS", "GNSS_SIM_SDF_NS", "RESOURCE_PATH_VARS", "MaterialClass", "MaterialTable",
           "SceneWarning", "SdfError", "SphericalCoordinates", "WorldMesh", "load_materials_yaml", "load_sdf_world",
           "model_sdf_path", "parse_pose", "resource_dirs"]
