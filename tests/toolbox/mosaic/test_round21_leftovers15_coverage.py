"""Cut polygons whose shared edges coincided only to rounding: ``voronoi_cells`` builds each
ortho's cell on its own (its footprint minus the half-planes closer to the others), so two
neighbours' common boundary was computed twice and the copies differed by ~1e-9 m at Siena's
coordinates (1,688,000 / 4,799,500): in a 6-ortho block, overlaps up to 6.8e-7 m² between
pairs, hairline holes 2e-10 - 7e-10 m wide, vertices 1e-9 m off the neighbour's edge, and GEOS's
coverage validator (``shapely.coverage_is_valid``) said no. The cut polygons written by
mosaic:seamlines METHOD=voronoi were those. Now they are an exact partition (GEOS's coverage
cleaner): the validator says yes, no pair overlaps, no hole; each cell is where it was (checked
against a brute-force nearest-centre labelling of sample points, numpy), its area within
1e-6 m²."""

from __future__ import annotations

import numpy as np
import pyogrio
import pytest
import shapely
from shapely import affinity

import toolbox
from toolbox.mosaic.partition import voronoi_cells

pytestmark = pytest.mark.skipif(not hasattr(shapely, "coverage_clean"),
                                reason="needs shapely >= 2.2 (GEOS >= 3.14)")
X0, Y0 = 1_688_000.0, 4_799_500.0


def _block(seed):
    """Six rotated 840 x 700 m footprints in 3 columns x 2 rows, jittered centres."""
    rng = np.random.default_rng(seed)
    footprints, centres = [], []
    for r in range(2):
        for c in range(3):
            cx, cy = X0 + c * 600 + rng.uniform(-40, 40), Y0 + r * 500 + rng.uniform(-40, 40)
            box = shapely.box(cx - 420, cy - 350, cx + 420, cy + 350)
            footprints.append(affinity.rotate(box, rng.uniform(-8, 8), origin=(cx, cy)))
            centres.append((cx + rng.uniform(-30, 30), cy + rng.uniform(-30, 30)))
    return footprints, centres


def _nearest_labels(footprints, centres, points):
    """Brute force: each point's ortho, the nearest centre among the footprints holding it."""
    inside = np.array([shapely.contains_xy(f, points[:, 0], points[:, 1]) for f in footprints])
    d = np.hypot(points[:, None, 0] - np.array(centres)[None, :, 0],
                 points[:, None, 1] - np.array(centres)[None, :, 1])
    d[~inside.T] = np.inf
    return np.where(np.isfinite(d).any(axis=1), d.argmin(axis=1), -1), np.sort(d, axis=1)


@pytest.mark.parametrize("seed", [0, 4])
def test_voronoi_cells_are_an_exact_coverage(seed):
    """Before (seed 0): overlaps in 5 pairs up to 6.0e-7 m², 3 holes, not a valid coverage;
    seed 4: 7 pairs up to 6.8e-7 m²."""
    footprints, centres = _block(seed)
    cells = voronoi_cells(footprints, centres)
    assert shapely.coverage_is_valid(cells)
    assert shapely.coverage_is_valid(cells, gap_width=1e-6)  # no hairline gap either
    for i in range(6):
        for j in range(i + 1, 6):
            assert cells[i].intersection(cells[j]).area == 0.0, (i, j)
    union = shapely.union_all(cells)
    assert all(not g.interiors for g in getattr(union, "geoms", [union]))
    area = shapely.union_all(footprints)
    assert abs(sum(c.area for c in cells) - area.area) < 1e-6
    # each cell where the nearest-centre rule puts it (points farther than 1 mm from a tie)
    rng = np.random.default_rng(seed)
    xmin, ymin, xmax, ymax = area.bounds
    points = np.column_stack([rng.uniform(xmin, xmax, 20000), rng.uniform(ymin, ymax, 20000)])
    labels, dist = _nearest_labels(footprints, centres, points)
    with np.errstate(invalid="ignore"):  # inf - inf: a point in no footprint, clear too
        margin = np.nan_to_num(dist[:, 1] - dist[:, 0], nan=np.inf)
    clear = (margin > 1e-3) & (shapely.distance(
        area.boundary, shapely.points(points)) > 1e-3)
    held = np.array([shapely.contains_xy(c, points[:, 0], points[:, 1]) for c in cells])
    assert clear.sum() > 15000
    assert (held.sum(axis=0)[clear] == (labels[clear] >= 0)).all()
    kept = clear & (labels >= 0)
    assert (held[labels[kept], np.flatnonzero(kept)]).all()


def _write_ortho(path, x0, y0, n=120):
    import rasterio
    from affine import Affine

    data = np.full((1, n, n), 100, "uint8")
    with rasterio.open(path, "w", driver="GTiff", width=n, height=n, count=1, dtype="uint8",
                       crs="EPSG:3003", transform=Affine(1, 0, x0, 0, -1, y0 + n),
                       nodata=0) as dst:
        dst.write(data)


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_seamlines_voronoi_writes_an_exact_coverage(tmp_path):
    """mosaic:seamlines METHOD=voronoi, six 120 m orthos at Siena's coordinates with jittered
    nadir points: before, the cut_polygons layer was no valid coverage (overlaps of ~1e-8 m²
    between neighbours)."""
    import geopandas as gpd

    paths, nadirs = [], []
    rng = np.random.default_rng(3)
    for r in range(2):
        for c in range(3):
            x, y = X0 + c * 85, Y0 + r * 90
            paths.append(tmp_path / f"o_{r}{c}.tif")
            _write_ortho(paths[-1], x, y)
            nadirs.append(shapely.Point(x + 60 + rng.uniform(-9, 9), y + 60 + rng.uniform(-9, 9)))
    gpd.GeoDataFrame({"photo": [p.stem for p in paths]}, geometry=nadirs,
                     crs="EPSG:3003").to_file(tmp_path / "nadirs.gpkg")
    out = toolbox.run("mosaic:seamlines", {
        "INPUT": [str(p) for p in paths], "METHOD": "voronoi",
        "NADIR_POINTS": str(tmp_path / "nadirs.gpkg"), "NADIR_FIELD": "photo",
        "OUTPUT": str(tmp_path / "seams.gpkg")})
    cells = list(pyogrio.read_dataframe(out["OUTPUT"], layer="cut_polygons").geometry)
    assert len(cells) == 6
    assert shapely.coverage_is_valid(cells)
    area = shapely.union_all([shapely.box(X0 + c * 85, Y0 + r * 90, X0 + c * 85 + 120,
                                          Y0 + r * 90 + 120) for r in range(2) for c in range(3)])
    assert abs(sum(c.area for c in cells) - area.area) < 1e-6
