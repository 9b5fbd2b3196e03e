"""Round 15, sweep_text: text as Italian offices' files carry it (Windows-1252, BOM, CRLF,
';' separator, decimal comma, thousands dots)."""

from __future__ import annotations

import numpy as np
import pytest

from toolbox.errors import ParameterError
from toolbox.io.vector import open_layer, read_vector


def _csv(tmp_path, name: str, data: bytes):
    path = tmp_path / name
    path.write_bytes(data)
    return path


def test_csv_decimal_comma_semicolon_read_as_written(tmp_path):
    path = _csv(tmp_path, "pts.csv", b"\xef\xbb\xbfX;Y;Z\r\n1234,5;5000,25;300,75\r\n"
                b"1240;5010,5;310\r\n")
    xyz = np.array([(g.x, g.y, g.z) for g in read_vector(path).geometry])
    np.testing.assert_allclose(xyz, [[1234.5, 5000.25, 300.75], [1240, 5010.5, 310]])


def test_csv_windows_1252_accents_read(tmp_path):
    # 'Località' / 'città' / 'perché' in Windows-1252: pyogrio failed ('utf-8' codec, exit 2)
    path = _csv(tmp_path, "pts.csv", b"X;Y;Z;Localit\xe0\r\n1000;5000;100;citt\xe0\r\n"
                b"1010;5000;110;perch\xe9\r\n")
    frame = read_vector(path)
    assert list(frame["Località"]) == ["città", "perché"]
    assert [g.x for g in frame.geometry] == [1000, 1010]


@pytest.mark.parametrize("cell", [b"1.000,5", b"1.681.000"])
def test_csv_thousands_separator_refused(tmp_path, cell):
    # GDAL reads '1.000,5' as no X: the row's point was dropped in silence (exit 0)
    path = _csv(tmp_path, "pts.csv", b"X;Y;Z\r\n" + cell + b";5000;100\r\n1010;5000;110\r\n"
                b"1000;5010;120\r\n")
    with pytest.raises(ParameterError, match=r"line 2: column X holds '" + cell.decode()):
        open_layer(str(path))


def test_csv_thousands_dot_beside_decimal_comma_refused(tmp_path):
    # '1.010' in a file of decimal commas was read as 1.01 (a thousands dot: 1010)
    path = _csv(tmp_path, "pts.csv", b"X;Y;Z\n1000,5;5000;100\n1.010;5000;110\n1000;5010;120\n")
    with pytest.raises(ParameterError, match=r"line 3: column X holds '1.010'.*line 2"):
        open_layer(str(path))


def test_csv_empty_x_refused(tmp_path):
    # a row with an empty X had no point and was dropped in silence
    path = _csv(tmp_path, "pts.csv", b"X,Y,Z\n1000,5000,100\n,5000,110\n1000,5010,120\n")
    with pytest.raises(ParameterError, match=r"line 3: column X is empty"):
        open_layer(str(path))


def test_orthority_csv_semicolon_decimal_comma_windows_1252(tmp_path):
    # orientation:convert refused both: 'utf-8' codec can't decode / 'expected numbers' (exit 2)
    from toolbox.exchange.csvtable import read_csv

    path = _csv(tmp_path, "opk.csv", b"filename;x;y;z;omega;phi;kappa\r\n"
                b"foto_citt\xe0_001.tif;1681000,5;4812000,25;1500,0;0,5;-0,25;90,0\r\n")
    oset = read_csv(path, crs="EPSG:3003")
    (photo,) = oset.photos.values()
    assert photo.id == "foto_città_001"
    np.testing.assert_allclose(photo.xyz, [1681000.5, 4812000.25, 1500.0])
    np.testing.assert_allclose(np.degrees(photo.opk), [0.5, -0.25, 90.0])


def test_orthority_csv_thousands_dot_refused(tmp_path):
    from toolbox.errors import InputDataError
    from toolbox.exchange.csvtable import read_csv

    path = _csv(tmp_path, "opk.csv", b"filename;x;y;z;omega;phi;kappa\n"
                b"f1.tif;1.681.000,5;4812000;1500;0;0;90\n")
    with pytest.raises(InputDataError, match="expected numbers"):
        read_csv(path, crs="EPSG:3003")


def test_restitution_ascii_decimal_comma(tmp_path):
    # '1688230,5 4799620' was read as E 1688230, N 5, Z 4799620 (exit 0); a ';'/space-separated
    # line's comma is its decimal comma
    from toolbox.attribution.restitution import read_ascii

    path = _csv(tmp_path, "r.txt", b"CODE FAB01002 12\r\n1688230,5 4799620 331,2\r\n"
                b"1688250;4799620,25;331\r\nEND\r\n")
    (geom,) = read_ascii(path).geometry
    assert list(geom.coords) == [(1688230.5, 4799620.0, 331.2), (1688250.0, 4799620.25, 331.0)]
    bad = _csv(tmp_path, "r3.txt", b"CODE P1\r\n1688230,5 4799620\r\nEND\r\n")
    with pytest.raises(Exception, match="line 2: expected 'E N Z'"):
        read_ascii(bad)


def test_restitution_two_tables_decimal_comma(tmp_path):
    # the first record's Z '300,5' made it a header line, dropped: every vertex shifted by one
    from toolbox.attribution.restitution import read_two_tables

    coords = _csv(tmp_path, "co.txt", b"1;1688230,5;4799620,25;300,5\n1;1688240;4799620;301\n"
                  b"1;1688250;4799630;302\n")
    desc = _csv(tmp_path, "de.txt", b"1;FAB01002;3;12;S;1688230;4799620;1688250;4799630;1\n")
    frame, _ = read_two_tables(desc, coords)
    (geom,) = frame.geometry
    assert list(geom.coords) == [(1688230.5, 4799620.25, 300.5), (1688240, 4799620, 301),
                                 (1688250, 4799630, 302)]


def test_read_text_windows_1252_apostrophe(tmp_path):
    # 'dell’edificio' saved by Word/Excel in Windows-1252 was decoded as Latin-1: U+0092 (a
    # control character) in the code descriptions, layer names and labels written from it
    from toolbox.io.text import read_text

    path = _csv(tmp_path, "codes.txt", b"FAB01002;muro dell\x92edificio \x96 citt\xe0 \x80\n")
    assert read_text(path) == "FAB01002;muro dell’edificio – città €\n"
    odd = _csv(tmp_path, "odd.txt", b"citt\xe0 \x81\n")  # undefined in cp1252: Latin-1 still
    assert read_text(odd) == "città \x81\n"
