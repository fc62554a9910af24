"""The land-mobile-satellite layer (lms_environment, core/multipath/lms.py) on the Hong Kong drive (about a minute):
line-of-sight code residuals with a real receiver's tail, the drive's other figures kept (docs/VALIDATION.md, "Urban
canyons: what a 3D model lacks")."""
from __future__ import annotations

import pytest
from test_urban_hk_drive import hk  # noqa: F401  (the drive, its city model, ephemeris and real file: one loader)

from gnss_sim_ros2.config_file import load_config
from gnss_sim_ros2.core.comparison import drive_check

#: the city model's georeference offset (east, north) [m] that test_urban_hk_drive estimates from the real file
#: (drive_check.model_offset_m; docs/VALIDATION.md)
PLACED_OFFSET_M = (-3.0, -5.0)


@pytest.fixture(scope="module")
def runs(hk):  # noqa: F811
    _, scene, prov, nav, real_obs, tmp, drive_dir = hk
    drive = drive_check.load_drive(drive_dir / "groundTruth_TST.csv", scene, offset_m=PLACED_OFFSET_M)
    out, real = {}, None
    for mode in ("off", "auto"):
        m = drive_check.run_drive(drive, scene, prov, nav, real_obs, tmp / f"lms_{mode}", config=load_config(),
                                  multipath="nlos", scattering=True, real=real, receiver={"lms_environment": mode})
        real = m["real_part"]
        out[mode] = m
    return out


def test_the_layer_gives_line_of_sight_ranges_a_real_receivers_tail(runs):
    off, auto = runs["off"], runs["auto"]
    print({mode: {k: v for k, v in m.items() if k.startswith("los_")} for mode, m in runs.items()})
    real_tail = auto["los_above_10m_real"]
    assert off["los_above_10m_sim"] < 0.5 * real_tail                     # the deterministic rays alone: too clean
    assert 0.5 <= auto["los_above_10m_sim"] / real_tail <= 2.0             # issue 27's acceptance band
    assert 0.5 <= auto["los_residual_rms_m_sim"] / auto["los_residual_rms_m_real"] <= 2.0


def test_the_drives_other_figures_stay(runs):
    """Recall / precision, NLOS share and the RTKLIB horizontal RMS within 0.02 / 0.02 / 0.05 / 10 % of the run
    without the layer (it acts on satellites in sight only)."""
    off, auto = runs["off"], runs["auto"]
    assert auto["recall"] == pytest.approx(off["recall"], abs=0.02)
    assert auto["precision"] == pytest.approx(off["precision"], abs=0.02)
    assert auto["nlos_fraction_sim"] == pytest.approx(off["nlos_fraction_sim"], abs=0.05)
    assert auto["h_sim"]["rms_m"] == pytest.approx(off["h_sim"]["rms_m"], rel=0.1)
