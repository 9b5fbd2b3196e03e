"""An ODM ``gcp_list.txt`` whose CRS line is the ESRI WKT of the CRS parameter's EPSG:6707
(round 22, crsdef). Before: its coordinates went through a pyproj transformation that moves
nothing, with the notes "transformation: Inverse of UTM zone 32N + UTM zone 32N ..." and
"ground coordinates RDN2008 / UTM zone 32N (N-E) -> RDN2008 / UTM zone 32N (N-E)". Now one CRS
(``toolbox.io.crs.one_crs`` on the points' extent): read as they are. ED50 / UTM 32N is still
transformed, as gdaltransform does."""

from __future__ import annotations

import pytest

from tests.toolbox.crs_cases import ESRI_6707
from toolbox.exchange import odm_gcp

ROWS = ("680123.456 4800456.789 210.5 100 200 IMG1.jpg g1\n"
        "680987.123 4800111.222 215.25 300 400 IMG2.jpg g2\n")


def _read(folder, head):
    path = folder / "gcp_list.txt"
    path.write_text(f"{head}\n{ROWS}")
    return odm_gcp.read_gcp_list(path, "EPSG:6707")


def test_gcp_list_in_the_esri_wkt_of_the_crs_is_read_as_it_is(tmp_path):
    esri = _read(tmp_path, ESRI_6707)
    epsg = _read(tmp_path, "EPSG:6707")
    assert esri.points == epsg.points == {"g1": (680123.456, 4800456.789, 210.5),
                                          "g2": (680987.123, 4800111.222, 215.25)}
    assert esri.notes == epsg.notes and esri.warnings == epsg.warnings == [], esri.notes
    # echo "680123.456 4800456.789 210.5" | gdaltransform -s_srs EPSG:23032 -t_srs EPSG:6707
    # (GDAL 3.6.2): 680040.811031893 4800260.68295641 210.5
    ed50 = _read(tmp_path, "EPSG:23032")
    assert ed50.points["g1"] == pytest.approx((680040.811031893, 4800260.68295641, 210.5),
                                              abs=1e-6)
    assert any(n.startswith("ground coordinates ED50 / UTM zone 32N ->") for n in ed50.notes)
