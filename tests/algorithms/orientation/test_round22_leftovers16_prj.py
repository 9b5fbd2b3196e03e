"""One reader for every table's ``.prj`` (:func:`toolbox.io.crs.read_prj`). The CONTROL tables'
reader decoded it as UTF-8 with replacement characters: GDAL's ESRI ``.prj`` of EPSG:3003 with
its name edited to "Monte_Mario_Città" and saved in Windows-1252 (as ESRI software writes it)
came out as "Monte_Mario_Citt\ufffd" in the output GeoPackage's CRS and in the errors naming it;
orientation:bundle's own reader (UTF-8, errors ignored) dropped such a ``.prj`` altogether, so
an ED50 one beside CONTROL under a PROJECT in EPSG:32632 was accepted (213 m off, exit 0). A
``.prj`` PROJ cannot read is one message wherever it sits: the parameter, the file, its text
and what was expected (exit 2)."""

from __future__ import annotations

import pyogrio
import pytest
from pyproj import CRS
from test_round20_leftovers12_control_prj import gdal_prj, tables

import toolbox
from tests.helpers_cli import cli, one_error
from toolbox.errors import InputDataError
from toolbox.exchange import csvtable

NAME = "Monte_Mario_Citt\u00e0"


def _accented(prj, name: str = NAME, false_easting: str | None = None) -> bytes:
    """GDAL's ESRI ``.prj`` (``prj``) with its CRS renamed ``name`` (and its false easting
    moved, so that no EPSG code matches and the name is kept), in Windows-1252."""
    text = prj.read_text()
    old = text.split('"')[1]
    text = text.replace(old, name, 1)
    if false_easting is not None:
        text = text.replace('"False_Easting",1500000.0', f'"False_Easting",{false_easting}')
        assert false_easting in text
    data = text.encode("cp1252")
    assert b"\xe0" in data and "\u00e0".encode() not in data  # one byte, not UTF-8's two
    return data


def test_a_windows_1252_prj_beside_control_is_read_not_garbled(tmp_path):
    model, control, _ = tables(tmp_path, 3003, None)
    prj = control.with_suffix(".prj")
    prj.write_bytes(_accented(gdal_prj(tmp_path, 3003), false_easting="1500000.5"))
    before = prj.read_bytes()
    toolbox.run("orientation:absolute", {"INPUT": model, "CONTROL": control,
                                         "OUTPUT": tmp_path / "o.gpkg",
                                         "REPORT": tmp_path / "r.json"})
    written = CRS.from_user_input(pyogrio.read_info(tmp_path / "o.gpkg")["crs"])
    assert written.name == NAME, written.name  # before: 'Monte_Mario_Citt\ufffd'
    assert {p.name: p.value for p in written.coordinate_operation.params}["False easting"] \
        == 1500000.5
    # the same file in a refusal: its name as written
    code, _, err = cli("run", "orientation:absolute", "--INPUT", model, "--CONTROL", control,
                       "--CRS", "EPSG:23032", "--REPORT", tmp_path / "r2.json")
    line = one_error(err)
    assert code == 2 and NAME in line and "\ufffd" not in line, line
    assert prj.read_bytes() == before


def test_bundle_reads_a_windows_1252_prj_beside_control(tmp_path):
    """An ED50 ``.prj`` in Windows-1252 beside CONTROL, PROJECT in EPSG:32632: refused as the
    same ``.prj`` in UTF-8 is (before: passed, the ``.prj`` silently ignored)."""
    from toolbox.errors import ParameterError
    from toolbox.registry import get

    _, control, ground = tables(tmp_path, 32632, 23032)
    prj = control.with_suffix(".prj")
    prj.write_bytes(_accented(prj, "ED_1950_UTM_32N_Citt\u00e0"))
    bundle = get("orientation:bundle")()
    with pytest.raises(ParameterError, match="CONTROL is in ED_1950_UTM_32N_Citt\u00e0 but "
                                             "PROJECT is in EPSG:32632"):
        bundle._check_crs("CONTROL", control, "EPSG:32632", ground[:, :2], toolbox.Feedback())


def test_a_bad_prj_is_one_message_everywhere(tmp_path):
    """CONTROL of orientation:absolute, orientation:bundle's CONTROL and an orientation CSV:
    the same sentence. Before: "CONTROL: .../control.prj is not a CRS PROJ knows (CONTROL's
    control.prj 'not a CRS' is not a CRS PROJ knows (expected e.g. EPSG:3003, WKT or a PROJ
    string)...)", "CONTROL 'not a CRS' is not a CRS PROJ knows (expected e.g. EPSG:3003...)"
    (the file unnamed) and ".../o.prj 'not a CRS' is not a CRS PROJ knows (...)"."""
    from toolbox.registry import get

    model, control, ground = tables(tmp_path, 32632, None)
    prj = control.with_suffix(".prj")
    prj.write_text("not a CRS")
    expected = (f"{prj}: 'not a CRS' is not a CRS PROJ knows (expected the table's CRS as "
                "WKT, ESRI WKT, a PROJ string or an EPSG code)")
    code, _, err = cli("run", "orientation:absolute", "--INPUT", model, "--CONTROL", control,
                       "--CRS", "EPSG:32632", "--REPORT", tmp_path / "r.json")
    line = one_error(err)
    assert code == 2 and line.startswith(f"toolbox: error: CONTROL: {expected}"), line
    assert not (tmp_path / "r.json").exists()
    with pytest.raises(InputDataError) as info:
        get("orientation:bundle")()._check_crs("CONTROL", control, "EPSG:32632", ground[:, :2],
                                               toolbox.Feedback())
    assert str(info.value).startswith(f"CONTROL: {expected}"), info.value
    orientations = tmp_path / "o.csv"
    orientations.write_text("filename,x,y,z,omega,phi,kappa\nIMG1,688000,4799500,1200,0,0,0\n")
    (tmp_path / "o.prj").write_text("not a CRS")
    with pytest.raises(InputDataError) as info:
        csvtable.read_csv(orientations)
    assert str(info.value).startswith(expected.replace("control.prj", "o.prj")), info.value
