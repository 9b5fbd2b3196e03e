"""An orientation CSV's ``.prj`` against the CRS parameter: one CRS when the positions' centroid
moves by at most 1 mm from one to the other (the CONTROL tables' rule, now in
``toolbox.io.crs``), not when the two definitions are equal: an ESRI ``.prj`` as GDAL writes it
(``gdalsrsinfo --single-line -o wkt_esri EPSG:n``, GDAL 3.6.2) of the CRS given is accepted; an
ED50 ``.prj`` with CRS EPSG:32632 is refused naming both and the shift, the shift checked
against ``gdaltransform``."""

from __future__ import annotations

import math

import pytest
from helpers_cli import cli, one_error

from toolbox.errors import InputDataError, ParameterError
from toolbox.exchange import csvtable

_TM = ('PROJECTION["Transverse_Mercator"],PARAMETER["False_Easting",{fe}],'
       'PARAMETER["False_Northing",0.0],PARAMETER["Central_Meridian",9.0],'
       'PARAMETER["Scale_Factor",0.9996],PARAMETER["Latitude_Of_Origin",0.0],UNIT["Meter",1.0]]')
_GEOGCS = ('GEOGCS["{gcs}",DATUM["{datum}",SPHEROID["{ellps}",{a},{rf}]],'
           'PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],')
ESRI = {  # gdalsrsinfo --single-line -o wkt_esri EPSG:n (GDAL 3.6.2)
    3003: 'PROJCS["Monte_Mario_Italy_1",' + _GEOGCS.format(
        gcs="GCS_Monte_Mario", datum="D_Monte_Mario", ellps="International_1924",
        a="6378388.0", rf="297.0") + _TM.format(fe="1500000.0"),
    32632: 'PROJCS["WGS_1984_UTM_Zone_32N",' + _GEOGCS.format(
        gcs="GCS_WGS_1984", datum="D_WGS_1984", ellps="WGS_1984", a="6378137.0",
        rf="298.257223563") + _TM.format(fe="500000.0"),
    6707: 'PROJCS["RDN2008_TM32",' + _GEOGCS.format(
        gcs="GCS_RDN2008", datum="D_Rete_Dinamica_Nazionale_2008", ellps="GRS_1980",
        a="6378137.0", rf="298.257222101") + _TM.format(fe="500000.0"),
    23032: 'PROJCS["ED_1950_UTM_Zone_32N",' + _GEOGCS.format(
        gcs="GCS_European_1950", datum="D_European_1950", ellps="International_1924",
        a="6378388.0", rf="297.0") + _TM.format(fe="500000.0"),
}
ROWS = "filename,x,y,z,omega,phi,kappa\nIMG1,{x0},4800000.0,1200,0.5,-0.3,90\n" \
       "IMG2,{x1},4800100.0,1210,0.2,0.1,91\n"


def _table(folder, code: int, prj: str | bytes | None = None):
    x0 = 1680000.0 if code == 3003 else 680000.0
    path = folder / "o.csv"
    path.write_text(ROWS.format(x0=x0, x1=x0 + 1000.0))
    text = ESRI[code] if prj is None else prj
    (folder / "o.prj").write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


@pytest.mark.parametrize("code", [3003, 32632, 6707])
def test_esri_prj_of_the_given_crs_is_accepted(tmp_path, code):
    """Before: EPSG:6707 with its ESRI .prj was refused ("CRS contradicts o.prj", exit 2): the
    two definitions differ (axis order) though they are one CRS."""
    from pyproj import CRS

    path = _table(tmp_path, code)
    before = path.read_bytes(), (tmp_path / "o.prj").read_bytes()
    oset = csvtable.read_csv(path, crs=f"EPSG:{code}")
    assert oset.crs == CRS.from_epsg(code)  # the CRS as given
    assert oset.photos["IMG1"].xyz == (1680000.0 if code == 3003 else 680000.0, 4800000.0,
                                       1200.0)
    assert any("o.prj" in n and "the same" in n for n in oset.notes), oset.notes
    assert (path.read_bytes(), (tmp_path / "o.prj").read_bytes()) == before
    out = tmp_path / "out.csv"
    code_, _, err = cli("run", "orientation:convert", "--INPUT", path, "--CRS", f"EPSG:{code}",
                        "--FORMAT_OUT", "csv", "--OUTPUT", out)
    assert code_ == 0, err
    assert out.exists()


def test_ed50_prj_with_wgs84_utm_crs_is_refused_naming_both_and_the_shift(tmp_path):
    """The centroid (680500, 4800050) in ED50 / UTM 32N goes to 680417.34931042
    4799853.89351424 in EPSG:32632 by ``gdaltransform -s_srs <the ESRI .prj> -t_srs
    EPSG:32632`` (GDAL 3.6.2): 212.812 m on the grid (the scale factor there is 1.0000)."""
    path = _table(tmp_path, 23032)
    expected = math.hypot(680500 - 680417.34931042, 4800050 - 4799853.89351424)
    with pytest.raises(ParameterError) as info:
        csvtable.read_csv(path, crs="EPSG:32632")
    message = str(info.value)
    assert message.startswith("CRS EPSG:32632 contradicts o.prj (EPSG:23032)"), message
    shift = float(message.split("move by ")[1].split(" m")[0])
    assert shift == pytest.approx(expected, abs=0.01)
    assert "680500.000, 4800050.000" in message
    code, out, err = cli("run", "orientation:convert", "--INPUT", path, "--CRS", "EPSG:32632",
                         "--FORMAT_OUT", "csv", "--OUTPUT", tmp_path / "out.csv")
    assert code == 2
    assert "EPSG:23032" in one_error(err) and f"{shift:.3f} m" in one_error(err)
    assert not (tmp_path / "out.csv").exists()


def test_different_height_datums_are_named_both(tmp_path):
    """The same horizontal CRS with two height datums: refused naming both datums (before:
    "contradicts o.prj (WGS 84 / UTM zone 32N + EGM96 height)", the parameter's left
    unnamed)."""
    path = _table(tmp_path, 32632, prj="EPSG:32632+5773")
    with pytest.raises(InputDataError, match="heights") as info:
        csvtable.read_csv(path, crs="EPSG:32632+3855")
    assert "EGM96" in str(info.value) and "EGM2008" in str(info.value)


def test_prj_in_windows_1252_is_read_and_a_bad_one_is_an_input_error(tmp_path):
    """A .prj with a Windows-1252 byte (an accented name, as ESRI software writes it): read
    (before: UnicodeDecodeError, "internal error", exit 3); one PROJ cannot read: a one-line
    input error naming the file, exit 2."""
    esri = ESRI[32632].replace("WGS_1984_UTM_Zone_32N", "UTM_32N_Citt\xe0").encode("cp1252")
    path = _table(tmp_path, 32632, prj=esri)
    oset = csvtable.read_csv(path)
    assert oset.crs.name == "UTM_32N_Citt\xe0" and oset.crs.to_epsg() == 32632
    code, _, err = cli("run", "orientation:convert", "--INPUT", path, "--FORMAT_OUT", "csv",
                       "--OUTPUT", tmp_path / "out.csv")
    assert code == 0, err
    (tmp_path / "o.prj").write_text("not a CRS")
    with pytest.raises(InputDataError, match="o.prj: 'not a CRS' is not a CRS PROJ knows"):
        csvtable.read_csv(path)


def test_centroid_shift_lives_in_the_crs_module():
    """Not photogrammetry-specific: ``toolbox.io.crs`` holds it and its tolerance; ESRI 6707
    against EPSG:6707 moves nothing, ED50 against WGS 84 by gdaltransform's 212.812 m."""
    from pyproj import CRS

    from toolbox.io.crs import PRJ_TOLERANCE_M, centroid_shift

    assert PRJ_TOLERANCE_M == 1e-3
    xy = [[680000.0, 4800000.0], [681000.0, 4800100.0]]
    shift, centre = centroid_shift(CRS.from_wkt(ESRI[6707]), "EPSG:6707", xy)
    assert shift <= 1e-6 and centre == (680500.0, 4800050.0)
    shift, _ = centroid_shift(CRS.from_wkt(ESRI[23032]), "EPSG:32632", xy)
    assert shift == pytest.approx(math.hypot(82.65068958, 196.10648576), abs=0.01)
