"""The demo world (worlds/courtyard.sdf): the scene every front end uses when none is given."""
from __future__ import annotations

from pathlib import Path

#: the demo world, relative to the source tree's root and to the installed share/gnss_sim folder
DEMO_WORLD = Path("worlds") / "courtyard.sdf"


def demo_world_path() -> Path:
    """worlds/courtyard.sdf from the source tree, else from the installed package's share folder."""
    here = Path(__file__).resolve().parents[3] / DEMO_WORLD
    if here.is_file():
        return here
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    except ImportError:
        raise ValueError(f"the demo world {DEMO_WORLD} was not found beside the sources and ament_index_python "
                         f"is not installed; give a world (--world, parameter world_file) or a mesh") from None
    try:
        installed = Path(get_package_share_directory("gnss_sim")) / DEMO_WORLD
    except PackageNotFoundError:
        installed = None
    if installed is None or not installed.is_file():
        raise ValueError(f"the demo world {DEMO_WORLD} was not found (source tree or share/gnss_sim); give a world "
                         f"(--world, parameter world_file) or a mesh (--mesh, parameter mesh_file)")
    return installed
