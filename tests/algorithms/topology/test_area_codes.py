"""Area codes from the code file (issue 30): a closed line codes the face it bounds only when the
code file says its code is an area code (type polygon) or names the area code it bounds; only area
codes conflict. Hand-made layers whose right answer is read off the drawing."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from click.testing import CliRunner

import toolbox
from toolbox.errors import InputDataError
from toolbox.io.code_file import read_code_file
from toolbox.topology.area_codes import AreaCodes
from toolbox.topology.build import build_topology

CODE_FILE = """\
# file dei codici (header layout, with the area column)
codice;descrizione;tipologia;colore;codice area
STR02001;limite di strada (cordolo);polilinea;3;
FAB01002;muro perimetrale di fabbricato civile;linea;12;AREA_FAB
FAB01003;fabbricato industriale;poligono;12;
VER01001;aiuola;poligono;1;
MAR01001;marciapiede;poligono;2;
AREA_FAB;fabbricato (area);poligono;12;
QUO01001;punto quotato;punto;5;
SIE01001;siepe o cordolo;linea;1;VER01001|MAR01001
"""

BLOCK = [(0, 0), (50, 0), (50, 30), (0, 30), (0, 0)]  # a kerb closed around a block
HOUSE = [(5, 5), (15, 5), (15, 15), (5, 15), (5, 5)]
SHED = [(25, 5), (35, 5), (35, 15), (25, 15), (25, 5)]


@pytest.fixture(scope="module")
def codes(tmp_path_factory):
    path = tmp_path_factory.mktemp("codes") / "codici.txt"
    path.write_text(CODE_FILE)
    return AreaCodes.from_table(read_code_file(path))


def build(lines, labels, area_codes):
    geoms = np.array([shapely.LineString(c) for _, c in lines], dtype=object)
    line_codes = np.array([code for code, _ in lines], dtype=object)
    points = np.array([shapely.Point(xy) for _, xy in labels], dtype=object)
    label_codes = np.array([code for code, _ in labels], dtype=object)
    return build_topology(geoms, line_codes, points, label_codes, area_codes=area_codes)


def code_at(out, x, y):
    inside = np.flatnonzero(shapely.contains_xy(out.areas.geometry, x, y))
    assert len(inside) == 1
    return out.areas.columns["code"][inside[0]]


def conflicts(out):
    cols = out.errors.columns
    return [d for t, d in zip(cols["type"], cols["detail"], strict=True)
            if t == "conflicting_labels"]


def test_code_file_area_column(codes):
    assert codes.of_outline("FAB01002") == ("AREA_FAB",)  # a line code naming its area
    assert codes.of_outline("FAB01003") == ("FAB01003",)  # a polygon code is an area code
    assert codes.of_outline("STR02001") == ()  # a kerb only bounds
    assert codes.of_outline("SIE01001") == ("VER01001", "MAR01001")
    assert not codes.is_area_label("QUO01001") and codes.is_area_label("MAR01001")


def test_kerb_closed_around_a_labelled_block_is_no_conflict(codes):
    lines = [("STR02001", BLOCK)]
    labels = [("MAR01001", (40, 25))]
    for area_codes in (codes, None):  # with the code file, and without one
        out = build(lines, labels, area_codes)
        assert conflicts(out) == []
        assert code_at(out, 40, 25) == "MAR01001"
        assert out.statistics["labels"]["conflicting_areas"] == 0


def test_kerb_closed_around_an_unlabelled_block_codes_nothing(codes):
    out = build([("STR02001", BLOCK)], [], codes)
    assert code_at(out, 40, 25) is None
    assert [t for t in out.errors.columns["type"]] == ["unlabelled_area"]


def test_two_different_area_codes_conflict(codes):
    lines = [("STR02001", BLOCK), ("FAB01003", SHED)]
    out = build(lines, [("MAR01001", (40, 25)), ("VER01001", (30, 10))], codes)
    assert conflicts(out) == ["closed line FAB01003 and label code VER01001 disagree: the "
                              "label's code is used"]
    assert code_at(out, 30, 10) == "VER01001"
    # without the code file a line code and an area code cannot be told apart: no conflict
    assert conflicts(build(lines, [("MAR01001", (40, 25)), ("VER01001", (30, 10))], None)) == []


def test_line_code_gives_the_area_code_it_bounds(codes):
    lines = [("STR02001", BLOCK), ("FAB01002", HOUSE), ("FAB01002", SHED)]
    # the house labelled with the building's area code; the shed unlabelled
    out = build(lines, [("MAR01001", (40, 25)), ("AREA_FAB", (10, 10))], codes)
    assert conflicts(out) == []
    assert code_at(out, 10, 10) == "AREA_FAB" and code_at(out, 30, 10) == "AREA_FAB"
    assert "unlabelled_area" not in list(out.errors.columns["type"])
    # a wall closed around an area labelled as a flower bed: two area codes
    out = build(lines, [("MAR01001", (40, 25)), ("VER01001", (10, 10))], codes)
    assert conflicts(out) == ["closed line FAB01002 (area AREA_FAB) and label code VER01001 "
                              "disagree: the label's code is used"]
    # labelled with the wall's own code: the label and the line say the same
    out = build(lines, [("MAR01001", (40, 25)), ("FAB01002", (10, 10))], codes)
    assert conflicts(out) == [] and code_at(out, 10, 10) == "FAB01002"


def test_a_line_bounding_either_of_two_areas(codes):
    lines = [("STR02001", BLOCK), ("SIE01001", HOUSE)]
    out = build(lines, [("MAR01001", (40, 25)), ("MAR01001", (10, 10))], codes)
    assert conflicts(out) == [] and code_at(out, 10, 10) == "MAR01001"
    out = build(lines, [("MAR01001", (40, 25))], codes)
    assert code_at(out, 10, 10) == "VER01001"  # unlabelled: the first area code
    out = build(lines, [("MAR01001", (40, 25)), ("FAB01003", (10, 10))], codes)
    assert conflicts(out) == ["closed line SIE01001 (area VER01001 or MAR01001) and label code "
                              "FAB01003 disagree: the label's code is used"]


def test_point_code_label_gives_attributes_only(codes):
    lines = [("STR02001", BLOCK), ("FAB01003", SHED)]
    out = build(lines, [("MAR01001", (40, 25)), ("QUO01001", (30, 10))], codes)
    assert conflicts(out) == [] and code_at(out, 30, 10) == "FAB01003"


def test_two_labels_with_different_area_codes(codes):
    out = build([("STR02001", BLOCK)], [("MAR01001", (40, 25)), ("VER01001", (20, 20))], codes)
    assert conflicts(out) == ["2 labels give area codes MAR01001, VER01001: MAR01001 (the first "
                              "label's) is used"]


def test_code_file_errors(tmp_path):
    bad = tmp_path / "codici.txt"
    bad.write_text("codice;tipologia;area\nQUO01001;punto;AREA_X\n")
    with pytest.raises(InputDataError, match="line 2: code 'QUO01001' is a point code: it "
                                             "cannot bound area AREA_X"):
        read_code_file(bad)
    bad.write_text("codice;tipologia;area\nFAB01002;linea;STR02001\nSTR02001;linea;\n")
    with pytest.raises(InputDataError, match="code 'FAB01002' bounds area 'STR02001', but line "
                                             "3 declares 'STR02001' a line code"):
        read_code_file(bad)


def _layers(tmp_path):
    import geopandas as gpd

    def siena(geoms):  # the hand-made layer moved near Siena (EPSG:3003)
        return shapely.transform(np.array(geoms, dtype=object), lambda xy: xy + (1688200, 4799600))

    lines = gpd.GeoDataFrame({"code": ["STR02001", "FAB01002"]},
                             geometry=siena([shapely.LineString(BLOCK), shapely.LineString(HOUSE)]),
                             crs="EPSG:3003")
    labels = gpd.GeoDataFrame({"code": ["MAR01001", "AREA_FAB"]},
                              geometry=siena([shapely.Point(40, 25), shapely.Point(10, 10)]),
                              crs="EPSG:3003")
    lines.to_file(tmp_path / "lines.gpkg")
    labels.to_file(tmp_path / "labels.gpkg")
    (tmp_path / "codici.txt").write_text(CODE_FILE)
    return tmp_path / "lines.gpkg", tmp_path / "labels.gpkg", tmp_path / "codici.txt"


def test_build_areas_reads_codes(tmp_path):
    lines, labels, code_file = _layers(tmp_path)
    stats = toolbox.run("topology:build_areas", {
        "INPUT": lines, "LABELS": labels, "CODES": code_file,
        "OUTPUT": tmp_path / "areas.gpkg"})["STATISTICS"]
    assert stats["labels"]["conflicting_areas"] == 0 and stats["area_codes"] == "CODES"
    stats = toolbox.run("topology:check", {
        "INPUT": lines, "LABELS": labels, "OUTPUT": tmp_path / "check.gpkg"})["STATISTICS"]
    assert stats["labels"]["conflicting_areas"] == 0  # no CODES: fill only


def test_bad_codes_exit_2_one_line_nothing_written(tmp_path):
    from toolbox.cli import main

    lines, labels, code_file = _layers(tmp_path)
    code_file.write_text("codice;tipologia\nFAB01002;triangolo\n")
    out = tmp_path / "areas.gpkg"
    res = CliRunner().invoke(main, ["run", "topology:build_areas", "--INPUT", str(lines),
                                    "--LABELS", str(labels), "--CODES", str(code_file),
                                    "--OUTPUT", str(out)])
    assert res.exit_code == 2
    assert res.stderr.strip().count("\n") == 0 and "CODES" in res.stderr
    assert "type 'triangolo' of code 'FAB01002'" in res.stderr
    assert "Traceback" not in res.output and not out.exists()


def test_shared_parameter_file_gives_no_warning(tmp_path):
    """The sample 'file dei parametri' holds every entry of the job: the entries for other steps
    are an information message, not a warning on every step (issue 30)."""
    from toolbox.demo.samples import linework

    data = linework.make(tmp_path, {})
    feedback = toolbox.Feedback()
    toolbox.run("topology:check", {"INPUT": data["linework"],
                                   "PARAMETERS": data["linework_parameters"],
                                   "OUTPUT": tmp_path / "c.gpkg"}, feedback=feedback)
    assert not [w for w in feedback.warnings if "PARAMETERS" in w]
    info = [t for lvl, t in feedback.messages if lvl == "info" and "not used by" in t]
    assert len(info) == 1 and "7 entries for other steps" in info[0]
