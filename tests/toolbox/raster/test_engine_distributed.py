"""Every algorithm on the shared raster engine honours DASK_SCHEDULER_ADDRESS (the standard Dask
variable), not only those with a SCHEDULER parameter: with it set, the tiles run on the cluster
and the file is byte-identical to the local run's."""

from __future__ import annotations

import hashlib

import pytest

import toolbox


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.distributed
@pytest.mark.slow
def test_engine_algorithms_run_on_the_cluster_of_the_environment(tmp_path, monkeypatch,
                                                                 plane_dem, points_gpkg):
    from distributed import LocalCluster

    dem = plane_dem[0]
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    toolbox.run("tin:delaunay", {"INPUT": points_gpkg, "OUTPUT": tmp_path / "tin.gpkg"})
    runs = {
        "dem:hillshade": {"INPUT": dem, "TILE_SIZE": 16},
        "dem:slope": {"INPUT": dem, "TILE_SIZE": 16},
        "dem:aspect": {"INPUT": dem, "TILE_SIZE": 16},
        "tin:to_raster": {"TIN": tmp_path / "tin.gpkg", "CELL_SIZE": 0.1},  # 1000² cells: 4 tiles
    }
    local = {}
    for alg, params in runs.items():
        out = tmp_path / f"{alg[4:]}_local.tif"
        toolbox.run(alg, params | {"OUTPUT": out})
        local[alg] = _sha(out)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", cluster.scheduler_address)
        for alg, params in runs.items():
            out = tmp_path / f"{alg[4:]}_dask.tif"
            toolbox.run(alg, params | {"OUTPUT": out})
            assert _sha(out) == local[alg], alg
        # and the engine said where the tiles ran
        from toolbox.io.raster import open_raster_info
        from toolbox.terrain.shading import hillshade_bytes, shade_raster

        done = shade_raster(open_raster_info(dem), 1, tmp_path / "direct.tif", hillshade_bytes,
                            "uint8", 0, None, tile_size=16)
        assert done["executor"] == f"dask scheduler {cluster.scheduler_address}"
        assert done["tiles"] == 16  # 60 x 50 cells in 16-cell tiles
