"""carto:sheet: the PDF's page size is the chosen ISO sheet, and the scale read back from the
file (grid-label and scale-bar text positions, in PDF points) is the requested one; one PDF per
sheet of a sheet grid, named by sheet id."""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import pytest
import shapely

import toolbox
from toolbox.demo.samples.terrain import CRS, terrain
from toolbox.raster.writer import write_raster

pypdf = pytest.importorskip("pypdf", reason="pypdf (dev extra) reads the sheet PDFs back")
PT_PER_MM = 72 / 25.4


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sheet")
    z, transform = terrain()
    dem = folder / "dem.tif"
    write_raster(dem, z, transform, CRS, nodata=-9999.0)
    shade = folder / "shade.tif"
    toolbox.run("dem:hillshade", {"INPUT": dem, "OUTPUT": shade})
    contours = folder / "contours.gpkg"
    toolbox.run("carto:contours", {"INPUT": dem, "INTERVAL": 5.0, "OUTPUT": contours})
    roads = gpd.GeoDataFrame({"code": ["road"]}, geometry=[shapely.linestrings(
        [[1687600, 4799000], [1688900, 4800200]])], crs=CRS)
    roads.to_file(folder / "roads.gpkg")
    return {"base": shade, "contours": contours, "roads": folder / "roads.gpkg"}


def texts(page):
    found = []

    def visit(text, cm, tm, font, size):
        if text.strip():
            found.append((text.strip(), cm[4] + tm[4], cm[5] + tm[5]))

    page.extract_text(visitor_text=visit)
    return found


def test_sheet_page_size_and_scale_from_the_pdf(inputs, tmp_path):
    out, png = tmp_path / "sheet.pdf", tmp_path / "sheet.png"
    res = toolbox.run("carto:sheet", {
        "EXTENT": "1687600,4799000,1688600,4799800 [EPSG:3003]", "SCALE": 5000,
        "BASE": inputs["base"], "CONTOURS": inputs["contours"], "LAYERS": [inputs["roads"]],
        "TITLE": "Siena demo", "DATE": "2026-12-01", "OUTPUT": out, "PNG": png})
    reader = pypdf.PdfReader(out)
    assert len(reader.pages) == 1
    box = reader.pages[0].mediabox
    # 1000 x 800 m at 1:5000 = 200 x 160 mm of map + panel: A3 landscape (420 x 297 mm)
    assert res["SHEETS_WRITTEN"][0]["paper"] == "A3"
    assert float(box.width) == pytest.approx(420 * PT_PER_MM, abs=0.01)
    assert float(box.height) == pytest.approx(297 * PT_PER_MM, abs=0.01)
    found = texts(reader.pages[0])
    words = {t for t, _, _ in found}
    assert {"Siena demo", "scale: 1:5000", "CRS: EPSG:3003", "date: 2026-12-01",
            "Legend", "N"} <= words
    # grid labels 1688000 and 1688500 at the bottom edge are 500 m apart on the ground
    bottom_y = min(y for t, x, y in found if t == "1688000")
    xs = sorted(x for t, x, y in found if t in ("1688000", "1688500") and y == bottom_y)
    assert len(xs) == 2
    scale = 500.0 / ((xs[1] - xs[0]) / PT_PER_MM / 1000.0)
    assert scale == pytest.approx(5000, rel=1e-6)
    # the scale bar: its end labels start at the bar's ends
    bar = res["SHEETS_WRITTEN"][0]["scale_bar"]
    x0 = next(x for t, x, y in found if t == "0")
    x1 = next(x for t, x, y in found if t == f"{bar['ground_length']:.0f} m")
    assert bar["ground_length"] / ((x1 - x0) / PT_PER_MM / 1000.0) == pytest.approx(5000,
                                                                                    rel=1e-6)
    assert "scale=1:5000" in reader.metadata["/Keywords"]
    assert png.read_bytes()[:4] == b"\x89PNG"
    # vector quality: the contours are paths, not only a picture
    content = reader.pages[0].get_contents().get_data()
    assert content.count(b" l\n") + content.count(b" l ") > 1000


def test_a_png_alone_is_a_sheet_output(inputs, tmp_path):
    """PNG is an output of its own: a sheet asked only as a PNG is drawn (it was refused with
    'OUTPUT or FOLDER: give at least one'), the same picture as beside a PDF."""
    params = {"EXTENT": "1687600,4799000,1688600,4799800 [EPSG:3003]", "SCALE": 5000,
              "BASE": inputs["base"], "DATE": "2026-12-01"}
    alone = toolbox.run("carto:sheet", params | {"PNG": tmp_path / "alone.png"})
    toolbox.run("carto:sheet", params | {"PNG": tmp_path / "with.png",
                                         "OUTPUT": tmp_path / "with.pdf"})
    assert alone["SHEETS_WRITTEN"][0]["paper"] == "A3"
    import rasterio

    with rasterio.open(tmp_path / "alone.png") as a, rasterio.open(tmp_path / "with.png") as b:
        assert a.shape == b.shape and np.array_equal(a.read(), b.read())


def test_one_pdf_per_sheet_named_by_id(inputs, tmp_path):
    sheets = gpd.GeoDataFrame({"name": ["NW", "NE"]}, geometry=[
        shapely.box(1687600, 4799600, 1688100, 4800000),
        shapely.box(1688100, 4799600, 1688600, 4800000)], crs=CRS)
    sheets.to_file(tmp_path / "sheets.gpkg")
    folder = tmp_path / "sheets"
    res = toolbox.run("carto:sheet", {"SHEETS": tmp_path / "sheets.gpkg", "SHEET_ID": "name",
                                      "SCALE": 2000, "BASE": inputs["base"],
                                      "OUTPUT": tmp_path / "atlas.pdf", "FOLDER": str(folder)})
    assert sorted(p.name for p in folder.iterdir()) == ["NE.pdf", "NE.png", "NW.pdf", "NW.png"]
    assert len(pypdf.PdfReader(tmp_path / "atlas.pdf").pages) == 2
    for sheet in res["SHEETS_WRITTEN"]:
        reader = pypdf.PdfReader(folder / f"{sheet['sheet']}.pdf")
        words = {t for t, _, _ in texts(reader.pages[0])}
        assert f"sheet: {sheet['sheet']}" in words and "scale: 1:2000" in words
        # 500 x 400 m at 1:2000 = 250 x 200 mm
        assert np.allclose(sheet["frame_mm"][2:], [250, 200])


def test_styles_from_the_shared_style_model():
    from dataclasses import dataclass

    from toolbox.cartography.sheet_io import styles_from_model

    @dataclass
    class Code:  # the fields of toolbox.styles.CodeStyle the sheet uses
        code: str
        kind: str
        rgb: tuple
        line_width: float
        fill: tuple | None
        label: str

    @dataclass
    class Layer:  # and of toolbox.styles.LayerStyle
        name: str
        kind: str
        styles: list
        field: str = "code"
        label_field: str | None = None

    frame = gpd.GeoDataFrame({"code": ["A", "B", "A"]}, geometry=[
        shapely.box(0, 0, 1, 1), shapely.box(2, 0, 3, 1), shapely.box(4, 0, 5, 1)], crs=CRS)
    layer = Layer("areas", "polygon", [Code("A", "polygon", (200, 0, 0), 0.3, (200, 0, 0, 96),
                                            "buildings"),
                                       Code("B", "polygon", (0, 120, 0), 0.3, None, "woods")])
    styles = styles_from_model(frame, layer)
    assert [(s.name, len(s.frame), s.rgb, s.fill) for s in styles] == [
        ("buildings", 2, (200, 0, 0), (200, 0, 0, 96)), ("woods", 1, (0, 120, 0), None)]


def sized_texts(page) -> list[tuple[str, float, float, float]]:
    """(text, x, y, size in pt at print size) of every text run."""
    found = []

    def visit(text, cm, tm, font, size):
        if text.strip():
            found.append((text.strip(), cm[4] + tm[4], cm[5] + tm[5],
                          size * float(np.hypot(tm[0], tm[1]))))

    page.extract_text(visitor_text=visit)
    return found


@pytest.fixture(scope="module")
def map_sheet(inputs, tmp_path_factory):
    """A sheet with spot heights (PointZ), a long sources line and the contours."""
    folder = tmp_path_factory.mktemp("sheet_map")
    spots = gpd.GeoDataFrame({"code": ["QUO01001"] * 2}, geometry=shapely.points(
        [1688000.0, 1688300.0], [4799300.0, 4799500.0], [312.46, 301.04]), crs=CRS)
    spots.to_file(folder / "spots.gpkg")
    sources = "; ".join(f"survey block {k} of 2009-03-31 by a long-named company" for k in
                        range(4))
    out = folder / "sheet.pdf"
    res = toolbox.run("carto:sheet", {
        "EXTENT": "1687600,4799000,1688600,4799800 [EPSG:3003]", "SCALE": 5000,
        "BASE": inputs["base"], "CONTOURS": inputs["contours"],
        "LAYERS": [folder / "spots.gpkg"], "SOURCES": sources, "TITLE": "Siena demo",
        "OUTPUT": out})
    return res["SHEETS_WRITTEN"][0], sized_texts(pypdf.PdfReader(out).pages[0]), sources


def test_spot_heights_carry_their_height_beside_the_point(map_sheet):
    sheet, found, _ = map_sheet
    left, bottom = sheet["frame_mm"][:2]
    for (x, y), label in (((1688000.0, 4799300.0), "312.5"), ((1688300.0, 4799500.0), "301.0")):
        px = (left + (x - 1687600.0) / 5.0) * PT_PER_MM  # 1:5000: 5 m per paper mm
        py = (bottom + (y - 4799000.0) / 5.0) * PT_PER_MM
        at = [(tx, ty) for t, tx, ty, _ in found if t == label]
        assert at, label
        tx, ty = at[0]
        assert 0 < tx - px < 3 * PT_PER_MM and abs(ty - py) < 2 * PT_PER_MM  # just right of it


def test_contour_interval_stated_and_text_readable(map_sheet):
    _, found, sources = map_sheet
    words = [t for t, _, _, _ in found]
    assert "contour interval: 5 m" in words and "contour, interval 5 m" in words
    assert any(w.startswith("index contour, every 25 m") for w in words)
    assert min(size for _, _, _, size in found) >= 6.0 - 1e-9  # >= 6 pt at print size
    # the sources are wrapped over lines, never cut
    joined = " ".join(" ".join(words).split())
    assert " ".join(f"sources: {sources}".split()) in joined.replace("  ", " ")


def test_grid_labels_keep_clear_of_the_corners(map_sheet):
    sheet, found, _ = map_sheet
    left, bottom, width, height = (v * PT_PER_MM for v in sheet["frame_mm"])
    labels = [(x, y) for t, x, y, _ in found if t.isdigit() and len(t) == 7]
    assert len(labels) >= 6
    for x, y in labels:  # within 8 mm of a corner along both edges would collide
        near_x = min(abs(x - left), abs(x - left - width)) < 8 * PT_PER_MM
        near_y = min(abs(y - bottom), abs(y - bottom - height)) < 8 * PT_PER_MM
        assert not (near_x and near_y), (x, y)


def test_a_small_sheet_is_centred_not_in_a_corner(tmp_path):
    res = toolbox.run("carto:sheet", {
        "EXTENT": "1688000,4799000,1688100,4799060 [EPSG:3003]", "SCALE": 1000,
        "OUTPUT": tmp_path / "small.pdf"})
    sheet = res["SHEETS_WRITTEN"][0]
    paper_w, paper_h = sheet["paper_mm"]
    left, bottom, width, height = sheet["frame_mm"]
    assert (width, height) == pytest.approx((100, 60))
    assert abs((bottom + height / 2) - paper_h / 2) < 1.0  # mid-height of the page
    panel_left, _, panel_width, _ = sheet["panel_mm"]
    # the map and its panel as one block, centred: equal margins left (beyond the grid labels'
    # 6 mm band) and right
    assert abs((left - 6.0) - (paper_w - panel_left - panel_width)) < 1.0


# -- null and empty geometries: SHEETS refused, LAYERS features left out with a warning ------
SQUARE = shapely.box(1688000, 4799000, 1688100, 4799100)


@pytest.mark.parametrize("geom, says", [(None, "has no geometry"),
                                        (shapely.Polygon(), "has an empty geometry")])
def test_sheet_refuses_a_null_or_empty_sheet(tmp_path, geom, says):
    from toolbox.errors import ParameterError

    sheets = tmp_path / "sheets.gpkg"
    gpd.GeoDataFrame({"no": ["A", "B"]}, geometry=[SQUARE, geom], crs=CRS).to_file(sheets)
    out = tmp_path / "s.pdf"
    with pytest.raises(ParameterError, match=rf"^SHEETS feature 2 \(sheet 'B'\) {says}"):
        toolbox.run("carto:sheet", {"SHEETS": sheets, "SHEET_ID": "no", "SCALE": 1000,
                                    "OUTPUT": out})
    assert not out.exists()


def test_sheet_leaves_out_layer_features_without_geometry(tmp_path):
    heights = tmp_path / "heights.gpkg"
    gpd.GeoDataFrame({"name": ["a", "none", "b"]}, geometry=[
        shapely.Point(1688030, 4799030, 111.1), None, shapely.Point(1688070, 4799070, 222.2)],
        crs=CRS).to_file(heights)
    out, feedback = tmp_path / "s.pdf", toolbox.Feedback()
    toolbox.run("carto:sheet", {"EXTENT": "1688000,4799000,1688100,4799100 [EPSG:3003]",
                                "SCALE": 1000, "LAYERS": [heights], "OUTPUT": out},
                feedback=feedback)
    assert any("LAYERS heights: 1 feature(s) without geometry" in w and "row 2, counting from 1" in w
               for w in feedback.warnings)
    # the two other spot heights are drawn, labelled with their Z
    words = {t for t, _, _ in texts(pypdf.PdfReader(out).pages[0])}
    assert {"111.1", "222.2"} <= words


def test_sheet_refuses_contours_without_elev(tmp_path):
    from toolbox.errors import ParameterError

    contours = tmp_path / "lines.gpkg"
    gpd.GeoDataFrame({"z": [100.0]}, geometry=[shapely.LineString(
        [(1688000, 4799050), (1688100, 4799050)])], crs=CRS).to_file(contours)
    out = tmp_path / "s.pdf"
    with pytest.raises(ParameterError, match="^CONTOURS .* has no numeric 'elev' field"):
        toolbox.run("carto:sheet", {"EXTENT": "1688000,4799000,1688100,4799100 [EPSG:3003]",
                                    "SCALE": 1000, "CONTOURS": contours, "OUTPUT": out})
    assert not out.exists()


def test_a_paletted_base_is_drawn_in_its_colours(tmp_path):
    """A paletted BASE (one band of colour codes and a colour table) was drawn as grey shading
    of the codes; it is read as its colours: at one paper pixel per cell, each pixel is the
    table's colour of its cell's code."""
    import rasterio
    from affine import Affine

    from toolbox.cartography.sheet_io import read_base
    from toolbox.io.raster import open_raster_info

    codes = (np.arange(40 * 30).reshape(30, 40) % 7).astype("uint8")
    table = {k: (30 * k, 255 - 30 * k, (70 * k) % 256, 255) for k in range(7)}
    path = tmp_path / "pal.tif"
    with rasterio.open(path, "w", driver="GTiff", width=40, height=30, count=1, dtype="uint8",
                       crs="EPSG:3003", transform=Affine(1, 0, 1688000, 0, -1, 4799030)) as dst:
        dst.write(codes, 1)
        dst.write_colormap(1, table)
    image, extent = read_base(open_raster_info(path, "BASE"), (1688000, 4799000, 1688040, 4799030),
                              scale=100, dpi=300)
    expected = np.array([table[k][:3] for k in range(7)], dtype="uint8")[codes]
    assert image.shape == (30, 40, 3) and extent == (1688000, 1688040, 4799000, 4799030)
    np.testing.assert_array_equal(image, expected)
