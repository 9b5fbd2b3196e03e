"""The coordinate-map protocols of the warp (toolbox.raster.maps): what each map declares is what
the warp uses, and every path gives the pixels of plain numpy indexing."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from affine import Affine

from toolbox.executor import Executor
from toolbox.io.grid import GridSpec
from toolbox.raster import maps
from toolbox.raster.homography import HomographyMap
from toolbox.raster.maps import EMPTY_PLAN, OUTSIDE, SourcePlan, plan_source, scan_bounds
from toolbox.raster.warp import warp_layout, warp_raster

H, W = 110, 120  # source rows, columns
GRID = GridSpec(Affine(1.0, 0.0, 500.0, 0.0, -1.0, 800.0), 70, 50, None)


def coordinates(tile):
    """Output cell (i, j) -> the centre of source pixel (2i + 3, W - 1 - j); the last 10 output
    columns fall outside the source."""
    w = tile.window
    ii, jj = np.mgrid[int(w.row_off):int(w.row_off + w.height),
                      int(w.col_off):int(w.col_off + w.width)]
    cols = (W - 1 - jj + 0.5).astype("float32")
    cols[jj >= 60] = 500.0
    return cols, (2 * ii + 3 + 0.5).astype("float32")


class Plain:
    def __call__(self, tile, aux):
        return coordinates(tile)


class Measured:
    calls = 0

    def __call__(self, tile, aux):
        raise AssertionError("a measured map is asked for its measure")

    def measured(self, tile, aux):
        Measured.calls += 1
        cols, rows = coordinates(tile)
        return cols, rows, scan_bounds(cols, rows) if (cols < W).all() else None


class Planned:
    calls = 0

    def __call__(self, tile, aux):
        raise AssertionError("a planned map is asked for its plan")

    def plan(self, tile, aux):
        cols, rows = coordinates(tile)
        inside = (cols <= W) & (rows <= H)
        bounds = scan_bounds(np.where(inside, cols, np.nan), rows)
        plan = plan_source(bounds, W, H, "nearest")
        if plan is None:  # the window misses the source: planned as empty, not unplanned
            return EMPTY_PLAN
        return SourcePlan(plan.window, plan.pads, plan.shift_col, plan.shift_row,
                          (cols, rows, inside))

    def planned_maps(self, plan):
        Planned.calls += 1
        cols, rows, inside = plan.inputs
        return (np.where(inside, cols - np.float32(plan.shift_col), OUTSIDE),
                np.where(inside, rows - np.float32(plan.shift_row), OUTSIDE))


def test_maps_declare_their_capabilities():
    homography = HomographyMap(np.eye(3), GRID.transform)
    assert isinstance(homography, maps.PerspectiveMap) and isinstance(homography, maps.BoundedMap)
    assert isinstance(Plain(), maps.CoordinateMap)
    assert not isinstance(Plain(), (maps.BoundedMap, maps.MeasuredMap, maps.PlannedMap))
    assert isinstance(Measured(), maps.MeasuredMap) and not isinstance(Measured(), maps.PlannedMap)
    assert isinstance(Planned(), maps.PlannedMap) and not isinstance(Planned(), maps.PerspectiveMap)


@pytest.mark.parametrize("tile_size", [16, 512])
def test_every_path_gives_the_pixels_of_numpy_indexing(tmp_path, tile_size):
    rng = np.random.default_rng(3)
    photo = rng.integers(0, 255, (3, H, W), dtype="uint8")
    path = tmp_path / "photo.tif"
    with rasterio.open(path, "w", driver="GTiff", width=W, height=H, count=3,
                       dtype="uint8") as dst:
        dst.write(photo)
    layout = warp_layout(path, "alpha")
    ii, jj = np.mgrid[0:50, 0:60]
    expected = photo[:, 2 * ii + 3, W - 1 - jj]
    for cmap in (Plain(), Measured(), Planned()):
        out = np.full((layout.count, 50, 70), 7, dtype="uint8")

        def put(tile, array, out=out):
            w = tile.window
            out[:, w.row_off:w.row_off + w.height, w.col_off:w.col_off + w.width] = array

        calls = (Measured.calls, Planned.calls)
        warp_raster(path, GRID, cmap, put, layout=layout, resampling="nearest",
                    tile_size=tile_size, executor=Executor("local", 1))
        name = type(cmap).__name__
        np.testing.assert_array_equal(out[:3, :, :60], expected, err_msg=name)
        assert (out[3, :, :60] == 255).all() and (out[:, :, 60:] == 0).all(), name
        used = (Measured.calls > calls[0], Planned.calls > calls[1])
        assert used == (name == "Measured", name == "Planned")
