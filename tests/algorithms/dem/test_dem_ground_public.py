"""dem:ground on a public classified LiDAR sample (laspy's ``autzen_trim.laz``, see
tests/data/pointclouds/README.md): the DTM the filter makes from ALL the points, ignoring
their classes, against the vendor's ground class (class 2) gridded independently by
scipy.interpolate.LinearNDInterpolator (what griddata "linear" uses) at the same cell centres.

The file is in international feet: 0.5 m = 1.64 ft. The vendor's class 2 is a thinned ground
(most class-1 points lie on the ground too), so agreement is measured on the surfaces, and on
the points that clearly stand up (class 1 more than 2 m above the class-2 surface), which the
filter must call non-ground. A control (all points gridded with no filter) must fail the same
threshold (dem:tin_linear of all the points: 86 % of the cells within 0.5 m), so the test
can tell a filter that works from one that does nothing.
"""

from __future__ import annotations

from pathlib import Path

import laspy
import numpy as np
import pytest
import rasterio
from scipy.interpolate import LinearNDInterpolator

import toolbox

SAMPLE = Path(__file__).resolve().parents[2] / "data" / "pointclouds" / "autzen_trim.laz"
FT = 1.0 / 0.3048  # feet per metre
CELL = 6.0  # ft


def _raster(path):
    with rasterio.open(path) as ds:
        return ds.read(1, masked=True).filled(np.nan), ds.transform


def _cell_centres(transform, shape):
    rows, cols = np.mgrid[0:shape[0], 0:shape[1]]
    return transform.c + (cols + 0.5) * transform.a, transform.f + (rows + 0.5) * transform.e


@pytest.fixture(scope="module")
def autzen(tmp_path_factory):
    if not SAMPLE.exists():
        pytest.skip(f"{SAMPLE} not present")
    tmp = tmp_path_factory.mktemp("autzen")
    las = laspy.read(SAMPLE)
    x, y, z = (np.asarray(v, dtype=float) for v in (las.x, las.y, las.z))
    ground = np.asarray(las.classification) == 2
    origin = np.array([x.min(), y.min()])
    # the truth surface: the class-2 points interpolated linearly by scipy (local coordinates)
    interp = LinearNDInterpolator(np.column_stack([x[ground], y[ground]]) - origin, z[ground])

    def truth(px, py):
        return interp(px - origin[0], py - origin[1])

    result = toolbox.run("dem:ground", {
        "INPUT": str(SAMPLE), "FILTER_CELL": 1.0 * FT, "SLOPE": 0.15, "MAX_WINDOW": 18.0 * FT,
        "ELEVATION_THRESHOLD": 0.5 * FT, "ELEVATION_SCALAR": 1.25, "CELL_SIZE": CELL,
        "OUTPUT": str(tmp / "dtm.tif"), "NONGROUND": str(tmp / "nonground.tif"),
        "GROUND_POINTS": str(tmp / "classified.laz")})
    return las, tmp, result, truth


def test_dtm_matches_the_ground_class(autzen):
    las, tmp, result, truth = autzen
    dtm, transform = _raster(tmp / "dtm.tif")
    ref = truth(*_cell_centres(transform, dtm.shape))
    both = np.isfinite(ref) & np.isfinite(dtm)
    assert both.sum() > 0.8 * dtm.size  # the DTM covers the ground class's hull
    within = np.abs(dtm[both] - ref[both]) <= 0.5 * FT
    assert within.mean() >= 0.95, f"{within.mean():.3f} of the cells within 0.5 m"
    # the control: the same gridding of every point, unfiltered, misses the threshold
    toolbox.run("dem:tin_linear", {"INPUT": str(SAMPLE), "CELL_SIZE": CELL,
                                   "OUTPUT": str(tmp / "all.tif")})
    unfiltered, t2 = _raster(tmp / "all.tif")
    assert t2 == transform
    both = np.isfinite(ref) & np.isfinite(unfiltered)
    assert (np.abs(unfiltered[both] - ref[both]) <= 0.5 * FT).mean() < 0.90


def test_points_standing_up_are_nonground(autzen):
    las, tmp, result, truth_at = autzen
    truth = np.asarray(las.classification) == 2
    x, y, z = (np.asarray(v, dtype=float) for v in (las.x, las.y, las.z))
    out = laspy.read(tmp / "classified.laz")
    assert len(out.points) == len(x)
    np.testing.assert_allclose(np.asarray(out.x), x, atol=0.002)  # same points, same order
    ground = np.asarray(out.classification) == 2
    above = z - truth_at(x, y)
    objects = ~truth & (above > 2.0 * FT)
    assert objects.sum() > 10_000  # trees and roofs of the sample
    assert (~ground[objects]).mean() >= 0.99
    assert ground[truth].mean() >= 0.99  # the vendor's ground stays ground
    stats = result["STATISTICS"]["ground_filter"]
    assert stats["points"] == len(x) and stats["ground"] == int(ground.sum())
