"""The parameter file reader (thesis S002 §2.2.1) and how tolerances are resolved."""

from __future__ import annotations

import pytest

from toolbox.demo.samples.linework import PARAMETER_FILE_TEXT
from toolbox.errors import InputDataError, ParameterError
from toolbox.io.parameter_file import KEYS, normalise_name, read_parameter_file
from toolbox.topology.tolerances import Tolerances, resolve_tolerances


def write(tmp_path, text, encoding="utf-8"):
    path = tmp_path / "parametri.txt"
    path.write_bytes(text.encode(encoding))
    return path


def test_every_entry_of_the_thesis_list_is_read(tmp_path):
    result = read_parameter_file(write(tmp_path, PARAMETER_FILE_TEXT))
    assert result.values == {
        "identification_tolerance": 0.5, "snap_tolerance": 0.2, "height_snap_tolerance": 0.1,
        "coordinate_unit": "m", "decimals": 3, "coordinate_offset": (0.0, 0.0),
        "alignment_tolerance": 0.05, "squaring_tolerance": 0.1, "squaring_angle_tolerance": 1.0,
        "spline_step": 0.5, "closure_tolerance": 0.5, "polyline_end_tolerance": 0.3,
        "min_dangle_length": 1.0, "min_area": 1.0}
    assert result.unknown == []
    assert result.line_numbers["snap_tolerance"] == 4


def test_syntax_variants(tmp_path):
    text = ("; commento INI\n"
            "Tolleranza di Riattacco Planimetrico [m]: 0,25   # virgola decimale\n"
            "passo  di   spline\t1,5\n"                   # tab-separated, extra spaces
            "unita di misura delle coordinate = metri\n"  # no accent
            "traslazione delle coordinate = 1688000; 4799500\n"
            "tolleranza di fine polline = 0.3\n"          # the thesis' misprint
            "colore di sfondo = 7\n"                      # not ours: kept as unknown
            "\n")
    result = read_parameter_file(write(tmp_path, text, "latin-1"))
    assert result.values["snap_tolerance"] == 0.25
    assert result.values["spline_step"] == 1.5
    assert result.values["coordinate_unit"] == "metri"
    assert result.values["coordinate_offset"] == (1688000.0, 4799500.0)
    assert result.values["polyline_end_tolerance"] == 0.3
    assert (7, "colore di sfondo") in result.unknown


def test_english_names(tmp_path):
    text = "snap tolerance = 0.1\nclosure tolerance = 0.4\nminimum dangle length = 2\n" \
           "min area = 3.5\ndecimals = 2\n"
    values = read_parameter_file(write(tmp_path, text)).values
    assert values == {"snap_tolerance": 0.1, "closure_tolerance": 0.4, "min_dangle_length": 2.0,
                      "min_area": 3.5, "decimals": 2}


@pytest.mark.parametrize("text, message", [
    ("tolleranza di chiusura = abc\n", "line 1: 'tolleranza di chiusura' must be a number >= 0, "
                                       "got 'abc'"),
    ("a = 1\ntolleranza di chiusura = -0.5\n", "line 2"),
    ("numero di cifre decimali = 2.5\n", "must be a whole number >= 0, got '2.5'"),
    ("traslazione delle coordinate = 5\n", "two numbers (east north)"),
    ("tolleranza di chiusura 0.5\n", "expected 'name = value'"),
    ("area minima = 1\nminimum area = 2\n", "given twice (first on line 1)"),
])
def test_bad_entries_name_file_line_and_entry(tmp_path, text, message):
    path = write(tmp_path, text)
    with pytest.raises(InputDataError) as err:
        read_parameter_file(path)
    assert message in str(err.value) and str(path) in str(err.value)


def test_missing_file(tmp_path):
    with pytest.raises(InputDataError, match="PARAMETERS: cannot read"):
        read_parameter_file(tmp_path / "nope.txt")


def test_names_normalised():
    assert normalise_name("  Unità  di_misura   delle COORDINATE (m) ") == \
        "unita di misura delle coordinate"
    assert all(len(aliases) >= 2 for _, aliases in KEYS.values())


def test_explicit_beats_file_beats_default(tmp_path):
    file = read_parameter_file(write(tmp_path, "tolleranza di riattacco planimetrico = 0.3\n"
                                               "numero di cifre decimali = 2\narea minima = 4\n"))
    tol, sources = resolve_tolerances({"SNAP_TOLERANCE": None, "MIN_AREA": 2.0}, file)
    assert tol == Tolerances(snap=0.3, closure=0.5, min_dangle=1.0, min_area=2.0,
                             precision=0.01)
    assert sources == {"snap": "file", "closure": "default", "min_dangle": "default",
                       "min_area": "parameter", "precision": "file"}
    tol, sources = resolve_tolerances({})
    assert tol == Tolerances() and set(sources.values()) == {"default"}


def test_precision_coarser_than_snap_refused():
    with pytest.raises(ParameterError, match="PRECISION .* must not be coarser than the snap"):
        resolve_tolerances({"SNAP_TOLERANCE": 0.05, "PRECISION": 0.1})
    tol, _ = resolve_tolerances({"SNAP_TOLERANCE": 0.0, "PRECISION": 0.1})
    assert tol.precision == 0.1
