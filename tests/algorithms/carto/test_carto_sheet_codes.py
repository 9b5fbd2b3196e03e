"""carto:sheet with CODES: the coded GeoPackage of attribution:apply (the demo's Siena code,
colour and model files) is drawn in the code file's colours and its legend lists the codes
with their descriptions. The colours are checked against the files themselves (colour index
-> %R %G %B) and against the QGIS style attribution:apply embedded, so the sheet and QGIS draw
one symbology: a building's fill pixel in the PNG is that QML fill composited over white, the
road stroke in the PDF is the code file's RGB."""

from __future__ import annotations

import re
import sqlite3
import xml.etree.ElementTree as ET

import geopandas as gpd
import numpy as np
import pytest
import shapely
from PIL import Image

import toolbox
from toolbox.demo.samples import restitution

pypdf = pytest.importorskip("pypdf", reason="pypdf (dev extra) reads the sheet PDFs back")
EXTENT = (1688290.0, 4799595.0, 1688410.0, 4799665.0)
SCALE = 1000.0
DPI = 150


@pytest.fixture(scope="module")
def coded(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sheet_codes")
    files = restitution.make(folder, {})
    # the code file without its symbology columns: the shared style model's look, as QGIS's
    # (the columns' own drawing is tested in test_carto_sheet_symbols.py)
    lines = files["restitution_codes"].read_text(encoding="latin-1").splitlines()
    files["restitution_codes"].write_bytes("\n".join(
        line if line.startswith("#") else ";".join(line.split(";")[:4])
        for line in lines).encode("latin-1"))
    out = folder / "coded.gpkg"
    toolbox.run("attribution:apply", {
        "INPUT": [files["restitution_model_12"], files["restitution_model_13"]],
        "CODES": files["restitution_codes"], "COLOURS": files["restitution_colours"],
        "PARAMETERS": files["restitution_parameters"], "CRS": "EPSG:3003", "OUTPUT": out})
    pdf, png = folder / "sheet.pdf", folder / "sheet.png"
    res = toolbox.run("carto:sheet", {
        "EXTENT": ",".join(f"{v:.0f}" for v in EXTENT) + " [EPSG:3003]", "SCALE": SCALE,
        "LAYERS": [f"{out}|layername={name}" for name in ("FAB01002", "STR02001", "QUO01001")],
        "CODES": files["restitution_codes"], "COLOURS": files["restitution_colours"],
        "MAP_STEP": 50.0, "OUTPUT": pdf, "PNG": png, "PNG_DPI": DPI})
    return files, out, pdf, png, res["SHEETS_WRITTEN"][0]


def file_colour(files, code: str) -> tuple[int, int, int]:
    """RGB 0-255 of a code read straight from the demo's code and colour files."""
    index = next(line.split(";")[3] for line in
                 files["restitution_codes"].read_text(encoding="latin-1").splitlines()
                 if line.startswith(code + ";"))
    row = next(line.split() for line in files["restitution_colours"].read_text().splitlines()
               if line.split() and line.split()[0] == index)
    return tuple(float(p) / 100 * 255 for p in row[1:4])


def embedded_colour(gpkg, layer: str, key: str) -> tuple[int, ...]:
    """A colour property of the default QML attribution:apply embedded for ``layer``."""
    with sqlite3.connect(gpkg) as db:
        qml, = db.execute("SELECT styleQML FROM layer_styles WHERE f_table_name = ? AND "
                          "useAsDefault = 1", (layer,)).fetchone()
    root = ET.fromstring(qml.split("\n", 1)[1])
    value = root.find(f".//symbol/layer/Option/Option[@name='{key}']").get("value")
    return tuple(int(v) for v in value.split(","))


def test_legend_lists_codes_with_descriptions(coded):
    files, _, pdf, _, _ = coded
    text = pypdf.PdfReader(pdf).pages[0].extract_text()
    for code, description in (("FAB01002", "muro perimetrale di fabbricato civile"),
                              ("STR02001", "limite di strada"), ("QUO01001", "punto quotato")):
        assert f"{code} {description}" in text
    assert "VEG01001" not in text  # only the codes drawn are listed


def test_road_stroke_is_the_code_file_colour(coded):
    files, gpkg, pdf, _, _ = coded
    expected = np.array(file_colour(files, "STR02001"))  # index 3: 100 0 0
    assert embedded_colour(gpkg, "STR02001", "line_color")[:3] == tuple(np.round(expected))
    content = pypdf.PdfReader(pdf).pages[0].get_contents().get_data().decode("latin-1")
    strokes = {tuple(float(v) for v in m) for m in
               re.findall(r"([\d.]+) ([\d.]+) ([\d.]+) RG", content)}
    assert any(np.allclose(np.array(s) * 255, expected, atol=0.6) for s in strokes)


def test_building_fill_pixel_is_the_embedded_qgis_fill(coded):
    files, gpkg, _, png, sheet = coded
    rgba = np.array(embedded_colour(gpkg, "FAB01002", "color"), dtype=float)
    assert np.allclose(rgba[:3], file_colour(files, "FAB01002"), atol=0.6)  # index 12: 30 %
    # a point well inside a building, away from its outline, on the page in pixels
    building = gpd.read_file(gpkg, layer="FAB01002").geometry.iloc[0]
    inner = shapely.force_2d(building).buffer(-1.5).representative_point()
    left, bottom, _, _ = sheet["frame_mm"]
    page_h = sheet["paper_mm"][1]
    x_mm = left + (inner.x - EXTENT[0]) / SCALE * 1000
    y_mm = bottom + (inner.y - EXTENT[1]) / SCALE * 1000
    image = np.asarray(Image.open(png).convert("RGB"), dtype=float)
    col, row = int(x_mm / 25.4 * DPI), int((page_h - y_mm) / 25.4 * DPI)
    pixel = image[row - 1:row + 2, col - 1:col + 2].reshape(-1, 3).mean(axis=0)
    alpha = rgba[3] / 255
    over_white = rgba[:3] * alpha + 255 * (1 - alpha)  # "source over" on the white page
    assert np.allclose(pixel, over_white, atol=3), (pixel, over_white)


def test_colours_need_codes(coded):
    from toolbox.errors import ParameterError

    files, gpkg, _, _, _ = coded
    with pytest.raises(ParameterError, match="COLOURS"):
        toolbox.run("carto:sheet", {"EXTENT": "1688290,4799595,1688410,4799665 [EPSG:3003]",
                                    "LAYERS": [f"{gpkg}|layername=FAB01002"],
                                    "COLOURS": files["restitution_colours"],
                                    "OUTPUT": gpkg.with_name("x.pdf")})


def test_code_field_layers_are_drawn_by_code(coded):
    """A layer with a code field (topology:build_areas, LAYOUT=type) is split by code in the
    code file's order; unknown codes are grey, features without a code keep a default style."""
    from toolbox.cartography.sheet_io import coded_styles
    from toolbox.io.code_file import read_code_file, read_colour_file

    files = coded[0]
    frame = gpd.GeoDataFrame({"code": ["STR02001", None, "XYZ", "FAB01002", "FAB01002"]},
                             geometry=[shapely.box(i, 0, i + 1, 1) for i in range(5)],
                             crs="EPSG:3003")
    styles = coded_styles([("areas", frame)], read_code_file(files["restitution_codes"]),
                          read_colour_file(files["restitution_colours"]))
    assert [(s.name, len(s.frame)) for s in styles] == [
        ("areas: no code", 1), ("FAB01002 muro perimetrale di fabbricato civile", 2),
        ("STR02001 limite di strada", 1), ("XYZ", 1)]
    assert styles[2].rgb == (255, 0, 0) and styles[3].rgb == (128, 128, 128)


def test_a_code_drawn_from_two_layers_is_listed_once(coded, tmp_path):
    files, gpkg, _, _, _ = coded
    pdf = tmp_path / "twice.pdf"
    toolbox.run("carto:sheet", {
        "EXTENT": "1688290,4799595,1688410,4799665 [EPSG:3003]", "SCALE": SCALE,
        "LAYERS": [f"{gpkg}|layername=FAB01002"] * 2, "CODES": files["restitution_codes"],
        "COLOURS": files["restitution_colours"], "OUTPUT": pdf})
    assert pypdf.PdfReader(pdf).pages[0].extract_text().count("FAB01002") == 1
