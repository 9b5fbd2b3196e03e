"""Vector inputs and outputs found wrong by a sweep: a multi-layer file read from its first
layer without a word, a CSV ``|subset=`` on the coordinate columns refused, GDAL virtual paths
called missing files, Shapefile field names cut in silence, and a failed GeoPackage/FlatGeobuf
write blamed on the (intact) input."""

from __future__ import annotations

import errno
import logging
import warnings
import zipfile

import geopandas as gpd
import numpy as np
import pandas as pd
import pyogrio
import pytest
import rasterio
import shapely

import toolbox
from toolbox.errors import OutputWriteError, ParameterError
from toolbox.io.vector import open_layer, read_vector
from toolbox.io.vector_write import write_layers

CRS = "EPSG:3003"
X0, Y0 = 1_688_000.0, 4_800_000.0


@pytest.fixture
def toolbox_warnings():
    """The warnings logged on the toolbox logger while the test runs."""
    messages: list[str] = []

    class Collect(logging.Handler):
        def emit(self, record):
            if record.levelno == logging.WARNING:
                messages.append(record.getMessage())

    logger = logging.getLogger("toolbox")
    handler = Collect()
    logger.addHandler(handler)
    try:
        yield messages
    finally:
        logger.removeHandler(handler)


def _points(n=60, seed=1, dz=0.0):
    rng = np.random.default_rng(seed)
    x, y = X0 + rng.uniform(0, 200, n), Y0 + rng.uniform(0, 200, n)
    z = rng.uniform(280, 340, n) + dz
    return gpd.GeoDataFrame({"k": np.arange(n)}, geometry=shapely.points(x, y, z), crs=CRS)


def test_multi_layer_file_without_layername_warns_naming_the_layers(tmp_path, toolbox_warnings):
    """The first layer of several is read, and a warning names it, the others and the syntax
    to choose; a named layer, a TIN's GeoPackage (read by its layer names) and vector:info
    (every layer) do not warn."""
    path = tmp_path / "multi.gpkg"
    real = _points()
    write_layers(path, {"decoy": _points(dz=1000.0), "real": real, "other": _points(seed=2)})
    out = toolbox.run("dem:nearest", {"INPUT": path, "CELL_SIZE": 20,
                                      "OUTPUT": tmp_path / "first.tif"})
    assert len(toolbox_warnings) == 1
    text = toolbox_warnings[0]
    assert "INPUT" in text and "'decoy'" in text and "'real'" in text and "'other'" in text
    assert f"'{path}|layername=NAME'" in text
    with rasterio.open(out["OUTPUT"]) as src:  # the default layer is the first (z + 1000)
        assert src.read(1, masked=True).min() > 1000
    toolbox_warnings.clear()
    toolbox.run("dem:nearest", {"INPUT": f"{path}|layername=real", "CELL_SIZE": 20,
                                "OUTPUT": tmp_path / "real.tif"})
    toolbox.run("vector:info", {"INPUT": path})
    tin = toolbox.run("tin:delaunay", {"INPUT": f"{path}|layername=real",
                                       "OUTPUT": tmp_path / "tin.gpkg"})["OUTPUT"]
    assert [str(n) for n, _ in pyogrio.list_layers(tin)][:3] == ["triangles", "nodes", "edges"]
    toolbox.run("tin:to_raster", {"TIN": tin, "CELL_SIZE": 20, "OUTPUT": tmp_path / "t.tif"})
    toolbox.run("carto:contours", {"TIN": tin, "INTERVAL": 10, "OUTPUT": tmp_path / "c.gpkg"})
    assert toolbox_warnings == []


def test_seamlines_geopackage_as_cutlines_does_not_warn(pair, seams, tmp_path, toolbox_warnings):
    """mosaic:build's CUTLINES is mosaic:seamlines' GeoPackage as written: its first layer,
    cut_polygons, is the one meant (the seamlines layer is read by name)."""
    orthos, _ = pair
    cutlines = seams["least_cost"]["OUTPUT"]
    assert [str(n) for n, _ in pyogrio.list_layers(cutlines)][:2] == ["cut_polygons", "seamlines"]
    toolbox.run("mosaic:build", {"INPUT": [str(o.path) for o in orthos], "CUTLINES": cutlines,
                                 "OUTPUT": tmp_path / "m.tif"})
    assert not [w for w in toolbox_warnings if "none was named" in w]


def test_csv_subset_on_the_coordinate_columns(tmp_path):
    """``|subset=`` may name the X/Y/Z columns (as ogrinfo -where does); they are not fields of
    the layer, and the points are the same as without a subset."""
    rng = np.random.default_rng(3)
    table = pd.DataFrame({"X": X0 + rng.uniform(0, 100, 40), "Y": Y0 + rng.uniform(0, 100, 40),
                          "Z": rng.uniform(280, 340, 40)})
    table["cls"] = (table["Z"] > 300).astype(int)
    path = tmp_path / "pts.csv"
    table.to_csv(path, index=False)
    whole = read_vector(path, crs=CRS)
    assert list(whole.columns) == ["cls", "geometry"] and open_layer(path).fields == ["cls"]
    assert np.allclose(shapely.get_coordinates(whole.geometry, include_z=True),
                       table[["X", "Y", "Z"]].to_numpy())
    for where, keep in (("Z > 300", table["Z"] > 300), ("X < 1688050", table["X"] < X0 + 50)):
        part = read_vector(f"{path}|subset={where}", crs=CRS)
        assert list(part.columns) == ["cls", "geometry"]
        assert np.allclose(shapely.get_coordinates(part.geometry, include_z=True),
                           table.loc[keep, ["X", "Y", "Z"]].to_numpy())
    out = toolbox.run("tin:delaunay", {"INPUT": f"{path}|subset=Z > 300", "CRS": CRS,
                                       "OUTPUT": tmp_path / "t.gpkg"})
    assert out["STATISTICS"]["nodes"] == int((table["Z"] > 300).sum())


def test_gdal_virtual_paths_are_refused_by_name(tmp_path, plane_dem):
    """/vsizip/ (and any /vsi...) inputs: one line saying so, nothing written; the zip itself
    was not what was missing."""
    dem, _, _ = plane_dem
    archive = tmp_path / "dem.zip"
    with zipfile.ZipFile(archive, "w") as z:
        z.write(dem, "dem.tif")
    _points().to_file(tmp_path / "pts.gpkg")
    with zipfile.ZipFile(tmp_path / "pts.zip", "w") as z:
        z.write(tmp_path / "pts.gpkg", "pts.gpkg")
    cases = [("dem:slope", {"INPUT": f"/vsizip/{archive}/dem.tif"}),
             ("tin:delaunay", {"INPUT": f"/vsizip/{tmp_path}/pts.zip/pts.gpkg"}),
             ("mosaic:cut", {"INPUT": f"/vsizip/{archive}/dem.tif", "SCALE": 1000}),
             ("mosaic:cut", {"INPUT": f"/vsizip/{tmp_path}/pts.zip/pts.gpkg|layerid=0",
                             "SCALE": 1000})]
    for alg, params in cases:
        out = tmp_path / ("o.tif" if alg == "dem:slope" else "o.gpkg" if alg == "tin:delaunay"
                          else "sheets")
        with pytest.raises(ParameterError, match=r"^INPUT '/vsizip/.*': GDAL virtual file "
                           r"systems \(/vsi\.\.\.\) are not supported: unzip"):
            toolbox.run(alg, params | {"OUTPUT": out})
        assert not out.exists()


def test_shapefile_output_warns_listing_renamed_fields(tmp_path, toolbox_warnings):
    frame = _points(5)
    frame["quadratic_z"] = 1.0
    frame["quadratic_err"] = 2.0
    frame["short"] = 3
    path = tmp_path / "r.shp"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        write_layers(path, {"r": frame})
    assert not [w for w in caught if "laundered" in str(w.message)]  # said once, by the toolbox
    written = list(pyogrio.read_info(path)["fields"])
    assert written == ["k", "quadratic_", "quadrati_1", "short"]
    assert len(toolbox_warnings) == 1
    assert "quadratic_z -> quadratic_, quadratic_err -> quadrati_1" in toolbox_warnings[0]
    assert "short" not in toolbox_warnings[0] and "r.shp" in toolbox_warnings[0]
    toolbox_warnings.clear()
    write_layers(tmp_path / "r.gpkg", {"r": frame})  # other formats keep the names
    assert list(pyogrio.read_info(tmp_path / "r.gpkg")["fields"]) == \
        ["k", "quadratic_z", "quadratic_err", "short"]
    assert toolbox_warnings == []


@pytest.mark.parametrize("ext", [".gpkg", ".fgb"])
@pytest.mark.parametrize("disk_full", [True, False])
def test_failed_tin_write_names_output_not_input(tmp_path, monkeypatch, ext, disk_full):
    """GDAL's write error of a TIN layer (what a full disk gives: pyogrio raises it without an
    errno) is OUTPUT's failed write, not a corrupt INPUT: "no space left" when the disk shows
    it, else the library's words naming OUTPUT's final path; nothing is left."""
    from pyogrio.errors import DataLayerError

    import toolbox.io.write_failures as write_failures

    source = tmp_path / "in" / "pts.gpkg"
    source.parent.mkdir()
    _points().to_file(source)

    def full(*args, **kwargs):
        staged = args[1]
        raise DataLayerError(f"Error while writing batch to OGR layer {staged}: "
                             "sqlite3_exec(COMMIT) failed: database or disk is full")

    monkeypatch.setattr(pyogrio, "write_arrow", full)
    monkeypatch.setattr(write_failures, "disk_errno",
                        lambda path: errno.ENOSPC if disk_full else None)
    out = tmp_path / "out" / f"t{ext}"
    with pytest.raises(OutputWriteError) as caught:
        toolbox.run("tin:delaunay", {"INPUT": source, "OUTPUT": out})
    text = str(caught.value)
    if disk_full:
        assert text == f"no space left on device writing OUTPUT '{out}'; nothing was written"
    else:
        assert text.startswith(f"cannot write OUTPUT '{out}': Error while writing batch")
        assert f"layer {out}:" in text and ".part" not in text  # the final path, not the staged
    assert "INPUT" not in text and not (tmp_path / "out").exists()
