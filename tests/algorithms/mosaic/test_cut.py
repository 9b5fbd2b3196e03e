"""mosaic:cut: a sheet grid from scale and sheet size gives files named by sheet id whose
pixels are exactly the mosaic's, with nothing lost; polygon sheets with an id field; vector
clipping (areas add up; polygons along sheet edges give polygon pieces only; every layer of a
file, or the one named); the output folder is staged and replaced only with --overwrite."""

from pathlib import Path

import geopandas as gpd
import numpy as np
import pyogrio
import pytest
import rasterio
import shapely

import toolbox
from toolbox.demo.samples.mosaic import ORIGIN
from toolbox.errors import OutputExistsError, ParameterError
from toolbox.io.vector_write import write_layers


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
    # vector input: the cut polygons clipped to the triangle add up to the triangle; every
    # layer of the seams' GeoPackage is cut
    vec = toolbox.run("mosaic:cut", {"INPUT": str(seams["least_cost"]["OUTPUT"]),
                                     "SHEETS": str(tmp_path / "sheets.gpkg"), "ID_FIELD": "name",
                                     "OUTPUT": str(tmp_path / "v")})
    clipped = gpd.read_file(Path(vec["OUTPUT"]) / "Tri_1.gpkg", layer="cut_polygons")
    assert abs(clipped.area.sum() - tri.area) < 1e-6 * tri.area
    assert set(clipped["source"]) == {"ortho_a", "ortho_b"}
    assert "seamlines" in gpd.list_layers(Path(vec["OUTPUT"]) / "Tri_1.gpkg")["name"].tolist()


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


def _sheet_boxes(folder: Path, size: float) -> dict[str, shapely.Polygon]:
    boxes = {}
    for path in folder.glob("*_*.gpkg"):
        i, j = map(int, path.stem.split("_"))
        boxes[path.name] = shapely.box(i * size, j * size, (i + 1) * size, (j + 1) * size)
    return boxes


def test_polygons_along_sheet_edges_keep_only_polygon_pieces(tmp_path):
    """Polygons whose edges lie on sheet edges meet the neighbour sheets in lines and points:
    only the polygon pieces are kept, and each feature's clipped area is shapely's
    intersection with the sheet (they add up to the polygon)."""
    x, y = 1_688_000.0, 4_799_500.0  # multiples of the 50 m sheets
    polygons = [shapely.box(x, y, x + 100, y + 50),  # two sheets, edges on sheet edges
                shapely.box(x + 100, y, x + 150, y + 100),  # touches the first along x + 100
                shapely.Polygon([(x, y + 50), (x + 100, y + 50), (x + 30, y + 120)])]
    frame = gpd.GeoDataFrame({"fid_": [1, 2, 3]}, geometry=polygons, crs="EPSG:3003")
    frame.to_file(tmp_path / "areas.gpkg", layer="areas")
    out = toolbox.run("mosaic:cut", {"INPUT": str(tmp_path / "areas.gpkg"), "SCALE": 1000,
                                     "SHEET_WIDTH": 5, "SHEET_HEIGHT": 5,
                                     "OUTPUT": str(tmp_path / "s")})
    folder = Path(out["OUTPUT"])
    boxes = _sheet_boxes(folder, 50.0)
    assert out["STATISTICS"]["written"] == len(boxes) > 3
    total = dict.fromkeys((1, 2, 3), 0.0)
    for name, box in boxes.items():
        part = gpd.read_file(folder / name, layer="areas")
        assert set(part.geom_type) <= {"Polygon", "MultiPolygon"}
        for fid, geom in zip(part["fid_"], part.geometry, strict=True):
            expected = polygons[fid - 1].intersection(box).area
            assert expected > 0 and abs(geom.area - expected) < 1e-6
            total[fid] += geom.area
    assert all(abs(total[f] - polygons[f - 1].area) < 1e-6 for f in total)


def test_every_layer_is_cut_or_the_one_named(tmp_path):
    """A GeoPackage of several layers: each sheet holds every layer with features in it, under
    its own name (nothing dropped); "path|layername=NAME" cuts that layer only."""
    x, y = 1_688_000.0, 4_799_500.0
    areas = gpd.GeoDataFrame({"a": [1]}, geometry=[shapely.box(x + 10, y + 10, x + 90, y + 40)],
                             crs="EPSG:3003")
    lines = gpd.GeoDataFrame({"b": [1, 2]}, geometry=[
        shapely.LineString([(x + 5, y + 5), (x + 95, y + 45)]),
        shapely.LineString([(x + 20, y + 30), (x + 30, y + 30)])], crs="EPSG:3003")
    points = gpd.GeoDataFrame({"c": [1, 2, 3]}, geometry=shapely.points(
        [(x + 1, y + 1), (x + 60, y + 20), (x + 99, y + 49)]), crs="EPSG:3003")
    source = tmp_path / "many.gpkg"
    write_layers(source, {"areas": areas, "lines": lines, "points": points})
    out = toolbox.run("mosaic:cut", {"INPUT": str(source), "SCALE": 1000, "SHEET_WIDTH": 5,
                                     "SHEET_HEIGHT": 5, "OUTPUT": str(tmp_path / "all")})
    folder = Path(out["OUTPUT"])
    boxes = _sheet_boxes(folder, 50.0)
    assert sorted(boxes) == ["33760_95990.gpkg", "33761_95990.gpkg"]
    sums = {"areas": 0.0, "lines": 0.0, "points": 0}
    for name in boxes:
        assert {str(n) for n, _ in pyogrio.list_layers(folder / name)} == set(sums)
        sums["areas"] += gpd.read_file(folder / name, layer="areas").area.sum()
        sums["lines"] += gpd.read_file(folder / name, layer="lines").length.sum()
        sums["points"] += len(gpd.read_file(folder / name, layer="points"))
    assert abs(sums["areas"] - areas.area.sum()) < 1e-6
    assert abs(sums["lines"] - lines.length.sum()) < 1e-6 and sums["points"] == 3
    one = toolbox.run("mosaic:cut", {"INPUT": f"{source}|layername=lines", "SCALE": 1000,
                                     "SHEET_WIDTH": 5, "SHEET_HEIGHT": 5,
                                     "OUTPUT": str(tmp_path / "one")})
    for name, box in _sheet_boxes(Path(one["OUTPUT"]), 50.0).items():
        assert [str(n) for n, _ in pyogrio.list_layers(Path(one["OUTPUT"]) / name)] == ["lines"]
        part = gpd.read_file(Path(one["OUTPUT"]) / name, layer="lines")
        assert abs(part.length.sum() - lines.intersection(box).length.sum()) < 1e-6


@pytest.mark.parametrize("crs, words", [("EPSG:4326", "the geographic CRS EPSG:4326"),
                                        ("EPSG:2263", "EPSG:2263.*US survey foot")])
def test_an_input_not_in_metres_is_refused(tmp_path, crs, words):
    """mosaic:cut's sheets are SCALE x cm of paper in metres: a lon/lat layer was cut into one
    sheet of -250..0 degrees, a feet one into sheets 3.28 times too small, exit 0. Refused in
    one line naming INPUT, as the runner refuses such CRSs for layer parameters."""
    points = gpd.GeoDataFrame({"n": [1, 2]}, geometry=shapely.points([(11.3, 43.3), (11.31, 43.31)]),
                              crs="EPSG:4326")
    if crs != "EPSG:4326":
        points = gpd.GeoDataFrame({"n": [1, 2]}, geometry=shapely.points(
            [(980000, 190000), (981000, 191000)]), crs=crs)
    points.to_file(tmp_path / "p.gpkg")
    with pytest.raises(ParameterError, match=f"INPUT is in {words}"):
        toolbox.run("mosaic:cut", {"INPUT": str(tmp_path / "p.gpkg"), "SCALE": 500,
                                   "OUTPUT": str(tmp_path / "sheets")})
    assert not (tmp_path / "sheets").exists()
