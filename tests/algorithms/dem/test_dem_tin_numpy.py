"""dem:tin_linear's two paths: the numpy kernels of small runs (no numba import) give the values
of the numba kernels (breaklines, crossings, MASK with a hole, MAX_DISTANCE, duplicates, the
hull's nodata, several tiles), both agree with scipy's linear griddata, and the path is chosen
by size."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import geopandas as gpd
import numpy as np
import pytest
import rasterio
import shapely
from scipy.interpolate import griddata

import toolbox
from toolbox.terrain.gridding.methods import tin_linear as method
from toolbox.terrain.gridding.tin_constrained import constrained_tin
from toolbox.terrain.tin.kernels import rasterize_tin

CRS = "EPSG:3003"
X0, Y0 = 1_688_000.0, 4_799_500.0


def surface(x, y):
    u, v = np.asarray(x) - X0, np.asarray(y) - Y0
    return 250.0 + 10 * np.sin(u / 23.0) * np.cos(v / 17.0) + 0.03 * u


def write_points(path, xy, z):
    gpd.GeoDataFrame({"h": z}, geometry=shapely.points(xy[:, 0], xy[:, 1], z),
                     crs=CRS).to_file(path)
    return path


def read(path):
    with rasterio.open(path) as src:
        return src.read(1, masked=True).astype("float64").filled(np.nan)


def assert_same_values(a, b, rtol=1e-9):
    assert a.shape == b.shape
    assert np.array_equal(np.isnan(a), np.isnan(b))  # the same nodata, the hull's included
    ok = ~np.isnan(a)
    assert np.allclose(a[ok], b[ok], rtol=rtol, atol=0.0)


# -- the kernels -------------------------------------------------------------------------------
def _tins():
    """(nodes, triangles) of random, lattice (centres on edges and nodes) and constrained TINs."""
    rng = np.random.default_rng(3)
    xy = rng.uniform(0, 100, (2000, 2))
    yield "random", np.column_stack([xy, surface(xy[:, 0] + X0, xy[:, 1] + Y0)]), None
    g = np.arange(0.0, 101.0, 5.0)
    lat = rng.permutation(np.array([(x, y) for x in g for y in g]))  # edges in all directions
    yield "lattice", np.column_stack([lat, 0.3 * lat[:, 0] - 0.2 * lat[:, 1] + (lat[:, 0] % 10)]), None
    seg = np.array([[0, 1], [2, 3], [4, 5]])  # two crossing breaklines and one more
    pts = np.vstack([[[10, 10], [90, 90], [10, 90], [90, 10], [20, 50], [80, 55]], xy[:500]])
    yield "breaklines", np.column_stack([pts, surface(pts[:, 0] + X0, pts[:, 1] + Y0)]), seg


@pytest.mark.parametrize("cell,corner", [(1.0, (-2.0, 101.0)), (0.7, (-2.0, 101.0)),
                                         (2.5, (-2.0, 101.0)),
                                         (1.0, (-0.5, 100.5)),  # centres on the hull, on nodes
                                         (2.5, (-1.25, 101.25))])
def test_numpy_rasteriser_equals_the_compiled_kernel(cell, corner):
    for name, xyz, seg in _tins():
        nodes, tri, _ = constrained_tin(xyz, seg)
        w, h = int(108 / cell), int(107 / cell)
        args = (nodes, tri, *corner, cell, cell, w, h)
        compiled = rasterize_tin(*args)
        vectorised = rasterize_tin(*args, compiled=False)
        assert np.isnan(compiled).any() and (~np.isnan(compiled)).sum() > 100, name
        assert_same_values(vectorised, compiled)


def test_rectangular_cells():
    for _, xyz, seg in _tins():
        nodes, tri, _ = constrained_tin(xyz, seg)
        args = (nodes, tri, -3.0, 104.0, 0.8, 1.3, 135, 83)
        assert_same_values(rasterize_tin(*args, compiled=False), rasterize_tin(*args))


def test_small_batches_give_the_same_raster(monkeypatch):
    """Batches cut by triangles and by (triangle, row) pairs (bounded memory for slivers)."""
    from toolbox.terrain.tin import planes_numpy

    _, xyz, seg = list(_tins())[2]
    nodes, tri, _ = constrained_tin(xyz, seg)
    args = (nodes, tri, -2.0, 101.0, 0.5, 0.5, 210, 208)
    whole = rasterize_tin(*args, compiled=False)
    for batch, rows in ((5, 10**9), (10**9, 7), (3, 1)):
        monkeypatch.setattr(planes_numpy, "BATCH", batch)
        monkeypatch.setattr(planes_numpy, "BATCH_ROWS", rows)
        assert_same_values(rasterize_tin(*args, compiled=False), whole, rtol=0.0)


def test_centres_on_edges_and_nodes_of_either_orientation():
    """Centres exactly on the edges and nodes of triangles listed clockwise and
    counter-clockwise (the triangulators give counter-clockwise ones; the kernels take both)."""
    nodes = np.array([[0.0, 0.0, 1.0], [0.0, 10.0, 2.0], [10.0, 0.0, 3.0], [10.0, 10.0, 5.0]])
    for tri in ([[0, 1, 2]], [[1, 0, 2]], [[2, 1, 0]], [[0, 2, 3], [0, 3, 1]],
                [[3, 2, 0], [1, 3, 0]]):
        args = (nodes, np.array(tri), -0.5, 10.5, 1.0, 1.0, 12, 12)
        compiled = rasterize_tin(*args)
        assert not np.isnan(compiled[0, 0]) and not np.isnan(compiled[10, 0])  # nodes
        assert_same_values(rasterize_tin(*args, compiled=False), compiled)


def test_both_paths_agree_with_scipy_linear_griddata():
    """Unconstrained points in general position: the Delaunay TIN is unique, so the linear
    interpolant is scipy's (Qhull's) too, inside the hull and NaN outside."""
    rng = np.random.default_rng(11)
    xy = rng.uniform(0, 200, (3000, 2))
    z = surface(xy[:, 0] + X0, xy[:, 1] + Y0)
    nodes, tri, _ = constrained_tin(np.column_stack([xy, z]), None)
    cell = 1.3
    w = h = int(210 / cell)
    gx, gy = np.meshgrid(-5 + (np.arange(w) + 0.5) * cell, 205 - (np.arange(h) + 0.5) * cell)
    reference = griddata(xy, z, (gx, gy), method="linear")
    for compiled in (True, False):
        ours = rasterize_tin(nodes, tri, -5.0, 205.0, cell, cell, w, h, compiled=compiled)
        assert_same_values(ours, reference, rtol=1e-9)


def test_numpy_bins_equal_the_compiled_bins(monkeypatch):
    from toolbox.terrain.gridding import neighbours
    from toolbox.warmup import compile_large_input_kernels

    rng = np.random.default_rng(5)
    xy = np.vstack([rng.uniform(0, 50, (3000, 2)), rng.integers(0, 20, (500, 2)) * 1.0])
    for points in (xy, np.unique(xy, axis=0), xy[:, ::-1] * [1.0, 0.0]):  # last: on a line
        built = {}
        for label, limit in (("numpy", 10**9), ("numba", -1)):
            monkeypatch.setattr(neighbours, "NUMPY_MAX_POINTS", limit)
            bins = neighbours.PointBins.build(points)
            built[label] = (bins.order, bins.offsets, bins.has_duplicates(),
                            bins.in_rect(10.0, 5.0, 30.5, 41.0), bins.in_rect(-5, -5, 0.0, 0.0))
        for a, b in zip(built["numpy"], built["numba"], strict=True):
            assert np.array_equal(a, b)
    compile_large_input_kernels()  # what `toolbox warmup` adds for large inputs: it runs


# -- whole runs ----------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tin_numpy")
    rng = np.random.default_rng(21)
    uv = rng.uniform(0, 300, (2500, 2))
    uv = np.vstack([uv, uv[:40]])  # 40 duplicate positions with other heights
    z = surface(uv[:, 0] + X0, uv[:, 1] + Y0)
    z[-40:] += 1.0
    write_points(folder / "pts.gpkg", uv + [X0, Y0], z)
    lines = [shapely.LineString([(X0 + 20, Y0 + 20, 250), (X0 + 280, Y0 + 260, 262)]),
             shapely.LineString([(X0 + 30, Y0 + 270, 255), (X0 + 270, Y0 + 40, 258)])]
    gpd.GeoDataFrame(geometry=lines, crs=CRS).to_file(folder / "bl.gpkg")
    ring = shapely.Polygon([(X0 + 10, Y0 + 10), (X0 + 290, Y0 + 10), (X0 + 290, Y0 + 290),
                            (X0 + 10, Y0 + 290)],
                           [[(X0 + 100, Y0 + 100), (X0 + 200, Y0 + 100), (X0 + 200, Y0 + 180),
                             (X0 + 100, Y0 + 180)]])
    gpd.GeoDataFrame(geometry=[ring], crs=CRS).to_file(folder / "mask.gpkg")
    return folder


def _run_both(monkeypatch, params, path):
    out = {}
    for label, cells in (("numba", -1), ("numpy", 10**12)):
        monkeypatch.setattr(method, "NUMPY_MAX_CELLS", cells)
        result = toolbox.run("dem:tin_linear", params | {"OUTPUT": path / f"{label}.tif"},
                             overwrite=True)
        assert result["STATISTICS"]["method"]["kernels"] == label
        out[label] = read(result["OUTPUT"])
    return out["numba"], out["numpy"]


@pytest.mark.parametrize("extra", [
    {},
    {"BREAKLINES": "bl.gpkg"},
    {"MASK": "mask.gpkg", "TILE_SIZE": 32},
    {"MAX_DISTANCE": 3.0, "TILE_SIZE": 48},
    {"BREAKLINES": "bl.gpkg", "MAX_DISTANCE": 4.0, "MASK": "mask.gpkg", "DUPLICATES": "max"},
    {"EXTENT": f"{X0 - 20},{Y0 - 15},{X0 + 320},{Y0 + 310}", "TILE_SIZE": 64},  # hull inside
    {"EXTENT": f"{X0 + 50.3},{Y0 + 40.1},{X0 + 170.3},{Y0 + 130.1}", "TILE_SIZE": 32},  # inside
])
def test_numpy_path_equals_the_numba_path(extra, inputs, tmp_path, monkeypatch):
    params = {"INPUT": inputs / "pts.gpkg", "CELL_SIZE": 1.7, "OVERVIEWS": False}
    params |= {k: inputs / v if str(v).endswith(".gpkg") else v for k, v in extra.items()}
    numba_z, numpy_z = _run_both(monkeypatch, params, tmp_path)
    assert np.isnan(numba_z).any() or "MASK" not in extra
    assert_same_values(numpy_z, numba_z)


def test_path_is_chosen_by_points_and_cells():
    assert not method.use_compiled(100_000, 632 * 632)  # the small bench case: numpy
    assert method.use_compiled(1_000_000, 2000 * 2000)  # the large one: numba
    assert method.use_compiled(method.NUMPY_MAX_POINTS + 1, 100)
    assert method.use_compiled(1000, method.NUMPY_MAX_CELLS + 1)
    assert not method.use_compiled(method.NUMPY_MAX_POINTS, method.NUMPY_MAX_CELLS)


def test_a_small_run_imports_neither_numba_nor_dask(inputs, tmp_path):
    """`toolbox run dem:tin_linear` (the CLI, as the whole-process bench runs it) on 2,540
    points, MAX_DISTANCE included: numba (about 1 s per process) and dask are never imported."""
    args = ["toolbox", "run", "dem:tin_linear", "--INPUT", str(inputs / "pts.gpkg"),
            "--CELL_SIZE", "2", "--MAX_DISTANCE", "5", "--OUTPUT", str(tmp_path / "z.tif"), "-q"]
    script = ("import json, sys\nfrom toolbox.cli import main\n"
              f"sys.argv = {args!r}\n"
              "try:\n    main()\nexcept SystemExit as exc:\n    assert not exc.code, exc.code\n"
              "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules}"
              " & {'numba', 'llvmlite', 'dask'})))\n")
    env = {k: v for k, v in os.environ.items() if not k.startswith("DASK_")}
    env["HOME"] = str(tmp_path)  # no ~/.config/dask
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=env, check=True)
    lines = done.stdout.splitlines()
    assert json.loads(lines[-1]) == []
    assert json.loads("\n".join(lines[:-1]))["STATISTICS"]["method"]["kernels"] == "numpy"
