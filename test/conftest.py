"""Shared pytest fixtures.

Real receiver and orbit data live outside the repository in ``../shared/data``
(next to the clone).  Tests that need them take the ``shared_data`` fixture,
which skips with the reason when the folder is absent (a user's fresh clone).
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("GNSS_SIM_SHARED_DATA", REPO_ROOT.parent / "shared" / "data"))


@pytest.fixture(scope="session", autouse=True)
def _a_cache_folder_of_the_sessions_own(tmp_path_factory):
    """The user's gnss_sim cache (parsed navigation files: core/rinex/nav/cache.py; downloads) stays out of the
    tests: the session, and every command it runs, uses a folder of its own."""
    before = os.environ.get("GNSS_SIM_CACHE")
    os.environ["GNSS_SIM_CACHE"] = str(tmp_path_factory.mktemp("gnss_sim_cache"))
    yield
    if before is None:
        os.environ.pop("GNSS_SIM_CACHE", None)
    else:
        os.environ["GNSS_SIM_CACHE"] = before


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """Path of ``../shared/data``; skips the test when it is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real GNSS data folder {SHARED_DATA} is absent (it exists beside the clone in CI only)")
    return SHARED_DATA


@pytest.fixture(scope="session")
def opec_dir(shared_data) -> Path:
    d = shared_data / "opec-2022-001"
    if not d.is_dir():
        pytest.skip(f"{d} is absent")
    return d
