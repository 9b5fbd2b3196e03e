"""mosaic:cut: a sheet grid from scale and sheet size gives files named by sheet id whose
pixels are exactly the mosaic's, with nothing lost; polygon sheets with an id field; vector
clipping (areas add up); the output folder is staged and replaced only with --overwrite."""

from pathlib import Path

import geopandas as gpd
import numpy as np
import pytest
import rasterio
import shapely

import toolbox
from toolbox.demo.samples.mosaic import ORIGIN
from toolbox.errors import OutputExistsError, ParameterError


@pytest.fixture(scope="module")
def mosaic(pair, tmp_path_factory):
    orthos, _ = pair
    folder = tmp_path_factory.mktemp("cut")
    return toolbox.run("mosaic:build", {"INPUT": [str(o.path) for o in orthos], "BLEND": "none",
                                        "OUTPUT": str(folder / "mosaic.tif")})["OUTPUT"]


def test_sheet_grid_from_scale_and_size(mosaic, tmp_path):
    # 1:1000, 25 x 20 cm -> 250 x 200 m sheets; the mosaic spans x 1688000-1689000, y 4799000-400
    out = toolbox.run("mosaic:cut", {"INPUT": str(mosaic), "SCALE": 1000, "SHEET_WIDTH": 25,
                                     "SHEET_HEIGHT": 20, "OUTPUT": str(tmp_path / "sheets")})
    folder = Path(out["OUTPUT"])
    ix = range(int(ORIGIN[0] // 250), int(ORIGIN[0] // 250) + 4)
    iy = range(int(ORIGIN[1] // 200), int(ORIGIN[1] // 200) + 2)
    expected = {f"{i}_{j}.tif" for i in ix for j in iy}
    assert {p.name for p in folder.glob("*.tif")} == expected
    assert out["STATISTICS"]["written"] == 8
    with rasterio.open(mosaic) as src:
        whole = src.read()
        t = src.transform
        colours, nodata = src.colorinterp, src.nodata
    covered = np.zeros(whole.shape[1:], int)
    for path in folder.glob("*.tif"):
        i, j = map(int, path.stem.split("_"))
        with rasterio.open(path) as s:
            assert s.bounds == (i * 250, j * 200, (i + 1) * 250, (j + 1) * 200)
            assert s.transform.a == t.a and s.crs == "EPSG:3003"
            # the RasterWriter's GeoTIFF: tiled, compressed, the mosaic's bands and alpha
            assert s.profile["tiled"] and s.compression.name == "deflate"
            assert s.colorinterp == colours and s.nodata == nodata
            c0, r0 = round((s.transform.c - t.c) / t.a), round((s.transform.f - t.f) / t.e)
            part = s.read()
            assert np.array_equal(part, whole[:, r0:r0 + s.height, c0:c0 + s.width])
            covered[r0:r0 + s.height, c0:c0 + s.width] += 1
    assert np.all(covered == 1)  # sheets tile the mosaic: each cell in exactly one sheet
    index = gpd.read_file(folder / "sheets.gpkg")
    assert sorted(index["file"]) == sorted(expected)


def test_polygon_sheets_with_ids_and_vector_input(pair, seams, mosaic, tmp_path):
    ox, oy = ORIGIN
    tri = shapely.Polygon([(ox + 100, oy + 50), (ox + 700, oy + 50), (ox + 400, oy + 390)])
    outside = shapely.box(ox + 5000, oy, ox + 5100, oy + 100)
    sheets = gpd.GeoDataFrame({"name": ["Tri 1", "far away"]}, geometry=[tri, outside],
                              crs="EPSG:3003")
    sheets.to_file(tmp_path / "sheets.gpkg")
    out = toolbox.run("mosaic:cut", {"INPUT": str(mosaic), "SHEETS": str(tmp_path / "sheets.gpkg"),
                                     "ID_FIELD": "name", "OUTPUT": str(tmp_path / "r")})
    assert [p.name for p in Path(out["OUTPUT"]).glob("*.tif")] == ["Tri_1.tif"]
    assert out["STATISTICS"]["skipped_empty"] == 1
    with rasterio.open(Path(out["OUTPUT"]) / "Tri_1.tif") as s:
        alpha = s.read(4)
        t = s.transform
    rows, cols = np.indices(alpha.shape)
    x, y = t @ (cols + 0.5, rows + 0.5)
    differ = (alpha > 0) != shapely.contains_xy(tri, x, y)
    assert differ.sum() < 40  # only centres exactly on an edge (GDAL counts them in)
    assert shapely.distance(tri.boundary, shapely.points(x[differ], y[differ])).max() < 1e-9
    # vector input: the cut polygons clipped to the triangle add up to the triangle
    cells = str(seams["least_cost"]["OUTPUT"]) + "|layername=cut_polygons"
    vec = toolbox.run("mosaic:cut", {"INPUT": str(seams["least_cost"]["OUTPUT"]),
                                     "SHEETS": str(tmp_path / "sheets.gpkg"), "ID_FIELD": "name",
                                     "OUTPUT": str(tmp_path / "v")})
    clipped = gpd.read_file(Path(vec["OUTPUT"]) / "Tri_1.gpkg")
    assert abs(clipped.area.sum() - tri.area) < 1e-6 * tri.area
    assert cells  # the default layer is the first one, cut_polygons
    assert set(clipped["source"]) == {"ortho_a", "ortho_b"}


def test_output_folder_needs_overwrite_and_sheet_source(mosaic, tmp_path):
    params = {"INPUT": str(mosaic), "SCALE": 2000, "OUTPUT": str(tmp_path / "s")}
    toolbox.run("mosaic:cut", params)
    with pytest.raises(OutputExistsError):
        toolbox.run("mosaic:cut", params)
    (tmp_path / "s" / "other.txt").write_text("a file the run does not write")
    toolbox.run("mosaic:cut", params, overwrite=True)
    assert (tmp_path / "s" / "other.txt").read_text() == "a file the run does not write"
    assert (tmp_path / "s" / "sheets.gpkg").exists()
    with pytest.raises(ParameterError, match="SCALE"):
        toolbox.run("mosaic:cut", {"INPUT": str(mosaic), "OUTPUT": str(tmp_path / "t")})
