"""The demo world (worlds/courtyard.sdf): the scene used when no world or mesh is given."""
from __future__ import annotations

from pathlib import Path

DEMO_WORLD_NAME = "courtyard.sdf"


def demo_world_path() -> Path:
    """worlds/courtyard.sdf from the source tree, else from the installed package's share folder.

    ValueError naming both places looked at when neither holds it."""
    here = Path(__file__).resolve().parents[3] / "worlds" / DEMO_WORLD_NAME
    if here.is_file():
        return here
    looked = [str(here)]
    try:
        from ament_index_python.packages import get_package_share_directory

        share = Path(get_package_share_directory("gnss_sim")) / "worlds" / DEMO_WORLD_NAME
        if share.is_file():
            return share
        looked.append(str(share))
    except Exception as exc:  # noqa: BLE001 - ament_index raises its own lookup errors, or is not installed
        looked.append(f"the gnss_sim share folder ({type(exc).__name__}: {exc})")
    raise ValueError(f"the demo world worlds/{DEMO_WORLD_NAME} was not found (looked in {', '.join(looked)}); "
                     f"give a world (--world / world_file) or a mesh (--mesh / mesh_file)")
