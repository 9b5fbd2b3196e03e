"""carto:sheet_index numbers CTR elements and sections as the CTRs are numbered (IGM 1:50000
sheet, 16 sections 01-16 by rows from the north-west, 4 elements 1-4 clockwise from the
north-east: it.wikipedia "Carta tecnica regionale", Regione Emilia-Romagna's CTR 1:5000
catalogue record), and carto:sheet draws the index map. The expected numbers are worked by
hand from that rule for points placed (ED50 longitude, latitude) in known cells; the sheet
edges are checked in ED50 through pyproj, and the index map's numbers are read back from the
PDF by poppler's pdftotext."""

from __future__ import annotations

import re
import shutil
import subprocess

import geopandas as gpd
import numpy as np
import pytest
import shapely
from pyproj import Transformer

import toolbox

ORIGIN = (11 + 10 / 60, 43 + 24 / 60)  # NW corner of the 1:50000 sheet: 11°10' E, 43°24' N
TO_GB = Transformer.from_crs("EPSG:4230", "EPSG:3003", always_xy=True)
TO_ED50 = Transformer.from_crs("EPSG:3003", "EPSG:4230", always_xy=True)


def _extent_at(minutes_east: float, minutes_south: float, half: float = 20.0) -> str:
    """A 40 m box (EPSG:3003) around the point ``minutes_east`` of the origin's meridian and
    ``minutes_south`` of its parallel."""
    x, y = TO_GB.transform(ORIGIN[0] + minutes_east / 60, ORIGIN[1] - minutes_south / 60)
    return f"{x - half},{y - half},{x + half},{y + half} [EPSG:3003]"


def _index(tmp_path, extent: str, scale: str = "5000", neighbours: bool = False,
           name: str = "index.gpkg"):
    out = tmp_path / name
    feedback = toolbox.Feedback()
    toolbox.run("carto:sheet_index", {"EXTENT": extent, "SHEET_50K": 296, "SCALE": scale,
                                      "ORIGIN": f"{ORIGIN[0]!r},{ORIGIN[1]!r}",
                                      "NEIGHBOURS": neighbours, "OUTPUT": out},
                feedback=feedback)
    return gpd.read_file(out, layer="sheets"), feedback, out


# (minutes east, minutes south) of a point -> its element, worked by hand: elements are
# 2.5' x 1.5'; column c = east // 2.5, row r = south // 1.5; section = 4 (r // 2) + c // 2 + 1;
# inside it (r % 2, c % 2): (0, 1) NE = 1, (1, 1) SE = 2, (1, 0) SW = 3, (0, 0) NW = 4
ELEMENTS = [((1.0, 0.5), "296014"),     # r 0, c 0: section 01, NW
            ((19.0, 0.5), "296041"),    # r 0, c 7: section 04, NE
            ((19.0, 11.5), "296162"),   # r 7, c 7: section 16, SE
            ((1.0, 11.5), "296133"),    # r 7, c 0: section 13, SW
            ((8.2, 4.0), "296061"),     # r 2, c 3: section 06, NE
            ((11.0, 7.7), "296113")]    # r 5, c 4: section 11, SW


@pytest.mark.parametrize("where, number", ELEMENTS)
def test_element_numbers_follow_the_ctr_rule(tmp_path, where, number):
    frame, _, _ = _index(tmp_path, _extent_at(*where))
    assert frame["number"].tolist() == [number]
    row = frame.iloc[0]
    assert (row["sheet_50k"], row["section"], row["element"], row["scale"]) == (
        296, int(number[3:5]), int(number[5]), 5000)
    assert row["name"] == f"elemento {number}"
    # its ED50 edges: 2'30" x 1'30", on the lattice from the origin, holding the point
    assert (row["east"] - row["west"]) * 60 == pytest.approx(2.5)
    assert (row["north"] - row["south"]) * 60 == pytest.approx(1.5)
    lon, lat = ORIGIN[0] + where[0] / 60, ORIGIN[1] - where[1] / 60
    assert row["west"] < lon < row["east"] and row["south"] < lat < row["north"]
    assert ((row["west"] - ORIGIN[0]) * 60 / 2.5) == pytest.approx(
        round((row["west"] - ORIGIN[0]) * 60 / 2.5), abs=1e-9)


def test_sections_at_1_10000(tmp_path):
    frame, _, _ = _index(tmp_path, _extent_at(8.2, 4.0), scale="10000")
    assert frame["number"].tolist() == ["296060"]  # r 1, c 1 of 5' x 3' sections
    assert frame.iloc[0]["element"] == 0


def test_polygons_are_the_ed50_meridians_and_parallels(tmp_path):
    """Every vertex of an element's polygon, taken back to ED50 by pyproj, lies on one of
    its four edges; the four elements of a section tile the section's polygon."""
    frame, _, _ = _index(tmp_path, _extent_at(8.2, 4.0), neighbours=True)
    assert len(frame) == 9 and frame["in_extent"].sum() == 1
    for _, row in frame.iterrows():
        lon, lat = TO_ED50.transform(*np.asarray(row.geometry.exterior.coords).T)
        on_edge = (np.isclose(lon, row["west"], atol=1e-9) | np.isclose(lon, row["east"],
                                                                        atol=1e-9)
                   | np.isclose(lat, row["south"], atol=1e-9)
                   | np.isclose(lat, row["north"], atol=1e-9))
        assert on_edge.all()
    section, _, _ = _index(tmp_path, _extent_at(8.2, 4.0), scale="10000", name="s.gpkg")
    # the section 06 element quartet: NE 061 (in the extent), and its three others
    quartet = []
    for where, number in (((8.2, 4.0), "296061"), ((8.2, 5.2), "296062"),
                          ((6.0, 5.2), "296063"), ((6.0, 4.0), "296064")):
        one, _, _ = _index(tmp_path, _extent_at(*where), name="q.gpkg")
        assert one["number"].tolist() == [number]
        quartet.append(one.geometry.iloc[0])
        (tmp_path / "q.gpkg").unlink()
    union = shapely.union_all(quartet)
    own = section.geometry.iloc[0]
    assert union.symmetric_difference(own).area < 1e-6 * own.area
    # neighbours share edges exactly: no gap, no overlap
    middle = frame[frame["in_extent"] == 1].geometry.iloc[0]
    for geom in frame.geometry:
        if geom is not middle:
            assert geom.intersection(middle).area < 1e-6


def test_sheets_outside_the_50k_sheet_are_unnumbered_and_said(tmp_path):
    frame, feedback, _ = _index(tmp_path, _extent_at(1.0, 0.5), neighbours=True)
    assert len(frame) == 9
    assert (frame["number"] == "").sum() == 5  # the NW corner element's ring: 5 outside
    assert sorted(n for n in frame["number"] if n) == ["296011", "296012", "296013",
                                                       "296014"]
    assert any("5 sheets fall outside 1:50000 sheet 296" in w for w in feedback.warnings)


def test_bad_origin_is_one_line_exit_2(tmp_path):
    from conftest import run_cli

    out = tmp_path / "idx.gpkg"
    proc = run_cli("run", "carto:sheet_index", "--EXTENT", _extent_at(8.2, 4.0),
                   "--SHEET_50K", "296", "--ORIGIN", "11.1667", "--OUTPUT", out)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "ORIGIN" in lines[0] and "lon,lat" in lines[0], lines
    assert "Traceback" not in proc.stderr and not out.exists()


@pytest.mark.parametrize("origin, word", [("abc,43", "lon,lat"), ("200,43", "longitude")])
def test_other_bad_origins_are_parameter_errors(tmp_path, origin, word):
    from toolbox.errors import ParameterError

    out = tmp_path / "idx.gpkg"
    with pytest.raises(ParameterError, match=f"ORIGIN.*{word}"):
        toolbox.run("carto:sheet_index", {"EXTENT": _extent_at(8.2, 4.0), "SHEET_50K": 296,
                                          "ORIGIN": origin, "OUTPUT": out})
    assert not out.exists()


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler's pdftotext")
def test_sheet_draws_the_index_map_of_its_element(tmp_path):
    """One sheet per element of the index (SHEETS = the index, SHEET_ID number) with the
    index map: each page shows its element's number and its 8 neighbours', at the panel's
    top right, not in the map frame."""
    _, _, index = _index(tmp_path, _extent_at(8.2, 4.0), neighbours=True)
    _, _, alone = _index(tmp_path, _extent_at(8.2, 4.0), name="alone.gpkg")
    pdf = tmp_path / "sheets.pdf"
    res = toolbox.run("carto:sheet", {
        "SHEETS": f"{alone}|layername=sheets", "SHEET_ID": "number", "SCALE": 5000,
        "INDEX": f"{index}|layername=sheets", "OUTPUT": pdf})
    page = res["SHEETS_WRITTEN"][0]
    assert page["sheet"] == "296061"
    assert page["index_map"]["sheet"] == "296061"
    assert sorted(page["index_map"]["neighbours"]) == [
        "296022", "296023", "296033", "296062", "296063", "296064", "296073", "296074"]
    html = subprocess.run(["pdftotext", "-bbox", str(pdf), "-"],
                          capture_output=True, text=True, check=True).stdout
    words = [(float(a), float(b), w) for a, b, _, _, w in re.findall(
        r'xMin="([\d.]+)" yMin="([\d.]+)" xMax="([\d.]+)" yMax="([\d.]+)">(2960\d\d)<', html)]
    # the index map: the panel's top 26 mm (the title block, at its foot, names the sheet too)
    left, bottom, width, height = page["panel_mm"]
    top_pt = (page["paper_mm"][1] - bottom - height) * 72 / 25.4
    inset = [(x, y, w) for x, y, w in words if top_pt < y < top_pt + 26 * 72 / 25.4]
    assert sorted(w for _, _, w in inset) == sorted(["296061", *page["index_map"]
                                                     ["neighbours"]])
    assert all(left * 72 / 25.4 < x < (left + width) * 72 / 25.4 for x, _, _ in inset)


@pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler's pdftotext")
def test_an_extent_sheet_names_its_index_number(tmp_path):
    """A sheet of an EXTENT (its id "1") inside element 296061: the title block says so."""
    _, _, index = _index(tmp_path, _extent_at(8.2, 4.0), neighbours=True)
    pdf = tmp_path / "one.pdf"
    toolbox.run("carto:sheet", {"EXTENT": _extent_at(8.2, 4.0, half=60.0), "SCALE": 2000,
                                "INDEX": index, "OUTPUT": pdf})
    text = subprocess.run(["pdftotext", "-layout", str(pdf), "-"], capture_output=True,
                          text=True, check=True).stdout
    assert "sheet: 1" in text and "in sheet index: 296061" in text
