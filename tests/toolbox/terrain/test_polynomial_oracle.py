"""An independent oracle for the hand-unrolled polynomial normal equations (kept for speed):
each cell recomputed with scipy's kd-tree and numpy's least squares on the same k nearest points,
for every order (plane, quadratic, cubic), on random neighbourhoods at Siena-sized coordinates."""

from __future__ import annotations

import numpy as np
import pytest

import toolbox

TERMS = {  # monomials x^i y^j of each order
    "plane": [(0, 0), (1, 0), (0, 1)],
    "quadratic": [(0, 0), (1, 0), (0, 1), (2, 0), (0, 2), (1, 1)],
    "cubic": [(0, 0), (1, 0), (0, 1), (2, 0), (0, 2), (1, 1), (3, 0), (0, 3), (2, 1), (1, 2)],
}
NEIGHBOURS = {"plane": 8, "quadratic": 12, "cubic": 20}


@pytest.fixture(scope="module")
def random_points(tmp_path_factory):
    import geopandas as gpd
    import shapely

    rng = np.random.default_rng(2024)
    n = 600
    x = 1_688_000.0 + rng.uniform(0, 500, n)
    y = 4_799_500.0 + rng.uniform(0, 500, n)
    u, v = (x - 1_688_250.0) / 100, (y - 4_799_750.0) / 100
    z = 300 + 8 * np.sin(u) * np.cos(v) + 2 * u * v + rng.normal(0, 0.3, n)
    path = tmp_path_factory.mktemp("oracle") / "points.gpkg"
    gpd.GeoDataFrame(geometry=shapely.points(x, y, z), crs="EPSG:3003").to_file(path)
    return path, np.column_stack([x, y, z])


def oracle(xyz: np.ndarray, centres: np.ndarray, order: str) -> np.ndarray:
    from scipy.spatial import cKDTree

    k = NEIGHBOURS[order]
    _, idx = cKDTree(xyz[:, :2]).query(centres, k=k)
    out = np.empty(len(centres))
    for n, (c, nb) in enumerate(zip(centres, idx, strict=True)):
        d = xyz[nb, :2] - c
        scale = np.hypot(d[:, 0], d[:, 1]).max()
        d /= scale
        design = np.column_stack([d[:, 0] ** i * d[:, 1] ** j for i, j in TERMS[order]])
        coef, *_ = np.linalg.lstsq(design, xyz[nb, 2], rcond=None)
        out[n] = coef[0]
    return out


@pytest.mark.parametrize("order", ["plane", "quadratic", "cubic"])
def test_unrolled_normal_equations_match_numpy_lstsq(random_points, tmp_path, order):
    import rasterio

    path, xyz = random_points
    out = tmp_path / f"{order}.tif"
    toolbox.run(f"dem:{order}", {"INPUT": path, "CELL_SIZE": 10, "OUTPUT": out})
    with rasterio.open(out) as ds:
        z = ds.read(1, masked=True)
        rows, cols = np.nonzero(~np.ma.getmaskarray(z))
        xs, ys = rasterio.transform.xy(ds.transform, rows, cols)
    pick = np.random.default_rng(1).choice(len(rows), size=min(400, len(rows)), replace=False)
    centres = np.column_stack([np.asarray(xs)[pick], np.asarray(ys)[pick]])
    expected = oracle(xyz, centres, order)
    got = np.asarray(z[rows[pick], cols[pick]], dtype=float)
    # float32 output: agreement to a millimetre on ~300 m heights, on (almost) every cell
    close = np.abs(got - expected) < 2e-3
    assert close.mean() > 0.99, np.abs(got - expected).max()
