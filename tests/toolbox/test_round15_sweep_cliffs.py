"""Round 15 sweep (cliffs): parameter values that made a run take forever or eat all memory
now refused before the work, naming the parameter (toolbox.limits.check_size)."""

from __future__ import annotations

import geopandas as gpd
import pytest

import toolbox
from tests.toolbox import test_size_guards as size_guards
from tests.toolbox.test_size_guards import CRS, E0, N0, never
from toolbox.errors import ParameterError

lines = size_guards.lines  # the fixture: a 300 m line


def test_densify_counts_the_moved_vertices_features(lines, tmp_path, monkeypatch):
    """densify writes a moved_vertices point (about 1 kB of memory) per added vertex: 300 m at
    DISTANCE 0.01 adds 29,999 of them, over a features limit of 1,000 (the vertices limit,
    meant for coordinate arrays, let 1e8 of them through: ~100 GB)."""
    from toolbox.attribution import editing

    monkeypatch.setattr(editing, "densify", never)
    monkeypatch.setenv("TOOLBOX_MAX_FEATURES", "1000")
    with pytest.raises(ParameterError) as info:
        toolbox.run("attribution:sample", {"INPUT": lines, "METHOD": "densify",
                                           "DISTANCE": 0.01, "OUTPUT": tmp_path / "s.gpkg"})
    text = str(info.value)
    assert info.value.name == "DISTANCE" and text.startswith("DISTANCE 0.01 "), text
    assert "30,000 added vertices" in text and "limit of 1,000 features" in text, text
    assert "TOOLBOX_MAX_FEATURES" in text
    # the distance method writes a point per removed input vertex only: not refused
    toolbox.run("attribution:sample", {"INPUT": lines, "METHOD": "distance", "DISTANCE": 0.01,
                                       "OUTPUT": tmp_path / "d.gpkg"})
    # within the limit densify runs and adds the vertices (300 m / 1 m: 299 added)
    monkeypatch.undo()
    monkeypatch.setenv("TOOLBOX_MAX_FEATURES", "1000")
    toolbox.run("attribution:sample", {"INPUT": lines, "METHOD": "densify", "DISTANCE": 1.0,
                                       "OUTPUT": tmp_path / "k.gpkg"})
    assert len(gpd.read_file(tmp_path / "k.gpkg", layer="moved_vertices")) == 299


def test_idw_sectors_tile_stops_when_its_run_is_canceled(monkeypatch):
    """A SECTORS search near the data's edge scans every point within RADIUS: with a large
    RADIUS a 512-cell tile ran for tens of seconds in one compiled call, and Ctrl-C waited for
    it (28 s measured, exit 130 at last). The tile now runs row by row and stops when the
    thread pool's caller has left (toolbox.executor.abandoned)."""
    import threading
    import time

    import numpy as np

    from toolbox.errors import CanceledError
    from toolbox.executor import thread_pool
    from toolbox.terrain.gridding import idw_kernel

    started = threading.Event()

    def slow(*args):  # stands for the compiled kernel: 20 ms per row given
        started.set()
        time.sleep(0.02 * len(args[10]))  # args[10]: the row centres ys

    monkeypatch.setattr(idw_kernel, "_grid_sectors", slow)
    xyz = np.array([[0.0, 0.0, 1.0], [10.0, 0.0, 2.0], [0.0, 10.0, 3.0]])
    xs, ys = np.arange(0.5, 10.0), np.arange(0.5, 150.0)  # 150 rows: 3 s in one call
    mask = np.ones((len(ys), len(xs)), bool)
    future = None
    began = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        with thread_pool(2) as submit:
            future = submit(idw_kernel.idw_grid, xyz, xs, ys, mask, 8, 2.0, 100.0, 4)
            assert started.wait(5)
            raise KeyboardInterrupt  # Ctrl-C in the main thread: the pool waits for its tasks
    assert time.perf_counter() - began < 1.0
    assert isinstance(future.exception(), CanceledError)
    # not canceled: every row computed by the real kernel (a grid of 1 x 3 rows, exact at data)
    monkeypatch.undo()
    out = idw_kernel.idw_grid(xyz, np.array([0.0]), np.array([0.0, 10.0, 5.0]),
                              np.ones((3, 1), bool), neighbours=8, radius=100.0, sectors=4)
    assert out[0, 0] == 1.0 and out[1, 0] == 3.0 and 1.0 < out[2, 0] < 3.0


def _noisy_dem(tmp_path, rows, cols):
    import numpy as np
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    slope = np.add.outer(np.zeros(rows), np.linspace(0.0, 50.0, cols))  # 0 .. 50 m
    z = slope + np.random.default_rng(0).normal(0.0, 3.0, (rows, cols))  # a DSM's noise
    path = tmp_path / "noisy.tif"
    write_raster(path, z.astype("float32"), from_origin(E0, N0 + rows, 1, 1), CRS,
                 nodata=-9999.0)
    return path, z


@pytest.mark.parametrize("in_memory", [True, False])
def test_contours_of_a_noisy_dem_count_its_level_crossings(tmp_path, monkeypatch, in_memory):
    """carto:contours' vertex guard counted (width + height) cells per level: a noisy DSM's
    levels wind around every cell (2000 x 2000 cells, 3 m of noise, INTERVAL 1: 27 million
    vertices, not the 2 million estimated) and the run died with MemoryError (exit 3) under
    3 GB. The guard now counts the edges each level crosses: the vertices traced."""
    import numpy as np

    from toolbox.cartography import contour_io

    path, z = _noisy_dem(tmp_path, 60, 80)
    k = np.floor(z.astype("float32").astype("float64") / 1.0)
    truth = np.abs(np.diff(k, axis=0)).sum() + np.abs(np.diff(k, axis=1)).sum()
    assert truth > 3 * 62 * (60 + 80)  # more than levels x (width + height): 8,680
    if not in_memory:  # read by 32-cell tiles: a few crossings between tiles are not counted
        monkeypatch.setattr(contour_io, "IN_MEMORY_CELLS", 100)
    monkeypatch.setattr(contour_io, "trace_raster", never)
    limit = int(0.8 * truth)  # over the old estimate (about 9,000), under the vertices
    monkeypatch.setenv("TOOLBOX_MAX_VERTICES", str(limit))
    with pytest.raises(ParameterError) as info:
        toolbox.run("carto:contours", {"INPUT": path, "INTERVAL": 1.0, "TILE_SIZE": 32,
                                       "OUTPUT": tmp_path / "c.gpkg"})
    text = str(info.value)
    assert info.value.name == "INTERVAL" and "vertices, over the limit of" in text, text
    shown = float(text.split("gives about ")[1].split(" ")[0].replace(",", ""))
    assert 0.9 * truth <= shown <= truth, (shown, truth)
    assert contour_io.level_crossings(z.astype("float32"), 1.0, 0.0, band=7) == truth


@pytest.fixture
def orthos(tmp_path):
    import numpy as np
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    paths = []
    for i, x0 in enumerate((E0, E0 + 300)):  # 600 x 300 cells of 1 m each, 300 m overlap
        path = tmp_path / f"o{i}.tif"
        write_raster(path, np.full((1, 300, 600), 100 + 50 * i, "uint8"),
                     from_origin(x0, N0 + 300, 1, 1), CRS)
        paths.append(path)
    return paths


@pytest.mark.parametrize("blend, name, value", [("feather", "FEATHER_WIDTH", 400.0),
                                                ("multiband", "LEVELS", 7)])
def test_mosaic_halo_is_guarded(orthos, tmp_path, monkeypatch, blend, name, value):
    """mosaic:build reads each 512-cell tile with a halo of half the feather width (or the
    pyramid's reach): FEATHER_WIDTH 2000 (m, for 2) at 0.25 m cells made 8,516 x 8,516-cell
    windows and died with MemoryError (exit 3) under 3 GB, as did LEVELS 10. The haloed window
    is now checked against the "window cells" limit before any tile is read."""
    from toolbox.mosaic import build

    monkeypatch.setenv("TOOLBOX_MAX_WINDOW_CELLS", "200000")
    monkeypatch.setattr(build, "write_mosaic", never)
    with pytest.raises(ParameterError) as info:  # 900 x 300 grid: min(512 + 2 x 202, 900) x 300
        toolbox.run("mosaic:build", {"INPUT": orthos, "BLEND": blend, name: value,
                                     "OUTPUT": tmp_path / "m.tif"})
    text = str(info.value)
    assert info.value.name == name and text.startswith(f"{name} {value:g}"), text
    assert "over the limit of 200,000 window cells" in text and "cells per tile" in text, text
    assert "TOOLBOX_MAX_WINDOW_CELLS" in text
    if blend == "feather":
        assert "a halo of 202 cells" in text and "270,000 cells per tile" in text  # 900 x 300, clipped, text
    monkeypatch.undo()
    monkeypatch.setenv("TOOLBOX_MAX_WINDOW_CELLS", "200000")
    small = {"FEATHER_WIDTH": 2.0, "LEVELS": 2}[name]  # halo 3 / 16 cells: within the limit
    toolbox.run("mosaic:build", {"INPUT": orthos, "BLEND": blend, name: small,
                                 "OUTPUT": tmp_path / "m.tif"})


def test_tin_contours_of_a_noisy_tin_count_its_level_crossings(monkeypatch):
    """The TIN path of carto:contours estimated 2·sqrt(triangles) vertices per level: a noisy
    TIN's levels cross most of its edges. The guard counts the crossings of the edges."""
    import numpy as np
    from scipy.spatial import Delaunay

    from toolbox.cartography import contour_io

    rng = np.random.default_rng(1)
    xy = rng.uniform(0.0, 100.0, (2000, 2))
    xyz = np.column_stack([xy, xy[:, 0] * 0.5 + rng.normal(0.0, 3.0, len(xy))])  # 0 .. 50 m
    triangles = Delaunay(xy).simplices
    edges = {tuple(sorted(e)) for t in triangles for e in ((t[0], t[1]), (t[1], t[2]),
                                                           (t[2], t[0]))}
    k = np.floor(xyz[:, 2])
    truth = sum(abs(k[a] - k[b]) for a, b in edges)  # vertices of the contours at INTERVAL 1
    levels = np.ptp(k) + 1
    assert truth > 2 * levels * 2 * np.sqrt(len(triangles))  # the old estimate: 7,572
    monkeypatch.setattr(contour_io, "tin_contours", never)
    monkeypatch.setenv("TOOLBOX_MAX_VERTICES", str(int(0.8 * truth)))
    with pytest.raises(ParameterError) as info:
        contour_io.tin_layer_contours(xyz, triangles, 1.0, 0.0)
    text = str(info.value)
    shown = float(text.split("gives about ")[1].split(" ")[0].replace(",", ""))
    assert info.value.name == "INTERVAL" and 0.9 * truth <= shown <= truth, (text, truth)
