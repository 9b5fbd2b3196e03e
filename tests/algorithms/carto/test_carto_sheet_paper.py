"""carto:sheet's paper: the smallest ISO sheet that holds the map at scale with its panel and
10 mm margins, and no text under 6 pt. Measured on the files, not taken from the layout code:
the page size from the PDF (pypdf), everything printed from the page rendered by poppler's
pdftoppm (the non-white pixels' extent), the font sizes from the PDF's text operators."""

from __future__ import annotations

import shutil
import subprocess

import geopandas as gpd
import numpy as np
import pytest
import shapely
from PIL import Image

import toolbox

pypdf = pytest.importorskip("pypdf", reason="pypdf (dev extra) reads the sheet PDFs back")
PT_PER_MM = 72 / 25.4
ISO = {"A4": (210, 297), "A3": (297, 420), "A2": (420, 594), "A1": (594, 841)}
SMALLER = {"A3": "A4", "A2": "A3", "A1": "A2"}
MARGIN_MM = 10.0
DPI = 25  # ~1 px per mm: enough to find the printed extent
E0, N0 = 1687000.0, 4798000.0


@pytest.mark.parametrize("ground, paper", [((500, 300), "A4"), ((1000, 800), "A3"),
                                           ((2000, 1500), "A2"), ((3000, 2200), "A1")])
@pytest.mark.skipif(shutil.which("pdftoppm") is None, reason="poppler's pdftoppm")
def test_smallest_iso_paper_with_10_mm_margins(tmp_path, ground, paper):
    w, h = ground
    road = gpd.GeoDataFrame({"code": ["road"]}, geometry=[shapely.LineString(
        [(E0, N0), (E0 + w, N0 + h)])], crs="EPSG:3003")
    road.to_file(tmp_path / "road.gpkg")
    pdf = tmp_path / "sheet.pdf"
    res = toolbox.run("carto:sheet", {"EXTENT": f"{E0},{N0},{E0 + w},{N0 + h} [EPSG:3003]",
                                      "SCALE": 5000, "LAYERS": [tmp_path / "road.gpkg"],
                                      "OUTPUT": pdf})
    box = pypdf.PdfReader(pdf).pages[0].mediabox
    page_mm = sorted((float(box.width) / PT_PER_MM, float(box.height) / PT_PER_MM))
    assert page_mm == pytest.approx(sorted(ISO[paper]), abs=0.05)
    assert res["SHEETS_WRITTEN"][0]["paper"] == paper
    # the map frame is ground / scale on paper
    assert res["SHEETS_WRITTEN"][0]["frame_mm"][2:] == pytest.approx([w / 5, h / 5])
    subprocess.run(["pdftoppm", "-r", str(DPI), "-gray", "-png", "-singlefile", str(pdf),
                    str(tmp_path / "page")], check=True)
    image = np.asarray(Image.open(tmp_path / "page.png").convert("L"))
    rows, cols = np.nonzero(image < 250)
    mm = 25.4 / DPI
    left, right = cols.min() * mm, (image.shape[1] - 1 - cols.max()) * mm
    top, bottom = rows.min() * mm, (image.shape[0] - 1 - rows.max()) * mm
    for side, margin in (("left", left), ("right", right), ("top", top), ("bottom", bottom)):
        assert margin >= MARGIN_MM - mm, f"{side} margin {margin:.1f} mm"
    # centred: equal margins left/right and top/bottom, within the grid labels' 6 mm band
    # (a side's labels need not reach its edge)
    assert abs(left - right) <= 6.0 + mm and abs(top - bottom) <= 6.0 + mm, (left, right, top,
                                                                             bottom)
    # and it is the smallest: the printed extent plus 10 mm margins does not fit the next size
    printed = ((cols.max() - cols.min()) * mm + 2 * MARGIN_MM,
               (rows.max() - rows.min()) * mm + 2 * MARGIN_MM)
    if paper in SMALLER:
        short, long_ = ISO[SMALLER[paper]]
        fits = any(printed[0] <= a and printed[1] <= b for a, b in ((short, long_),
                                                                    (long_, short)))
        assert not fits, (printed, SMALLER[paper])


def test_every_text_is_at_least_6_pt_at_print_size(tmp_path):
    """A full sheet (spot heights, a long sources line, grid labels in two CRSs, legend,
    title block): every text shown, its size from the text matrix times the current matrix."""
    spots = gpd.GeoDataFrame(geometry=shapely.points(
        [E0 + 200, E0 + 600], [N0 + 200, N0 + 500], [312.46, 301.04]), crs="EPSG:3003")
    spots.to_file(tmp_path / "spots.gpkg")
    pdf = tmp_path / "sheet.pdf"
    toolbox.run("carto:sheet", {"EXTENT": f"{E0},{N0},{E0 + 1000},{N0 + 800} [EPSG:3003]",
                                "SCALE": 5000, "LAYERS": [tmp_path / "spots.gpkg"],
                                "GRID_CRS": "EPSG:6707", "SOURCES": "a long sources line " * 8,
                                "OUTPUT": pdf})
    sizes = []

    def visit(text, cm, tm, font, size):
        if text.strip():
            sizes.append(size * float(np.hypot(tm[0], tm[1])) * float(np.hypot(cm[0], cm[1])))

    pypdf.PdfReader(pdf).pages[0].extract_text(visitor_text=visit)
    assert len(sizes) > 20
    assert min(sizes) >= 6.0 - 1e-6
