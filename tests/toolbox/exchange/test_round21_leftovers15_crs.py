"""Two more places that took one CRS with two definitions for two CRSs: an Orthority exterior
GeoJSON's ``world_crs`` against the CRS parameter, and the inputs merged by
orientation:convert against each other. Both now use the ``.prj`` rule
(``toolbox.io.crs.check_one_crs``): one CRS when the positions' centroid moves by at most 1 mm
from one to the other; else an error naming both CRSs and the shift. The ESRI WKT is GDAL's
(``gdalsrsinfo --single-line -o wkt_esri EPSG:6707``, GDAL 3.6.2); the shifts are checked
against ``gdaltransform``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from helpers_cli import cli, one_error

from tests.toolbox.crs_cases import ESRI_6707
from toolbox.errors import InputDataError
from toolbox.exchange import formats, orthority

# echo "680500 4800050" | gdaltransform -s_srs <ESRI_6707> -t_srs EPSG:23032 -output_xy
# (GDAL 3.6.2): 680582.651850311 4800246.10910895; the scale factor there is 1.0000
ED50_SHIFT = math.hypot(680582.651850311 - 680500, 4800246.10910895 - 4800050)  # 212.815 m
ROWS = "filename,x,y,z,omega,phi,kappa\n{a},680000.0,4800000.0,1200,0.5,-0.3,90\n" \
       "{b},681000.0,4800100.0,1210,0.2,0.1,91\n"


def _csv(folder, stem, prj, names=("IMG1", "IMG2")):
    path = folder / f"{stem}.csv"
    path.write_text(ROWS.format(a=names[0], b=names[1]))
    (folder / f"{stem}.prj").write_text(prj)
    return path


def _geojson(folder, world_crs=ESRI_6707):
    features = [{"type": "Feature", "geometry": None,
                 "properties": {"filename": name, "camera": "c", "xyz": [x, y, z],
                                "opk": [0.01, -0.005, 1.57]}}
                for name, x, y, z in (("IMG1", 680000.0, 4800000.0, 1200.0),
                                      ("IMG2", 681000.0, 4800100.0, 1210.0))]
    path = folder / "ext.geojson"
    path.write_text(json.dumps({"type": "FeatureCollection", "world_crs": world_crs,
                                "features": features}))
    return path


def test_merged_csvs_with_esri_and_epsg_prj_of_one_crs_are_one_crs(tmp_path):
    """Before: "b.csv is in RDN2008 / UTM zone 32N (N-E), an earlier input in RDN2008 / UTM
    zone 32N (N-E): give inputs in one CRS", exit 2 (the two definitions differ, the CRS
    does not: pyproj moves no point from one to the other)."""
    from pyproj import CRS

    a = _csv(tmp_path, "a", ESRI_6707)
    b = _csv(tmp_path, "b", "EPSG:6707", names=("IMG3", "IMG4"))
    before = [p.read_bytes() for p in sorted(tmp_path.iterdir())]
    oset = formats.read_orientations([a, b])
    assert oset.crs.equals(CRS.from_wkt(ESRI_6707))  # the first input's, kept
    assert sorted(oset.photos) == ["IMG1", "IMG2", "IMG3", "IMG4"]
    assert oset.photos["IMG3"].xyz == (680000.0, 4800000.0, 1200.0)
    assert any(n.startswith("b.csv: its CRS (EPSG:6707)") for n in oset.notes), oset.notes
    out = tmp_path / "out.csv"
    code, _, err = cli("run", "orientation:convert", "--INPUT", f"{a},{b}", "--FORMAT_OUT",
                       "csv", "--OUTPUT", out)
    assert code == 0, err
    assert len(out.read_text().splitlines()) == 5
    assert [p.read_bytes() for p in sorted(tmp_path.iterdir()) if p.stem != "out"] == before


def test_merged_csvs_in_two_datums_are_refused_naming_both_and_the_shift(tmp_path):
    """RDN2008 then ED50 / UTM 32N: refused naming both CRSs and gdaltransform's shift (before:
    the CRSs' names only, no shift)."""
    a = _csv(tmp_path, "a", "EPSG:23032")
    b = _csv(tmp_path, "b", ESRI_6707, names=("IMG3", "IMG4"))
    with pytest.raises(InputDataError) as info:
        formats.read_orientations([a, b])
    message = str(info.value)
    assert message.startswith("b.csv is in ") and "EPSG:23032" in message, message
    assert "(centroid 680500.000, 4800050.000)" in message
    shift = float(message.split("move by ")[1].split(" m")[0])
    assert shift == pytest.approx(ED50_SHIFT, abs=0.01)
    out = tmp_path / "out.csv"
    code, _, err = cli("run", "orientation:convert", "--INPUT", f"{a},{b}", "--FORMAT_OUT",
                       "csv", "--OUTPUT", out)
    assert code == 2 and f"{shift:.3f} m" in one_error(err)
    assert not out.exists()


def test_orthority_world_crs_as_esri_wkt_of_the_given_crs_is_accepted(tmp_path):
    """Before: "world_crs 'RDN2008 / UTM zone 32N (N-E)' contradicts the given CRS 'RDN2008 /
    UTM zone 32N (N-E)'", exit 2."""
    from pyproj import CRS

    path = _geojson(tmp_path)
    oset = orthority.read_exterior(path, crs="EPSG:6707")
    assert oset.crs == CRS.from_epsg(6707)  # the CRS as given
    assert oset.photos["IMG2"].xyz == (681000.0, 4800100.0, 1210.0)
    assert any("world_crs" in n and "the same" in n for n in oset.notes), oset.notes
    out = tmp_path / "out.csv"
    code, _, err = cli("run", "orientation:convert", "--INPUT", path, "--CRS", "EPSG:6707",
                       "--FORMAT_OUT", "csv", "--OUTPUT", out)
    assert code == 0, err
    assert CRS.from_user_input((tmp_path / "out.prj").read_text()).to_epsg() == 6707


def test_orthority_world_crs_in_another_datum_is_refused_naming_both_and_the_shift(tmp_path):
    path = _geojson(tmp_path)
    with pytest.raises(InputDataError) as info:
        orthority.read_exterior(path, crs="EPSG:23032")
    message = str(info.value)
    assert "world_crs is in " in message and "CRS is in EPSG:23032" in message, message
    shift = float(message.split("move by ")[1].split(" m")[0])
    assert shift == pytest.approx(ED50_SHIFT, abs=0.01)
    out = tmp_path / "out.csv"
    code, _, err = cli("run", "orientation:convert", "--INPUT", path, "--CRS", "EPSG:23032",
                       "--FORMAT_OUT", "csv", "--OUTPUT", out)
    assert code == 2 and f"{shift:.3f} m" in one_error(err)
    assert not out.exists()


def test_without_positions_the_definitions_are_compared():
    """No point to move: two CRSs are one only when their horizontal definitions are equal."""
    from toolbox.io.crs import check_one_crs

    none = np.empty((0, 2))
    assert check_one_crs("a", "EPSG:6707", "b", "EPSG:6707+5214", none) == 0.0
    with pytest.raises(InputDataError, match="a is in EPSG:23032 but b is in EPSG:6707"):
        check_one_crs("a", "EPSG:23032", "b", "EPSG:6707", none)
