"""carto:sheet with the code file's symbology columns (the demo's Siena code file: widths, line
types, point symbols, hatching, delivered codes), the restitution's texts and a second CRS's
grid. Checked from the files written, independently of the drawing code: the PDF's text and
word boxes read by poppler's pdftotext, font sizes by pypdf, the hatching's and the scarp
ticks' spacing measured in the PNG's pixels."""

from __future__ import annotations

import shutil
import subprocess

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
DPI = 300
PT_PER_MM = 72 / 25.4
SCARP_Y = 4799598.0  # a scarp plotted west -> east along the sheet's foot


@pytest.fixture(scope="module")
def sheet(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sheet_symbols")
    files = restitution.make(folder, {})
    coded, dxf = folder / "coded.gpkg", folder / "dxf.gpkg"
    common = {"CODES": files["restitution_codes"], "COLOURS": files["restitution_colours"],
              "CRS": "EPSG:3003"}
    toolbox.run("attribution:apply", {
        "INPUT": [files["restitution_model_12"], files["restitution_model_13"]],
        "PARAMETERS": files["restitution_parameters"], "OUTPUT": coded} | common)
    toolbox.run("attribution:apply", {"INPUT": files["restitution_dxf"], "LAYOUT": "type",
                                      "OUTPUT": dxf} | common)
    # a kerb (MAR01001) delivered as a road edge, and a scarp drawn west -> east
    codes = folder / "codes.txt"
    codes.write_bytes(files["restitution_codes"].read_bytes()
                      + "SCA01001;scarpata;polilinea;7;0.18;scarpata;;;SCARPATA\n"
                      .encode("latin-1"))
    extra = gpd.GeoDataFrame({"code": ["MAR01001", "SCA01001"]}, geometry=[
        shapely.LineString([(1688300, 4799652), (1688340, 4799652)]),
        shapely.LineString([(1688300, SCARP_Y), (1688400, SCARP_Y)])], crs="EPSG:3003")
    extra.to_file(folder / "extra.gpkg")
    pdf, png = folder / "sheet.pdf", folder / "sheet.png"
    res = toolbox.run("carto:sheet", {
        "EXTENT": ",".join(f"{v:.0f}" for v in EXTENT) + " [EPSG:3003]", "SCALE": SCALE,
        "LAYERS": [f"{coded}|layername={n}" for n in ("FAB01002", "STR02001", "QUO01001")]
        + [f"{dxf}|layername=labels", folder / "extra.gpkg"],
        "CODES": codes, "COLOURS": files["restitution_colours"], "MAP_STEP": 50.0,
        "GRID_CRS": "EPSG:6707", "OUTPUT": pdf, "PNG": png, "PNG_DPI": DPI})
    return pdf, png, res["SHEETS_WRITTEN"][0], coded


def _pixel(sheet_info, x, y):
    left, bottom, _, _ = sheet_info["frame_mm"]
    x_mm = left + (x - EXTENT[0]) / SCALE * 1000
    y_mm = bottom + (y - EXTENT[1]) / SCALE * 1000
    return x_mm / 25.4 * DPI, (sheet_info["paper_mm"][1] - y_mm) / 25.4 * DPI


def _period_px(profile: np.ndarray) -> float:
    """The dominant period (pixels) of a 1-D profile, from its spectrum."""
    p = profile - profile.mean()
    spectrum = np.abs(np.fft.rfft(p * np.hanning(len(p))))
    k = int(np.argmax(spectrum[2:])) + 2
    return len(p) / k


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler's pdftotext")
def test_legend_and_texts_from_the_code_file(sheet):
    pdf = sheet[0]
    text = subprocess.run(["pdftotext", "-layout", str(pdf), "-"], capture_output=True,
                          text=True, check=True).stdout
    for name in ("EDIFICIO muro perimetrale di fabbricato civile",
                 "BORDO_STRADA limite di strada", "PUNTO_QUOTATO punto quotato",
                 "SCARPATA scarpata", "TOPONIMO toponimo (località)"):
        assert name in text, name
    assert "Località Pian dei Mantellini" in text  # the DXF's text, placed on the map
    # working codes are not shown; the kerb is delivered as a road edge: one entry
    assert "FAB01002" not in text and "marciapiede" not in text
    assert text.count("BORDO_STRADA") == 1
    assert "AREA_VERDE" not in text  # only what is drawn is listed


def test_smallest_text_is_6_pt(sheet):
    sizes = []

    def visit(text, cm, tm, font, size):
        if text.strip():
            sizes.append(size * float(np.hypot(tm[0], tm[1])) * float(np.hypot(cm[0], cm[1])))

    pypdf.PdfReader(sheet[0]).pages[0].extract_text(visitor_text=visit)
    assert len(sizes) > 20 and min(sizes) >= 6.0 - 1e-6


def test_buildings_hatched_at_45_degrees_1_mm_apart(sheet):
    _, png, info, coded = sheet
    image = np.asarray(Image.open(png).convert("L"), dtype=float)
    building = shapely.force_2d(gpd.read_file(coded, layer="FAB01002").geometry.iloc[0])
    inner = building.buffer(-2.0)  # away from the outline
    x0, y0, x1, _ = inner.bounds
    ymid = (inner.bounds[1] + inner.bounds[3]) / 2
    c0, row = _pixel(info, x0, ymid)
    c1, _ = _pixel(info, x1, ymid)
    profile = image[int(row), int(c0):int(c1)]
    assert profile.min() < 150 and profile.max() > 230  # lines on white
    # lines 1 mm apart at 45 degrees cross a row every 1 / sin(45) = 1.414 mm
    assert _period_px(profile) == pytest.approx(1.414 / 25.4 * DPI, rel=0.06)
    # no hatching outside the building (a patch of the street between buildings A and E)
    c, r = _pixel(info, 1688340.0, 4799632.0)
    assert image[int(r) - 5:int(r) + 5, int(c) - 5:int(c) + 5].min() > 230


def test_scarp_ticks_on_the_left_every_2_mm(sheet):
    _, png, info, _ = sheet
    image = np.asarray(Image.open(png).convert("L"), dtype=float)
    c0, r = _pixel(info, 1688354.0, SCARP_Y)  # between the map grid's crosses
    c1, _ = _pixel(info, 1688396.0, SCARP_Y)
    mm = DPI / 25.4
    above = image[int(r - 0.7 * mm), int(c0):int(c1)]  # left of a west -> east line: north
    below = image[int(r + 0.7 * mm), int(c0):int(c1)]
    assert above.min() < 180 and below.min() > 230
    assert _period_px(above) == pytest.approx(2.0 * mm, rel=0.05)


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler's pdftotext")
def test_grid_labels_in_two_crss_do_not_overlap(sheet):
    import re

    html = subprocess.run(["pdftotext", "-bbox", str(sheet[0]), "-"], capture_output=True,
                          text=True, check=True).stdout
    boxes = [(float(a), float(b), float(c), float(d), w) for a, b, c, d, w in re.findall(
        r'xMin="([\d.]+)" yMin="([\d.]+)" xMax="([\d.]+)" yMax="([\d.]+)">(\d{6,7})<', html)]
    gb = [b for b in boxes if b[4].startswith(("1688", "4799"))]  # Gauss-Boaga (EPSG:3003)
    utm = [b for b in boxes if b[4].startswith("688")]  # ETRS89 / UTM 32N eastings
    assert len(gb) >= 4 and len(utm) >= 2
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            overlap = min(a[2], b[2]) - max(a[0], b[0]) > 0 and min(a[3], b[3]) - max(a[1],
                                                                                  b[1]) > 0
            assert not overlap, (a, b)
    # each UTM easting is where pyproj puts it along the bottom edge
    from pyproj import Transformer

    to_gb = Transformer.from_crs("EPSG:6707", "EPSG:3003", always_xy=True)
    left_pt = sheet[2]["frame_mm"][0] * PT_PER_MM
    for x0, _, x1, _, word in utm:
        e, _ = to_gb.transform(float(word), 4799600.0)  # near the bottom edge (N 4799595)
        expected = left_pt + (e - EXTENT[0]) / SCALE * 1000 * PT_PER_MM
        assert abs((x0 + x1) / 2 - expected) < 1.0 * PT_PER_MM  # within 1 mm (the edge's N)


def test_bad_hatch_is_one_line_exit_2(sheet, tmp_path):
    from conftest import run_cli

    bad = tmp_path / "codes.txt"
    bad.write_text("codice;descrizione;tipologia;colore;campitura\n"
                   "FAB01002;edificio;poligono;12;diagonal\n", encoding="utf-8")
    out = tmp_path / "bad.pdf"
    proc = run_cli("run", "carto:sheet", "--EXTENT", "1688290,4799595,1688410,4799665 "
                   "[EPSG:3003]", "--LAYERS", f"{sheet[3]}|layername=FAB01002", "--CODES", bad,
                   "--OUTPUT", out)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "hatch 'diagonal'" in lines[0] and "line 2" in lines[0]
    assert "Traceback" not in proc.stderr and not out.exists()


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler's pdftotext")
def test_crowded_spot_heights_never_overlap_each_other_or_a_text(tmp_path):
    """Nine spot heights 12 m apart (2.4 mm at 1:5000) under a place name: every label is
    placed where it touches no other text, or left out and counted."""
    import re

    heights = [300.1 + k for k in range(9)]
    x = 1688000.0 + 12.0 * np.arange(9)
    gpd.GeoDataFrame({"quota": heights}, geometry=shapely.points(x, np.full(9, 4799500.0)),
                     crs="EPSG:3003").to_file(tmp_path / "spots.gpkg")
    gpd.GeoDataFrame({"text": ["Poggio al Vento"], "text_height": [10.0]},
                     geometry=[shapely.Point(1688030.0, 4799490.0)],
                     crs="EPSG:3003").to_file(tmp_path / "texts.gpkg")
    pdf = tmp_path / "crowded.pdf"
    res = toolbox.run("carto:sheet", {
        "EXTENT": "1687900,4799400,1688150,4799600 [EPSG:3003]", "SCALE": 5000,
        "LAYERS": [tmp_path / "texts.gpkg", tmp_path / "spots.gpkg"], "OUTPUT": pdf})
    left_out = res["SHEETS_WRITTEN"][0]["labels_left_out"]
    html = subprocess.run(["pdftotext", "-bbox", str(pdf), "-"], capture_output=True,
                          text=True, check=True).stdout
    words = [(float(a), float(b), float(c), float(d), w) for a, b, c, d, w in re.findall(
        r'xMin="([\d.]+)" yMin="([\d.]+)" xMax="([\d.]+)" yMax="([\d.]+)">([^<]+)<', html)]
    labels = [w for w in words if re.match(r"30\d\.\d", w[4]) or w[4] in ("Poggio", "al",
                                                                           "Vento")]
    placed = re.findall(r"30\d\.\d", " ".join(w[4] for w in words))  # pdftotext may join two
    assert len(placed) == 9 - left_out
    assert 0 < left_out and len(placed) >= 3  # crowded: some left out, several placed
    for i, a in enumerate(labels):
        for b in labels[i + 1:]:
            overlap = min(a[2], b[2]) - max(a[0], b[0]) > 0.1 and min(a[3], b[3]) - max(
                a[1], b[1]) > 0.1
            assert not overlap, (a, b)


def test_a_geographic_grid_crs_is_refused_in_one_line(sheet, tmp_path):
    from conftest import run_cli

    out = tmp_path / "geo.pdf"
    proc = run_cli("run", "carto:sheet", "--EXTENT", "1688290,4799595,1688410,4799665 "
                   "[EPSG:3003]", "--LAYERS", f"{sheet[3]}|layername=FAB01002",
                   "--GRID_CRS", "EPSG:4326", "--OUTPUT", out)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "GRID_CRS" in lines[0] and "projected" in lines[0]
    assert not out.exists()
