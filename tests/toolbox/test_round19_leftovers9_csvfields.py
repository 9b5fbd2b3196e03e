"""A CSV point file's X/Y/Z columns are read as the geometry, not as fields: a bad ``Z_FIELD``
said "fields are: (none)" for a file whose header the user sees as ``x,y,z``; the message lists
the CSV's columns (header read independently with the csv module) and what they are read as."""

from __future__ import annotations

import csv

import pytest

from tests.helpers_cli import cli, one_error


@pytest.fixture
def xyz_csv(tmp_path):
    path = tmp_path / "pts.csv"
    path.write_text("x,y,z\n1500000,5000000,10\n1500010,5000000,11\n1500000,5000010,12\n"
                    "1500010,5000010,13\n1500005,5000005,14\n")
    return path


@pytest.mark.parametrize("alg, extra", [("dem:idw", ("--CELL_SIZE", "2")),
                                        ("tin:delaunay", ())])
def test_a_bad_z_field_of_an_xyz_csv_lists_its_columns(tmp_path, xyz_csv, alg, extra):
    header = next(csv.reader(xyz_csv.open()))
    out = tmp_path / ("o.tif" if alg.startswith("dem") else "o.gpkg")
    code, _, err = cli("run", alg, "--INPUT", xyz_csv, "--Z_FIELD", "h", *extra, "--OUTPUT", out)
    line = one_error(err)
    assert code == 2, err
    assert "(none)" not in line, line
    assert f"Z_FIELD field 'h' is not in '{xyz_csv}'; columns are: {', '.join(header)} " \
           "(x, y, z read as the points' X, Y, Z, not as fields; leave Z_FIELD out for the " \
           "heights of z)" in line, line
    assert not out.exists()


def test_other_columns_are_listed_beside_the_coordinates_and_a_gpkg_keeps_its_fields(tmp_path):
    path = tmp_path / "en.csv"
    path.write_text("E;N;quota_rilievo;code\n1500000;5000000;10,5;a\n1500010;5000000;11;b\n"
                    "1500000;5000010;12;c\n")
    code, _, err = cli("run", "dem:idw", "--INPUT", path, "--Z_FIELD", "height", "--CELL_SIZE",
                       "2", "--OUTPUT", tmp_path / "o.tif")
    line = one_error(err)
    assert code == 2 and "columns are: E, N, quota_rilievo, code (E, N read as the points' X, " \
                         "Y, not as fields)" in line, line

    # a layer of another format keeps its message (its fields only)
    import geopandas as gpd
    import shapely

    gpkg = tmp_path / "p.gpkg"
    gpd.GeoDataFrame({"a": [1.0, 2.0, 3.0]}, geometry=shapely.points(
        [[1500000, 5000000], [1500010, 5000000], [1500000, 5000010]]), crs=3003).to_file(gpkg)
    code, _, err = cli("run", "dem:idw", "--INPUT", gpkg, "--Z_FIELD", "h", "--CELL_SIZE", "2",
                       "--OUTPUT", tmp_path / "o.tif")
    assert code == 2 and one_error(err).endswith(f"Z_FIELD field 'h' is not in '{gpkg}'; "
                                                 "fields are: a"), err
