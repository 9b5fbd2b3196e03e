"""Round 17, demfactor: DEM_FACTOR k that does not divide the DEM's width or height. The coarse
DEM dropped the last partial block of k x k cells: ortho:photo / ortho:batch / the RPC ortho
(exit 0) left the ortho up to one coarse block short on the east and south, cells "without DEM
height" although the DEM covers them (103 x 97 cells, k = 4: 1564 of 39964 cells of 5 m).

Now the coarse DEM keeps the partial block: the mean of the DEM cells it holds, centred at the
centre of those cells, ending at the DEM's edge (the edge value held across its outer half
block, as everywhere else). Truth: NumPy's mean of each block's cells; a plane DEM, whose block
means are the plane at the blocks' centres, so that the coarse DEM's bilinear heights are the
plane at the point clamped to the hull of the block centres (for any k: the ortho with k equals
the one with k = 1 inside that hull); a photo whose pixel values are linear in (col, row), so
that an ortho cell's value names the photo point it was projected to, checked against the
collinearity equations written out in :mod:`test_round16_orthoedge`."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "algorithms" / "ortho"))
import ortho_scene as scene  # noqa: E402
from test_round16_orthoedge import (  # noqa: E402
    collinearity,
    photo_value,
    write_linear_photo,
)

CELL = 4.0  # DEM cell, m
X0, Y0 = 1688000.0, 4799000.0  # the DEM's south-west corner (under the scene's photo)


def plane(x, y):
    return 300.0 + 0.75 * (x - X0) - 0.5 * (y - Y0)  # exact in float32 at the cells


def hull(cols: int, rows: int, k: int) -> tuple[float, float, float, float]:
    """x of the first and last coarse block centres, y of the first and last (the last block
    partial when k does not divide: the centre of the cells it holds)."""
    y1 = Y0 + rows * CELL
    last_col, last_row = (cols - 1) // k * k, (rows - 1) // k * k  # first cell of the last block
    return (X0 + 0.5 * min(k, cols) * CELL, X0 + 0.5 * (last_col + cols) * CELL,
            y1 - 0.5 * min(k, rows) * CELL, y1 - 0.5 * (last_row + rows) * CELL)


def plane_dem(folder: Path, cols: int, rows: int):
    from toolbox.io.raster import open_raster_info

    t = Affine(CELL, 0.0, X0, 0.0, -CELL, Y0 + rows * CELL)
    xx, yy = np.meshgrid(X0 + (np.arange(cols) + 0.5) * CELL,
                         t.f - (np.arange(rows) + 0.5) * CELL)
    path = scene.write_dem(folder / f"plane_{cols}x{rows}.tif", plane(xx, yy), t)
    return open_raster_info(path, "DEM")


@pytest.fixture(scope="module")
def photo_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("demfactor")
    write_linear_photo(folder)
    return folder


@pytest.mark.parametrize("k", [1, 4, 5])
def test_ortho_with_dem_factor_reaches_the_dem_edge(photo_folder, k):
    """ortho:photo with DEM_FACTOR k on a 103 x 97 plane DEM of 4 m cells, EXTENT the DEM:
    every cell has a value (the old code left the east 3 and south 1 (k = 4) or 3 and 2
    (k = 5) DEM cells empty), equal within 1 DN (1/40 px) to the photo at the collinearity
    projection of the plane at the point clamped to the coarse block centres' hull (the edge
    value held); k = 1 is the same check on the DEM's own cells."""
    import toolbox

    cols, rows = 103, 97
    dem = plane_dem(photo_folder, cols, rows)
    out = photo_folder / f"ortho_{k}.tif"
    toolbox.run("ortho:photo", {
        "INPUT": photo_folder / "p1.tif", "PROJECT": photo_folder / "project.yaml",
        "DEM": dem.path, "DEM_FACTOR": k, "CELL_SIZE": 2.0,
        "EXTENT": f"{X0},{Y0},{X0 + cols * CELL},{Y0 + rows * CELL}", "OUTSIDE": "nodata",
        "NODATA": 0, "OUTPUT": out}, overwrite=True)
    with rasterio.open(out) as src:
        value, t = src.read(1).astype("float64"), src.transform
    assert (src.width, src.height) == (206, 194)
    xx, yy = np.meshgrid(t.c + (np.arange(src.width) + 0.5) * t.a,
                         t.f + (np.arange(src.height) + 0.5) * t.e)
    empty = value == 0
    assert not empty.any(), (np.where(empty.all(axis=0))[0], np.where(empty.all(axis=1))[0])
    xa, xb, ya, yb = hull(cols, rows, k)
    z = plane(np.clip(xx, xa, xb), np.clip(yy, yb, ya))
    col, row = collinearity(xx, yy, z)
    assert np.abs(value - photo_value(col, row)).max() <= 1.0


@pytest.mark.parametrize("k", [4, 5, 8])
@pytest.mark.parametrize("compiled", [True, False])
def test_coarse_block_heights_are_the_means_of_their_cells(tmp_path, k, compiled):
    """DemSampler (compiled and NumPy kernels) on a random 103 x 97 DEM: the height at the
    centre of every coarse block (a partial one's: the centre of the cells it holds) is NumPy's
    mean of the block's cells; from a partial block's centre to the DEM's edge its value is
    held, beyond the edge there is none (the old sampler: NaN on the whole last row and
    column of blocks)."""
    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.dem import DemSampler

    cols, rows = 103, 97
    z = (100.0 + 50.0 * np.random.default_rng(3).random((rows, cols))).astype("float32")
    t = Affine(CELL, 0.0, X0, 0.0, -CELL, Y0 + rows * CELL)
    info = open_raster_info(scene.write_dem(tmp_path / "dem.tif", z, t), "DEM")
    ni, nj = -(-rows // k), -(-cols // k)
    means = np.array([[z[i * k:(i + 1) * k, j * k:(j + 1) * k].astype("float64").mean()
                       for j in range(nj)] for i in range(ni)])
    first = np.arange(nj) * k
    cx = X0 + 0.5 * (first + np.minimum(first + k, cols)) * CELL
    first = np.arange(ni) * k
    cy = t.f - 0.5 * (first + np.minimum(first + k, rows)) * CELL
    sampler = DemSampler(info, None, 1, k)
    sampler.compiled = compiled
    np.testing.assert_allclose(sampler.heights(cx, cy), means, rtol=0, atol=1e-9)
    # east: the partial block's centre, between it and the edge, just inside, just beyond
    x_east = np.array([cx[-1], 0.5 * (cx[-1] + X0 + cols * CELL), X0 + cols * CELL - 1e-3,
                       X0 + cols * CELL + 1e-3])
    got = sampler.heights(x_east, cy[:2])
    np.testing.assert_allclose(got[:, :3], np.repeat(means[:2, -1:], 3, axis=1), atol=1e-9)
    assert np.isnan(got[:, 3]).all()
    y_south = np.array([cy[-1], 0.5 * (cy[-1] + Y0), Y0 + 1e-3, Y0 - 1e-3])
    got = sampler.heights(cx[:2], y_south)
    np.testing.assert_allclose(got[:3], np.repeat(means[-1:, :2], 3, axis=0), atol=1e-9)
    assert np.isnan(got[3]).all()


TM = "+proj=tmerc +lat_0=0 +lon_0=9 +k=0.9996 +x_0={} +y_0={} +ellps=intl +units=m +no_defs"


@pytest.mark.parametrize("size", [(103, 97), (100, 96)])
@pytest.mark.parametrize("k", [1, 4, 5])
@pytest.mark.parametrize("shifted", [False, True])
def test_any_factor_gives_the_plane_on_a_plane_dem(tmp_path, size, k, shifted):
    """A plane DEM: for any k (dividing its size or not) the coarse heights on a 1 m grid over
    the DEM and beyond are the plane at the point clamped to the hull of the coarse block
    centres, NaN beyond the DEM's edges (so inside the hull k changes nothing: the same heights
    as k = 1 to 1e-9 m). ``shifted``: the DEM in another CRS (a transverse Mercator 7.3 m east
    and 4.1 m south of the ortho's), through the scattered-point kernel, the truth at pyproj's
    points."""
    from pyproj import CRS

    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.dem import DemSampler

    cols, rows = size
    info = plane_dem(tmp_path, cols, rows)
    out_crs = CRS.from_proj4(TM.format(1500000.0, 0.0))
    with rasterio.open(info.path, "r+") as dst:
        dst.crs = CRS.from_proj4(TM.format(1500007.3, -4.1)) if shifted else out_crs
    info = open_raster_info(info.path, "DEM")
    ox, oy = (X0 - 7.3, Y0 + 4.1) if shifted else (X0, Y0)  # the DEM's corner, ortho CRS
    xs = ox - 3.0 + np.arange(int(cols * CELL) + 6) + 0.5
    ys = oy + rows * CELL + 3.0 - np.arange(int(rows * CELL) + 6) - 0.5
    sampler = DemSampler(info, out_crs, 1, k)
    assert (sampler.transformer is not None) == shifted
    got = sampler.heights(xs, ys)
    if sampler.transformer is not None:
        px, py = sampler.transformer.transform(*np.meshgrid(xs, ys))
    else:
        px, py = np.meshgrid(xs, ys)
    xa, xb, ya, yb = hull(cols, rows, k)
    truth = plane(np.clip(px, xa, xb), np.clip(py, yb, ya))
    beyond = (px < X0) | (px > X0 + cols * CELL) | (py < Y0) | (py > Y0 + rows * CELL)
    truth[beyond] = np.nan
    assert beyond.any() and not beyond.all()
    np.testing.assert_allclose(got, truth, rtol=0, atol=1e-8)


@pytest.mark.parametrize("k", [1, 4, 5])
def test_ortho_windows_fused_inside_and_at_the_partial_block(tmp_path, photo_folder, k):
    """orthorectify in 64-cell windows (the one-pass kernel inside, the partial blocks' windows
    through DemSampler.heights): every cell filled, the ortho of one window within 1 DN (the
    windows' float32 maps differ in their last bits, so do they with k = 1); a DEM that k
    divides keeps the one-pass kernel up to its edge (DemSampler.part)."""
    from pyproj import CRS

    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.dem import DemSampler
    from toolbox.ortho.plan import lattice_grid
    from toolbox.ortho.run import OrthoOptions, orthorectify
    from toolbox.photogrammetry.project import load_project

    cols, rows = 103, 97
    dem = plane_dem(tmp_path, cols, rows)
    photo = load_project(photo_folder / "project.yaml").photos["p1"]
    image = open_raster_info(photo_folder / "p1.tif")
    grid = lattice_grid((X0, Y0, X0 + cols * CELL, Y0 + rows * CELL), 2.0, CRS(scene.CRS))
    out = {}
    for chunk in (64, 1024):
        path = tmp_path / f"o{chunk}.tif"
        orthorectify(photo, image, dem, grid, path,
                     OrthoOptions(dem_factor=k, chunk=chunk, outside="nodata", nodata=0))
        with rasterio.open(path) as src:
            out[chunk] = src.read(1)
    assert (out[64] > 0).all()
    assert np.abs(out[64].astype(int) - out[1024]).max() <= 1
    xs, ys = grid.cell_centers(None)
    assert DemSampler(dem, grid.crs, 1, k).part(xs[:64], ys[:64]) is not None
    east = DemSampler(dem, grid.crs, 1, k).part(xs[-64:], ys[:64])  # the partial column
    assert (east is None) == (k > 1)
    whole = plane_dem(tmp_path, 100, 96)
    assert DemSampler(whole, grid.crs, 1, 4).part(xs[-64:], ys[-64:]) is not None


@pytest.mark.parametrize("k", [4, 5])
def test_rpc_ortho_with_dem_factor_reaches_the_dem_edge(tmp_path, k):
    """The RPC ortho (ortho:photo on an image with RPCs) with DEM_FACTOR k on a 103 x 97 DEM of
    30 m cells, EXTENT the DEM: the same cells have an image position as with k = 1, all of
    them (the old code: 1564 (k = 4) and 1964 (k = 5) of 39964 cells left empty)."""
    from pyproj import Transformer

    import toolbox

    sys.path.insert(0, str(Path(__file__).parents[1] / "algorithms" / "ortho"))
    from rpc_scene import NODATA, synthetic_rpc, write_ramp

    x0, y0 = Transformer.from_crs("EPSG:4326", "EPSG:32632", always_xy=True).transform(11, 45)
    x0, y0 = round(x0 / 30.0) * 30.0 - 1500.0, round(y0 / 30.0) * 30.0 - 1500.0
    t = Affine(30.0, 0.0, x0, 0.0, -30.0, y0 + 97 * 30.0)
    z = 300.0 + 0.1 * np.add.outer(np.arange(97.0), np.arange(103.0))
    scene.write_dem(tmp_path / "dem.tif", z, t, crs="EPSG:32632")
    ramp = write_ramp(tmp_path / "ramp.tif", synthetic_rpc(), 1200, 1000)
    valid = {}
    for factor in (1, k):
        out = tmp_path / f"rpc{factor}.tif"
        toolbox.run("ortho:photo", {
            "INPUT": ramp, "DEM": tmp_path / "dem.tif", "OUTSIDE": "nodata", "NODATA": NODATA,
            "OVERVIEWS": False, "CELL_SIZE": 15.0, "DEM_FACTOR": factor, "OUTPUT": out,
            "EXTENT": f"{x0},{y0},{x0 + 103 * 30.0},{y0 + 97 * 30.0}"}, overwrite=True)
        with rasterio.open(out) as src:
            valid[factor] = src.read(1) != NODATA
    assert valid[1].all() and valid[k].shape == (194, 206)
    assert valid[k].all(), (np.where(~valid[k].all(axis=0))[0], np.where(~valid[k].all(axis=1))[0])


def test_dem_factor_leaving_less_than_two_coarse_cells_is_refused(tmp_path, photo_folder):
    """DEM_FACTOR at least the DEM's smaller side (60 x 50 cells, k = 50): one coarse cell
    across, no bilinear height anywhere. The old code failed on OUTPUT ("would have no valid
    cell ... check that EXTENT, TEMPLATE and CELL_SIZE cover the data") although the DEM covers
    the extent (ortho:batch wrote an empty ortho); now DEM_FACTOR is named with its largest
    value, and k = 49 (two coarse cells, one of them partial) gives an ortho without a gap."""
    import toolbox
    from toolbox.errors import ParameterError

    dem = plane_dem(tmp_path, 60, 50)
    params = {"INPUT": photo_folder / "p1.tif", "PROJECT": photo_folder / "project.yaml",
              "DEM": dem.path, "CELL_SIZE": 2.0, "OUTSIDE": "nodata", "NODATA": 0,
              "EXTENT": f"{X0},{Y0},{X0 + 60 * CELL},{Y0 + 50 * CELL}",
              "OUTPUT": tmp_path / "o.tif"}
    with pytest.raises(ParameterError, match=r"^DEM_FACTOR is 50, .*expected at most 49$"):
        toolbox.run("ortho:photo", {**params, "DEM_FACTOR": 50}, overwrite=True)
    toolbox.run("ortho:photo", {**params, "DEM_FACTOR": 49}, overwrite=True)
    with rasterio.open(tmp_path / "o.tif") as src:
        assert (src.read(1) > 0).all()
