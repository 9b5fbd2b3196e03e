"""Issue 31, scale-out: every algorithm whose work splits by tiles, blocks or photos takes the
same SCHEDULER parameter (a Dask address, 'local', or DASK_SCHEDULER_ADDRESS when not given),
and a run on a Dask cluster of two worker processes writes the same file, byte for byte, as
the local run (the tasks come back in order; the client writes)."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

import toolbox
from toolbox.registry import spec_index

X0, Y0 = 1_688_000.0, 4_799_500.0

# the algorithms whose work splits into independent tasks (tiles, blocks, photos, pairs,
# seams, sheets)
SPLIT_WORK = ["carto:contours", "carto:sheet", "dem:aspect", "dem:cubic", "dem:ground",
              "dem:hillshade", "dem:idw", "dem:match", "dem:nearest", "dem:plane",
              "dem:quadratic", "dem:slope", "dem:tin_linear", "mosaic:build", "mosaic:cut",
              "mosaic:seamlines", "orientation:tiepoints", "ortho:batch", "ortho:photo",
              "rectify:image", "stereo:epipolar", "tin:to_raster", "tin:volume"]


def _only_on_workers(monkeypatch, module, name: str) -> None:
    """``module.name`` fails in this (the client's) process: the worker processes import their
    own modules, so a run that still succeeds did that work on the workers."""
    def not_here(*args, **kwargs):
        raise AssertionError(f"{module.__name__}.{name} ran in the client, not on a worker")

    monkeypatch.setattr(module, name, not_here)


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_every_split_algorithm_declares_the_same_scheduler_parameter():
    specs = spec_index()
    helps = {}
    for alg in SPLIT_WORK:
        params = {p["name"]: p for p in specs[alg]["parameters"]}
        assert "SCHEDULER" in params, alg
        assert params["SCHEDULER"]["optional"] and params["SCHEDULER"]["advanced"], alg
        helps[alg] = params["SCHEDULER"]["description"]
    assert all("DASK_SCHEDULER_ADDRESS" in text for text in helps.values()), helps


def test_a_bad_scheduler_address_is_refused_with_one_line(tmp_path):
    from conftest import run_cli

    dem = tmp_path / "dem.tif"
    _bumpy_dem(dem)
    proc = run_cli("run", "dem:slope", "--INPUT", str(dem), "--SCHEDULER", "not an address",
                   "--OUTPUT", str(tmp_path / "s.tif"))
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "SCHEDULER" in proc.stderr
    assert not (tmp_path / "s.tif").exists()


def _bumpy_dem(path, size=(90, 70)):
    rows, cols = np.mgrid[0:size[0], 0:size[1]]
    z = 300 + 20 * np.sin(cols / 9.0) * np.cos(rows / 7.0) + 0.3 * cols
    with rasterio.open(path, "w", driver="GTiff", width=size[1], height=size[0], count=1,
                       dtype="float32", crs="EPSG:3003", transform=from_origin(X0, Y0, 5, 5),
                       nodata=-9999) as dst:
        dst.write(z.astype("float32"), 1)


def _photo_and_transform(tmp_path):
    rng = np.random.default_rng(3)
    photo = tmp_path / "photo.tif"
    with rasterio.open(photo, "w", driver="GTiff", width=300, height=200, count=3,
                       dtype="uint8") as dst:
        dst.write(rng.integers(0, 255, (3, 200, 300), dtype="uint8"))
    gcps = tmp_path / "gcps.csv"
    corners = [(0.0, 0.0), (300, 0.0), (300, 200), (0.0, 200), (150, 70)]
    gcps.write_text("id,col,row,X,Y,Z,role\n" + "".join(
        f"P{k},{c},{r},{X0 + 0.5 * c + 0.05 * r},{Y0 - 0.5 * r},0,control\n"
        for k, (c, r) in enumerate(corners)))
    transform = tmp_path / "t.json"
    toolbox.run("rectify:estimate", {"INPUT": gcps, "CRS": "EPSG:3003", "MODEL": "homography",
                                     "OUTPUT": transform})
    return photo, transform


@pytest.mark.distributed
@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::rasterio.errors.NotGeoreferencedWarning")
def test_cluster_runs_write_the_local_files(tmp_path, monkeypatch, pair):
    from distributed import LocalCluster

    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    dem = tmp_path / "dem.tif"
    _bumpy_dem(dem)
    photo, transform = _photo_and_transform(tmp_path)
    orthos, _ = pair
    runs = {
        "carto:contours": ({"INPUT": dem, "INTERVAL": 2, "TILE_SIZE": 16}, "gpkg"),
        "rectify:image": ({"INPUT": photo, "TRANSFORM": transform, "CELL_SIZE": 0.5}, "tif"),
        "mosaic:build": ({"INPUT": [str(o.path) for o in orthos], "COG": False}, "tif"),
        "dem:hillshade": ({"INPUT": dem, "TILE_SIZE": 16}, "tif"),
    }
    local = {}
    for alg, (params, ext) in runs.items():
        out = tmp_path / f"{alg.replace(':', '_')}_local.{ext}"
        toolbox.run(alg, params | {"SCHEDULER": "local", "OUTPUT": out})
        local[alg] = out
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        for alg, (params, ext) in runs.items():
            out = tmp_path / f"{alg.replace(':', '_')}_dask.{ext}"
            result = toolbox.run(alg, params | {"SCHEDULER": cluster.scheduler_address,
                                                "OUTPUT": out})
            if ext == "tif":
                assert _sha(out) == _sha(local[alg]), alg
            else:  # a GeoPackage holds its creation time: compare the features
                import geopandas as gpd

                a, b = (gpd.read_file(f, layer="contours") for f in (local[alg], out))
                assert len(a) == len(b) > 10
                assert all(x.equals_exact(y, 0) for x, y in zip(a.geometry, b.geometry))
                assert result["STATISTICS"]["tiles"] > 4
                assert result["STATISTICS"]["executor"].startswith("dask scheduler")
        # sheets cut on the workers: the same files
        cut = {}
        for where in ("local", cluster.scheduler_address):
            folder = tmp_path / f"sheets_{len(cut)}"
            result = toolbox.run("mosaic:cut", {"INPUT": local["mosaic:build"], "SCALE": 500,
                                                "SHEET_WIDTH": 20, "SHEET_HEIGHT": 20,
                                                "SCHEDULER": where, "OUTPUT": folder})
            cut[where] = {f.name: _sha(f) for f in folder.glob("*.tif")}
            assert result["STATISTICS"]["written"] == len(cut[where]) >= 4
        assert cut["local"] == cut[cluster.scheduler_address]
        # the standard variable selects the cluster when SCHEDULER is not given
        monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", cluster.scheduler_address)
        out = tmp_path / "contours_env.gpkg"
        result = toolbox.run("carto:contours", runs["carto:contours"][0] | {"OUTPUT": out})
        assert result["STATISTICS"]["executor"] == f"dask scheduler {cluster.scheduler_address}"
        monkeypatch.delenv("DASK_SCHEDULER_ADDRESS")


@pytest.mark.parametrize("address, valid", [
    ("tcp://127.0.0.1:8786", True), ("head:8786", True), ("tls://h.example:1", True),
    ("tcp://[::1]:8786", True), ("a:b", False), ("tcp://head", False), ("http://h:1", False),
    ("h:0", False), ("h:70000", False), ("not an address", False), ("ü:12", False)])
def test_scheduler_addresses_are_checked_before_any_connection(address, valid):
    from toolbox.errors import ParameterError
    from toolbox.executor import resolve_executor

    if valid:
        assert resolve_executor(address).address == address
    else:
        with pytest.raises(ParameterError, match="SCHEDULER.*tcp://host:8786"):
            resolve_executor(address)


@pytest.mark.distributed
@pytest.mark.slow
def test_tie_points_matched_on_a_cluster_are_the_local_ones(tmp_path, monkeypatch):
    """orientation:tiepoints detects its photos (and their thumbnails), matches its pairs and
    refines its tracks on the workers (each reads the photos by their paths; features and tracks
    travel): the measurements and the pair table are the local run's, byte for byte, both with
    cameras (essential matrices, footprint pairs, refined) and without (fundamental matrices,
    thumbnail pairs)."""
    from pathlib import Path

    from distributed import LocalCluster

    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    monkeypatch.syspath_prepend(str(Path(__file__).parent / "matching"))
    import block_scene

    block = block_scene.make_block(tmp_path / "block")
    cases = {"project": {"PROJECT": block.project, "TERRAIN_HEIGHT": 350.0},
             "images": {"IMAGES": str(block.images[0].parent), "MAX_SIZE": 400,
                        "REFINE": False}}

    def run(case, where, tag):
        outs = {"OUTPUT": tmp_path / f"{case}_{tag}.csv", "PAIRS": tmp_path / f"{case}_{tag}_p.csv"}
        stats = toolbox.run("orientation:tiepoints",
                            cases[case] | outs | {"SCHEDULER": where})["STATISTICS"]
        return stats, {k: p.read_bytes() for k, p in outs.items()}

    local = {case: run(case, "local", "local") for case in cases}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        for case in cases:
            stats, files = run(case, cluster.scheduler_address, "dask")
            assert stats["executor"] == f"dask scheduler {cluster.scheduler_address}"
            assert stats["pairs_tied"] >= 10 and stats["points"] > 50, (case, stats)
            assert files == local[case][1], case
            assert stats["pairs_candidate"] == local[case][0]["pairs_candidate"]


@pytest.mark.distributed
@pytest.mark.slow
def test_dense_matching_pairs_on_a_cluster_write_the_local_dsm(tmp_path, monkeypatch):
    """dem:match matches its stereo pairs on the workers (each reads its pair's images by
    path) and fuses them on the client: DSM, COUNT and SPREAD are the local run's, byte for
    byte, and the LAZ holds the same points."""
    from pathlib import Path

    import laspy
    from distributed import LocalCluster

    from toolbox.photogrammetry.synthetic import hills_dem, wave_texture

    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    monkeypatch.syspath_prepend(str(Path(__file__).parents[1] / "algorithms" / "stereo"))
    import stereo_scene as sc

    z, transform = hills_dem((sc.X0 - 300, sc.Y0 - 100, sc.X0 + 1300, sc.Y0 + 1100), cell=4.0,
                             relief=40.0, base=300.0, seed=5)
    (tmp_path / "scene").mkdir()
    scene = sc.make_pair(tmp_path / "scene", z, transform,
                         wave_texture(seed=2, wavelength=(8.0, 40.0), waves=40),
                         names=("L", "R", "M"))

    def run(where, tag):
        outs = {name: tmp_path / f"{name.lower()}_{tag}.{ext}" for name, ext in
                (("OUTPUT", "tif"), ("COUNT", "tif"), ("SPREAD", "tif"), ("POINTS", "laz"))}
        stats = toolbox.run("dem:match", {
            "PROJECT": str(scene.project), "PHOTOS": "L,R,M", "MIN_HEIGHT": 280.0,
            "MAX_HEIGHT": 350.0, "CELL_SIZE": 8.0, "SCHEDULER": where} | outs)["STATISTICS"]
        return stats, outs

    local_stats, local = run("local", "local")
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        stats, outs = run(cluster.scheduler_address, "dask")
    assert stats["executor"] == f"dask scheduler {cluster.scheduler_address}"
    assert [p["pair"] for p in stats["pairs"]] == [p["pair"] for p in local_stats["pairs"]]
    assert len(stats["pairs"]) == 3 and stats["cells_with_value"] > 1000
    for name in ("OUTPUT", "COUNT", "SPREAD"):
        assert _sha(outs[name]) == _sha(local[name]), name
    a, b = (laspy.read(outs["POINTS"]), laspy.read(local["POINTS"]))
    assert len(a.points) == len(b.points) == stats["points_written"] > 10000
    assert np.array_equal(a.xyz, b.xyz) and np.array_equal(a.red, b.red)


def _grid_block(folder):
    """Four 260 x 260 m orthos on a 2 x 2 grid with 60 m overlaps: two seams in each direction,
    so seams sharing no cut polygon (0/1 and 2/3, then 0/2 and 1/3) are routed side by side."""
    from toolbox.demo.samples.mosaic import make_block

    specs = [{"name": f"g{r}{c}", "bounds": (200 * c, 200 * r, 200 * c + 260, 200 * r + 260),
              "nadir": (200 * c + 130, 200 * r + 130), "gain": 1.0 + 0.04 * (2 * r + c)}
             for r in range(2) for c in range(2)]
    orthos, _ = make_block(folder, specs, building=(230.0, 230.0, 15.0))
    return [str(o.path) for o in orthos]


def _same_geopackage(a, b):
    """The two GeoPackages hold the same layers with the same rows and geometries, exactly (a
    GeoPackage stores its creation time: the bytes differ)."""
    import geopandas as gpd
    import pyogrio
    from geopandas.testing import assert_geodataframe_equal

    names = [name for name, _ in pyogrio.list_layers(a)]
    assert names == [name for name, _ in pyogrio.list_layers(b)]
    for name in names:
        assert_geodataframe_equal(gpd.read_file(a, layer=name), gpd.read_file(b, layer=name))
    return names


def test_seam_waves_keep_the_order_of_seams_sharing_a_polygon():
    from toolbox.mosaic.seams import seam_waves

    pairs = [(0, 1), (2, 3), (0, 2), (1, 3), (0, 3), (4, 5), (1, 2)]
    assert seam_waves(pairs) == [[0, 1, 5], [2, 3], [4, 6]]
    assert seam_waves([]) == []


def test_seams_routed_in_waves_are_the_seams_routed_one_by_one(tmp_path):
    """least_cost_cells (waves of independent seams, each wave's tasks made from the polygons
    the earlier waves left) gives the cut polygons of routing every seam in turn on the
    polygons the previous ones left."""
    from toolbox.executor import Executor
    from toolbox.mosaic.block import centres_of, open_block
    from toolbox.mosaic.partition import seamlines, voronoi_cells
    from toolbox.mosaic.seams import CostWeights, PairCost, SeamTask, least_cost_cells, route_seam

    sources, crs = open_block(_grid_block(tmp_path), "INPUT", None)
    centres = centres_of(sources, "nadir", None, None)
    footprints = [s.footprint for s in sources]
    start = voronoi_cells(footprints, centres)

    def cost_for(i, j):
        return PairCost(sources[i], sources[j], crs, CostWeights(), centres=(centres[i],
                                                                            centres[j]))

    waved, report = least_cost_cells(start, footprints, cost_for, 2.0,
                                     executor=Executor("local", 2))
    cells = list(start)
    pairs = [(i, j) for i, j, _ in sorted(seamlines(cells), key=lambda s: -s[2].length)]
    for i, j in pairs:
        entry, new = route_seam(SeamTask(i, j, cells[i], cells[j], footprints[i], footprints[j],
                                         cost_for(i, j), 2.0, 4_000_000))
        if new is not None:
            cells[i], cells[j] = new
    assert sum(e["method"] == "least_cost" for e in report) >= 4
    assert [(e["a"], e["b"]) for e in report] == pairs
    assert all(a.equals_exact(b, 0) for a, b in zip(waved, cells, strict=True))
    assert not all(a.equals_exact(b, 0) for a, b in zip(waved, start, strict=True))


def test_local_seams_report_progress_per_seam_and_stop_when_canceled(tmp_path, monkeypatch):
    """Run locally, least_cost_cells moves the progress at every seam (not once per wave) and a
    cancellation asked while a seam is routed stops the run inside that route."""
    import toolbox.mosaic.seams as seams
    from toolbox.errors import CanceledError
    from toolbox.executor import Executor
    from toolbox.mosaic.block import centres_of, open_block
    from toolbox.mosaic.partition import voronoi_cells

    sources, crs = open_block(_grid_block(tmp_path), "INPUT", None)
    centres = centres_of(sources, "nadir", None, None)
    footprints = [s.footprint for s in sources]
    start = voronoi_cells(footprints, centres)

    def cost_for(i, j):
        return seams.PairCost(sources[i], sources[j], crs, seams.CostWeights(),
                              centres=(centres[i], centres[j]))

    feedback = toolbox.Feedback()
    progress = []
    feedback.set_progress = progress.append
    _, report = seams.least_cost_cells(start, footprints, cost_for, 2.0, feedback=feedback,
                                       executor=Executor("local", 1))
    assert progress == [100.0 * k / len(report) for k in range(len(report))]
    assert len(report) > len(seams.seam_waves([(e["a"], e["b"]) for e in report]))

    canceled = toolbox.Feedback()
    route = seams.seam_path

    def cancel_then_route(*args):
        canceled.cancel()  # asked while the first seam is being routed
        return route(*args)

    monkeypatch.setattr(seams, "seam_path", cancel_then_route)
    with pytest.raises(CanceledError):
        seams.least_cost_cells(start, footprints, cost_for, 2.0, feedback=canceled,
                               executor=Executor("local", 1))


@pytest.mark.distributed
@pytest.mark.slow
def test_seams_and_vector_sheets_on_a_cluster_are_the_local_ones(tmp_path, monkeypatch):
    """mosaic:seamlines routes independent seams on the workers and mosaic:cut clips a vector
    layer's sheets there: the GeoPackages hold what the local runs write."""
    from distributed import LocalCluster

    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    orthos = _grid_block(tmp_path / "block")
    seams = {"INPUT": orthos, "METHOD": "least_cost", "SEAM_CELL_SIZE": 2.0}

    def cut(where, tag):
        folder = tmp_path / f"sheets_{tag}"
        stats = toolbox.run("mosaic:cut", {"INPUT": tmp_path / "seams_local.gpkg", "SCALE": 1000,
                                           "SHEET_WIDTH": 15, "SHEET_HEIGHT": 15,
                                           "SCHEDULER": where,
                                           "OUTPUT": folder})["STATISTICS"]
        return stats, folder

    local = toolbox.run("mosaic:seamlines", seams | {"SCHEDULER": "local",
                                                     "OUTPUT": tmp_path / "seams_local.gpkg"})
    cut_local, folder_local = cut("local", "local")
    import toolbox.mosaic.sheets as sheets

    _only_on_workers(monkeypatch, sheets, "clip_vector")
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        address = cluster.scheduler_address
        dask = toolbox.run("mosaic:seamlines", seams | {"SCHEDULER": address,
                                                        "OUTPUT": tmp_path / "seams_dask.gpkg"})
        cut_dask, folder_dask = cut(address, "dask")
    assert dask["STATISTICS"]["executor"] == f"dask scheduler {address}"
    assert sum(s["method"] == "least_cost" for s in dask["STATISTICS"]["seams"]) >= 4
    assert dask["STATISTICS"]["seams"] == local["STATISTICS"]["seams"]
    assert "seamlines" in _same_geopackage(tmp_path / "seams_local.gpkg",
                                           tmp_path / "seams_dask.gpkg")
    assert cut_dask["files"] == cut_local["files"] and cut_dask["written"] >= 4
    for name in cut_local["files"]:
        _same_geopackage(folder_local / name, folder_dask / name)


@pytest.mark.distributed
@pytest.mark.slow
def test_map_sheets_drawn_on_a_cluster_are_the_local_ones(tmp_path, monkeypatch):
    """carto:sheet draws each sheet of SHEETS on a worker (which writes its FOLDER files) and
    gathers the pages of OUTPUT from the workers' figures: with a fixed SOURCE_DATE_EPOCH (the
    PDFs' creation date) every file is the local run's, byte for byte."""
    import geopandas as gpd
    import shapely
    from distributed import LocalCluster

    pypdf = pytest.importorskip("pypdf", reason="pypdf (dev extra) reads the PDFs back")
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")  # inherited by the worker processes
    dem = tmp_path / "dem.tif"
    _bumpy_dem(dem)
    contours = tmp_path / "contours.gpkg"
    toolbox.run("carto:contours", {"INPUT": dem, "INTERVAL": 5, "OUTPUT": contours})
    gpd.GeoDataFrame({"name": ["W", "E"]}, geometry=[
        shapely.box(X0, Y0 - 450, X0 + 175, Y0), shapely.box(X0 + 175, Y0 - 450, X0 + 350, Y0)],
        crs="EPSG:3003").to_file(tmp_path / "sheets.gpkg")

    def run(where, tag):
        folder = tmp_path / f"folder_{tag}"
        result = toolbox.run("carto:sheet", {
            "SHEETS": tmp_path / "sheets.gpkg", "SHEET_ID": "name", "SCALE": 2000, "BASE": dem,
            "CONTOURS": contours, "DATE": "2026-12-03", "SCHEDULER": where,
            "OUTPUT": tmp_path / f"atlas_{tag}.pdf", "PNG": tmp_path / f"first_{tag}.png",
            "FOLDER": folder})
        files = {p.name: p.read_bytes() for p in sorted(folder.iterdir())}
        files |= {name: (tmp_path / f"{name}_{tag}.{ext}").read_bytes()
                  for name, ext in (("atlas", "pdf"), ("first", "png"))}
        return result["SHEETS_WRITTEN"], files

    local_sheets, local = run("local", "local")
    import toolbox.cartography.sheet_job as sheet_job

    _only_on_workers(monkeypatch, sheet_job, "render_sheet")
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        sheets, files = run(cluster.scheduler_address, "dask")
    assert sorted(files) == ["E.pdf", "E.png", "W.pdf", "W.png", "atlas", "first"]
    assert [s["sheet"] for s in sheets] == ["W", "E"]
    assert [{k: v for k, v in s.items() if k != "files"} for s in sheets] == \
        [{k: v for k, v in s.items() if k != "files"} for s in local_sheets]
    assert len(pypdf.PdfReader(tmp_path / "atlas_dask.pdf").pages) == 2
    assert {name for name in files if files[name] != local[name]} == set()
