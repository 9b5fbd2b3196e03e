"""Code file, colour file and the shared parameter file (thesis S002 §2.2.1, §3.6)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

import toolbox
from toolbox.demo.parameter_files import parameter_file_text
from toolbox.errors import InputDataError
from toolbox.io.code_file import percent_to_byte, read_code_file, read_colour_file
from toolbox.io.parameter_file import read_parameter_file


def write(tmp_path, name, text, encoding="utf-8"):
    path = tmp_path / name
    path.write_bytes(text.encode(encoding))
    return path


# -- code file ---------------------------------------------------------------------------------
def test_thesis_layout_tab_separated_with_empty_colour(tmp_path):
    # the two lines printed in S002 l.688-689, then one with a Latin-1 description
    text = ("FAB01002\t12\tmuro perimetrale di fabbricato civile\n"
            "STR0200104\t\tlimite di strada\n"
            "TOP01001\t8\ttoponimo di località\n")
    table = read_code_file(write(tmp_path, "codici.txt", text, "latin-1"))
    assert table.layout == "code colour description"
    assert list(table.entries) == ["FAB01002", "STR0200104", "TOP01001"]
    assert table["FAB01002"].colour == "12" and table["FAB01002"].kind is None
    assert table["FAB01002"].description == "muro perimetrale di fabbricato civile"
    assert table["STR0200104"].colour is None
    assert table["TOP01001"].description == "toponimo di località"


def test_thesis_layout_white_space_quoted_and_unquoted(tmp_path):
    text = ('# codici\n'
            'FAB01002 12 "muro perimetrale di fabbricato civile"\n'
            'STR0200104 "limite di strada"\n'
            'VEG01001 1 area a verde di località\n'
            '"2PIANI" "2 piani fuori terra"\n')
    table = read_code_file(write(tmp_path, "codici.txt", text))
    assert [(e.code, e.colour, e.description) for e in table.entries.values()] == [
        ("FAB01002", "12", "muro perimetrale di fabbricato civile"),
        ("STR0200104", None, "limite di strada"),
        ("VEG01001", "1", "area a verde di località"),
        ("2PIANI", None, "2 piani fuori terra")]
    assert table["FAB01002"].line == 2


def test_zmap_layout_semicolons(tmp_path):
    # S002 l.3251: ID; description; type (point, line, polyline); colour
    text = ("FAB01002; muro perimetrale di fabbricato civile; poligono; 12\n"
            "STR02001; limite di strada; polilinea; 3\n"
            "QUO01001; punto quotato; punto; 5\n"
            "CUR01001; curva di livello; line;\n")
    table = read_code_file(write(tmp_path, "zmap.txt", text))
    assert table.layout == "id; description; type; colour"
    assert {c: (e.kind, e.colour) for c, e in table.entries.items()} == {
        "FAB01002": ("polygon", "12"), "STR02001": ("line", "3"), "QUO01001": ("point", "5"),
        "CUR01001": ("line", None)}


@pytest.mark.parametrize("header, sep", [
    ("Tipologia;COLORE;Codice;Descrizione", ";"),
    ("type\tcolour\tcode\tdescription", "\t"),
    ("color code type description", " "),
])
def test_header_columns_in_any_order_language_and_case(tmp_path, header, sep):
    names = header.replace(";", " ").replace("\t", " ").split()
    values = {"type": "polygon", "colour": "12", "code": "FAB01002",
              "description": "muro perimetrale di località"}
    key = {"tipologia": "type", "colore": "colour", "codice": "code", "descrizione":
           "description", "type": "type", "colour": "colour", "color": "colour", "code": "code",
           "description": "description"}
    row = [values[key[n.lower()]] for n in names]
    if sep == " ":
        row = [f'"{v}"' if " " in v else v for v in row]
    table = read_code_file(write(tmp_path, "c.txt", header + "\n" + sep.join(row) + "\n",
                                 "latin-1"))
    entry = table["FAB01002"]
    assert (entry.kind, entry.colour, entry.description) == (
        "polygon", "12", "muro perimetrale di località")
    assert table.layout == "header"


@pytest.mark.parametrize("text, message", [
    ("FAB01002;muro;pentagono;12\n", "line 1: type 'pentagono' of code 'FAB01002'"),
    ("codice;colore\nFAB01002;12\nFAB01002;3\n", "line 3: code 'FAB01002' given twice "
                                                   "(first on line 2)"),
    ("codice\tcolore\tdescrizione\nFAB01002\trosso\tmuro\n", "line 2: colour 'rosso'"),
    ("# solo commenti\n", "has no codes"),
    ("codice;colore;descrizione\n;12;senza codice\n", "line 2: no code"),
])
def test_code_file_errors_name_file_and_line(tmp_path, text, message):
    path = write(tmp_path, "codici.txt", text)
    with pytest.raises(InputDataError) as err:
        read_code_file(path)
    assert message in str(err.value) and str(path) in str(err.value)


# -- colour file -------------------------------------------------------------------------------
def test_colour_file_thesis_values_and_rounding(tmp_path):
    # S002 l.701-704 (header as printed), then decimal percentages (point and comma) and 30 %
    text = ("INDICE\t%ROSSO\t%VERDE\t%BLU\n1\t20\t80\t0\n2\t10\t65\t65\n3\t100\t0\t0\n"
            "4 12.5 50,2 30\n")
    colours = read_colour_file(write(tmp_path, "colori.txt", text))
    # round(p * 255 / 100) half up: 20 -> 51, 80 -> 204, 10 -> 25.5 -> 26, 65 -> 165.75 -> 166,
    # 12.5 -> 31.875 -> 32, 50.2 -> 128.01 -> 128, 30 -> 76.5 -> 77
    assert colours == {"1": (51, 204, 0), "2": (26, 166, 166), "3": (255, 0, 0),
                       "4": (32, 128, 77)}
    assert [percent_to_byte(p) for p in (0, 50, 100)] == [0, 128, 255]


def test_colour_file_without_header(tmp_path):
    assert read_colour_file(write(tmp_path, "c.txt", "12 30 30 30\n")) == {"12": (77, 77, 77)}


@pytest.mark.parametrize("text, message", [
    # duplicate-ok: the bad files of each format written out, with their messages
    ("INDICE %R %G %B\n1 20 80\n", "line 2: expected 'INDEX %RED %GREEN %BLUE'"),
    ("1 20 180 0\n", "line 1: colour 1: components must be percentages 0-100"),
    ("1 20 80 0\n1 0 0 0\n", "line 2: colour index 1 given twice (first on line 1)"),
    ("1 0 0 0\n2 x 0 0\n", "line 2: colour 2: components must be percentages"),
    ("INDICE %R %G %B\na1 20 80 0\n", "line 2: colour index 'a1' must be a whole number"),
])
def test_colour_file_errors(tmp_path, text, message):
    path = write(tmp_path, "colori.txt", text)
    with pytest.raises(InputDataError) as err:
        read_colour_file(path)
    assert message in str(err.value) and str(path) in str(err.value)


# -- parameter file: one reader, every entry used or named ---------------------------------------
# the restitution sample's entries without its comment line, a decimal comma, one unknown entry
FULL_PARAMETERS = parameter_file_text([], ("0.50", "0.20", "0.10", "m", "3", "1688000 4799000",
                                           "0.10", "0.20", "3,0", "2.0", "0.50", "0.30"),
                                      {"colore di sfondo": "7"})


def test_parameter_file_unused_entries_named(tmp_path):
    file = read_parameter_file(write(tmp_path, "p.txt", FULL_PARAMETERS, "latin-1"))
    assert file.values["squaring_angle_tolerance"] == 3.0
    assert file.offset == (1688000.0, 4799000.0)
    unused = file.unused({"closure_tolerance", "coordinate_offset", "decimals",
                          "coordinate_unit", "snap_tolerance", "height_snap_tolerance"})
    assert unused == ["'tolleranza di identificazione' (line 1)",
                      "'tolleranza planimetrica di allineamento' (line 7)",
                      "'tolleranza planimetrica di squadratura' (line 8)",
                      "'tolleranza angolare di squadratura' (line 9)",
                      "'passo di spline' (line 10)", "'tolleranza di fine polilinea' (line 12)",
                      "'colore di sfondo' (line 13)"]


def test_angle_tolerance_range(tmp_path):
    with pytest.raises(InputDataError, match="line 1: 'tolleranza angolare di squadratura' must "
                                             "be an angle in degrees"):
        read_parameter_file(write(tmp_path, "p.txt", "tolleranza angolare di squadratura = 50\n"))


def test_translation_applied(tmp_path):
    file = read_parameter_file(write(tmp_path, "p.txt", "traslazione delle coordinate = 10 20\n"))
    line = shapely.LineString([(1, 2, 300), (3, 4, 301)])
    moved = file.translate(np.array([line], dtype=object))[0]
    assert shapely.get_coordinates(moved, include_z=True).tolist() == [[11, 22, 300],
                                                                        [13, 24, 301]]


def test_topology_applies_the_translation_and_names_unused_entries(tmp_path):
    """topology:build_areas reads the same file: stored coordinates + translation = map."""
    import geopandas as gpd

    square = shapely.LineString([(100, 200), (110, 200), (110, 210), (100, 210), (100, 200)])
    # stored (false-origin) coordinates carry no CRS: only the translated ones are EPSG:3003
    lines = gpd.GeoDataFrame({"code": ["FAB01002"]}, geometry=[square])
    src = tmp_path / "stored.gpkg"
    with pytest.warns(UserWarning, match="'crs' was not provided"):  # meant: no CRS
        lines.to_file(src, driver="GPKG")
    params = write(tmp_path, "p.txt", FULL_PARAMETERS)
    feedback = toolbox.Feedback()
    out = tmp_path / "areas.gpkg"
    toolbox.run("topology:build_areas", {"INPUT": src, "PARAMETERS": params, "OUTPUT": out},
                feedback=feedback)
    areas = gpd.read_file(out, layer="areas")
    assert areas.total_bounds.tolist() == [1688100.0, 4799200.0, 1688110.0, 4799210.0]
    # entries other steps use: one information message; the unknown entry: a warning
    info = next(t for lvl, t in feedback.messages
                if lvl == "info" and "not used by area building" in t)
    for name in ("tolleranza di identificazione", "tolleranza planimetrica di squadratura",
                 "passo di spline", "tolleranza di riattacco altimetrico"):
        assert name in info
    assert "traslazione" not in info and "tolleranza di chiusura" not in info
    assert [w for w in feedback.warnings if "PARAMETERS" in w] == [
        "PARAMETERS 'p.txt': 1 entries not recognised (not a known 'file dei parametri' entry: "
        "misspelt?): 'colore di sfondo' (line 13)"]
