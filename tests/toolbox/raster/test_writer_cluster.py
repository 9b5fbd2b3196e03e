"""On a Dask cluster the writer closes a streamed GeoTIFF on the client and makes its overviews, or
its COG copy, on a worker that sees the file (shared storage), else on the client: the same bytes
as without a cluster, and GDAL's own reading of the overviews agrees with a block average."""

from __future__ import annotations

import hashlib
import os

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin
from rasterio.windows import Window

from toolbox.io.grid import GridSpec
from toolbox.raster.datasets import file_stamp
from toolbox.raster.writer import FinishTask, RasterWriter, finish_geotiff

ROWS, COLS = 700, 1100  # streamed (memory_mb 0), overviews at 2 and 4 (down to one 512 tile)


def _grid() -> GridSpec:
    return GridSpec(from_origin(500_000.0, 4_800_000.0, 2.0, 2.0), COLS, ROWS,
                    rasterio.crs.CRS.from_epsg(32632))


def _values() -> np.ndarray:
    rows, cols = np.mgrid[0:ROWS, 0:COLS]
    return (100.0 + 20.0 * np.sin(cols / 37.0) * np.cos(rows / 53.0)).astype("float32")


def _rgba() -> np.ndarray:
    rows, cols = np.mgrid[0:ROWS, 0:COLS]
    out = np.stack([cols % 251, (rows * 3 + cols) % 253, (rows + 2 * cols) % 127,
                    np.full_like(rows, 255)]).astype("uint8")
    out[3, :40] = 0  # a transparent strip
    return out


def _write(path, executor=None, cog=False):
    data = _rgba() if cog else _values()[np.newaxis]
    writer = RasterWriter(path, _grid(), data.shape[0], data.dtype, None if cog else -9999.0,
                          alpha=cog, cog=cog, executor=executor)
    with writer:
        for row in range(0, ROWS, 256):  # by windows, as the engine writes
            h = min(256, ROWS - row)
            writer.write(Window(0, row, COLS, h), data[:, row:row + h])
    return writer


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.distributed
@pytest.mark.slow
def test_overviews_and_cog_made_on_a_worker_are_the_local_bytes(tmp_path):
    from distributed import LocalCluster

    from toolbox.executor import Executor

    local = {cog: _write(tmp_path / f"local_{cog}.tif", cog=cog) for cog in (False, True)}
    assert all(w.finished_on is None for w in local.values())
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        dask = Executor("dask", 0, cluster.scheduler_address, "SCHEDULER")
        for cog in (False, True):
            out = tmp_path / f"dask_{cog}.tif"
            done = _write(out, dask, cog)
            host, pid = done.finished_on.rsplit(":", 1)
            assert int(pid) != os.getpid()  # a worker process made them
            assert _sha(out) == _sha(tmp_path / f"local_{cog}.tif"), cog
            assert not (tmp_path / f".{out.name}.tiled.tif").exists()
    with rasterio.open(tmp_path / "dask_False.tif") as src:
        assert src.overviews(1) == [2, 4]
        half = src.read(1, out_shape=(ROWS // 2, COLS // 2))  # GDAL picks the overview
    block = _values()[:ROWS // 2 * 2, :COLS // 2 * 2].reshape(ROWS // 2, 2, COLS // 2, 2)
    np.testing.assert_allclose(half, block.mean(axis=(1, 3)), atol=1e-3)


def test_a_worker_that_does_not_see_the_file_leaves_it_to_the_client(tmp_path, monkeypatch):
    """No shared storage: the worker's copy differs (here: none), it does nothing and says so;
    the client then makes the overviews itself, the same bytes as without a cluster."""
    _write(tmp_path / "local.tif")
    out = tmp_path / "closed.tif"
    writer = RasterWriter(out, _grid(), 1, "float32", -9999.0)
    task = writer._finish_task()
    writer.overviews = False  # the file as the client closes it, without overviews
    with writer:
        writer.write(Window(0, 0, COLS, ROWS), _values())
    task.stamp = file_stamp(out)
    before = out.read_bytes()
    moved = FinishTask(**{**task.__dict__, "tiled_path": str(tmp_path / "elsewhere.tif")})
    assert finish_geotiff(moved) is None
    assert finish_geotiff(FinishTask(**{**task.__dict__, "stamp": (1, 2)})) is None
    assert out.read_bytes() == before  # untouched
    # the writer's fallback: a "cluster" whose worker answers None
    import toolbox.executor

    monkeypatch.setattr(toolbox.executor, "map_tiles", lambda func, tasks, executor: [None])
    fallback = tmp_path / "fallback.tif"
    done = _write(fallback, executor=type("Dask", (), {"kind": "dask"})())
    assert done.finished_on.endswith(f":{os.getpid()}")
    assert _sha(fallback) == _sha(tmp_path / "local.tif")
