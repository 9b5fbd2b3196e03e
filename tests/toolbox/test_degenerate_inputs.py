"""Degenerate inputs that crashed (exit 3) in issue 24 §3: each is now a one-line exit-2 message
naming the feature, line or record, or (forward intersection) a flagged point."""

from __future__ import annotations

import random
import warnings

import geopandas as gpd
import numpy as np
import pytest
from shapely.geometry import LineString, Polygon

from tests.helpers_cli import cli, one_error
from toolbox.errors import InputDataError

E0, N0 = 1688000.0, 4799000.0
CRS = "EPSG:3003"




def test_sample_zero_length_building_names_the_feature(tmp_path):
    point = (E0, N0)
    good = Polygon([(E0 + 50, N0), (E0 + 60, N0), (E0 + 60, N0 + 10), (E0 + 50, N0 + 10)])
    gpd.GeoDataFrame({"id": [1, 2]}, geometry=[good, Polygon([point] * 4)], crs=CRS) \
        .to_file(tmp_path / "b.gpkg")
    for method in ("vectors", "distance", "densify"):
        code, _, err = cli("run", "attribution:sample", "--INPUT", tmp_path / "b.gpkg",
                           "--METHOD", method, "--OUTPUT", tmp_path / "s.gpkg")
        line = one_error(err)
        assert code == 2 and "feature 2" in line and "zero length" in line
        assert not (tmp_path / "s.gpkg").exists()


def test_sample_that_would_collapse_a_ring_leaves_it_unchanged(tmp_path):
    small = Polygon([(E0, N0), (E0 + 1, N0), (E0 + 1, N0 + 1), (E0, N0 + 1)])
    gpd.GeoDataFrame({"id": [1]}, geometry=[small], crs=CRS).to_file(tmp_path / "b.gpkg")
    code, out, err = cli("run", "attribution:sample", "--INPUT", tmp_path / "b.gpkg",
                         "--METHOD", "distance", "--DISTANCE", 5, "--OUTPUT",
                         tmp_path / "s.gpkg")
    assert code == 0, err
    assert "fewer than 3 vertices" in err
    written = gpd.read_file(tmp_path / "s.gpkg", layer=None)
    assert written.geometry.iloc[0].equals(small)


def test_profile_zero_length_line_names_the_line(tmp_path):
    from rasterio.transform import from_origin

    from toolbox.raster.writer import write_raster

    write_raster(tmp_path / "dem.tif", np.full((20, 20), 100.0, "float32"),
                 from_origin(E0 - 100, N0 + 100, 10, 10), CRS, nodata=-9999.0)
    lines = [LineString([(E0 - 50, N0), (E0 + 50, N0)]), LineString([(E0, N0), (E0, N0)])]
    gpd.GeoDataFrame({"id": [1, 2]}, geometry=lines, crs=CRS).to_file(tmp_path / "l.gpkg")
    for mode in ("step", "sections"):
        code, _, err = cli("run", "carto:profile", "--INPUT", tmp_path / "l.gpkg", "--DEM",
                           tmp_path / "dem.tif", "--MODE", mode, "--OUTPUT",
                           tmp_path / "p.gpkg")
        line = one_error(err)
        assert code == 2 and "line 2" in line and "zero length" in line


def test_intersection_with_a_singular_normal_matrix_is_a_flagged_point():
    """The case a fuzz found (numpy raised 'Singular matrix' in the Gauss-Newton step), exactly
    parallel rays from two centres, and a good point in the same call: the good one is solved
    (two vertical photos 500 m apart, truth known), the others flagged parallel_rays."""
    from toolbox.photogrammetry.forward_intersection import PARALLEL_RAYS, intersect

    rot = np.stack([np.eye(3)] * 6)
    c1 = np.array([E0, N0, 1500.0])
    bad = c1 + [0.0004463745281100273, -0.0005369530990719795, 0.000581118104264533]
    truth = np.array([E0 + 250.0, N0 + 40.0, 300.0])
    c3, c4 = c1, c1 + [500.0, 0.0, 0.0]
    xy = [-150.0 * (truth[:2] - c[:2]) / (truth[2] - c[2]) for c in (c3, c4)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        result = intersect(np.array([0, 0, 1, 1, 2, 2]),
                           np.array([[-1e-08, 150.0], [0.001, 0.0], [0.0, 0.0], [0.0, 0.0],
                                     *xy]),
                           np.array([c1, bad, c1, c1 + [100.0, 0, 0], c3, c4]), rot,
                           np.array([1.5e-7, 1.5e-7, 150.0, 150.0, 150.0, 150.0]))
    assert result.status[0] != 0 and result.status[1] == PARALLEL_RAYS and result.status[2] == 0
    assert np.allclose(result.xyz[2], truth, atol=1e-6)
    with warnings.catch_warnings():  # alone, the singular case is refused in the same way
        warnings.simplefilter("ignore", RuntimeWarning)
        alone = intersect(np.array([0, 0]), np.array([[-1e-08, 150.0], [0.001, 0.0]]),
                          np.array([c1, bad]), rot[:2], np.array([1.5e-7, 1.5e-7]))
    assert alone.status[0] == PARALLEL_RAYS and not alone.ok.any()


def _dxf(tmp_path):
    import ezdxf

    doc = ezdxf.new()
    msp = doc.modelspace()
    msp.add_line((E0, N0, 10), (E0 + 10, N0 + 10, 12), dxfattribs={"layer": "STR02001"})
    msp.add_point((E0 + 5, N0 + 5, 11), dxfattribs={"layer": "QUO01001"})
    path = tmp_path / "ok.dxf"
    doc.saveas(path)
    return path.read_text().splitlines()


def test_dxf_malformed_group_codes_values_and_infinities(tmp_path):
    from toolbox.attribution.restitution import read_dxf

    lines = _dxf(tmp_path)
    at = lines.index("AcDbLine") + 1  # the group code " 10" of the line's start x

    def variant(name, change):
        mutated = list(lines)
        change(mutated)
        path = tmp_path / name
        path.write_text("\n".join(mutated) + "\n")
        return path

    cases = {
        "code.dxf": (lambda m: m.__setitem__(at, "abc"), "group code"),
        "float.dxf": (lambda m: m.__setitem__(at + 1, "12x.5"), "floating point"),
        "inf.dxf": (lambda m: m.__setitem__(at + 1, "1e999"), "not a finite number"),
        "nan.dxf": (lambda m: m.__setitem__(at + 3, "nan"), "not a finite number"),
        "cut.dxf": (lambda m: m.__delitem__(slice(at + 1, None)), "ENDSEC"),
    }
    for name, (change, words) in cases.items():
        with pytest.raises(InputDataError, match=words) as info:
            read_dxf(variant(name, change), crs=CRS)
        assert name in str(info.value) and "\n" not in str(info.value)
    assert "LINE handle" in str(pytest.raises(InputDataError, read_dxf, tmp_path / "inf.dxf").value)
    # through the CLI: one line, exit 2
    codes = tmp_path / "codes.txt"
    codes.write_text("codice;descrizione;tipologia;colore\nSTR02001;strada;polilinea;3\n"
                     "QUO01001;quota;punto;5\n")
    code, _, err = cli("run", "attribution:apply", "--INPUT", tmp_path / "inf.dxf", "--CODES",
                       codes, "--CRS", CRS, "--OUTPUT", tmp_path / "o.gpkg")
    assert code == 2 and "inf.dxf" in one_error(err)


def test_dxf_mutations_never_crash(tmp_path):
    """300 random line edits (values, deletions, truncations, insertions): read or refused."""
    from toolbox.attribution.restitution import read_dxf

    lines = _dxf(tmp_path)
    rng = random.Random(3)
    values = ["abc", "", "1e999", "-1e999", "nan", "99999999999999999999999", "-1", "1.5",
              "x" * 300]
    path = tmp_path / "m.dxf"
    for _ in range(300):
        mutated = list(lines)
        for _ in range(rng.randint(1, 3)):
            k = rng.randrange(len(mutated))
            op = rng.random()
            if op < 0.5:
                mutated[k] = rng.choice(values)
            elif op < 0.7:
                del mutated[k]
            elif op < 0.85:
                mutated = mutated[:k]
            else:
                mutated.insert(k, rng.choice(values))
        path.write_text("\n".join(mutated) + "\n")
        try:
            frame, _ = read_dxf(path, crs=CRS)
        except InputDataError:
            continue
        coords = np.concatenate([np.asarray(g.coords) for g in frame.geometry if g is not None]
                                or [np.zeros((0, 3))])
        assert np.isfinite(coords).all()


def test_two_tables_huge_record_number_names_the_line(tmp_path):
    from toolbox.attribution.restitution import read_two_tables

    (tmp_path / "c.txt").write_text("colour;E;N;Z\n1;1688000;4799000;10\n1;1688010;4799010;11\n")
    (tmp_path / "d.txt").write_text(
        "record;code;vertices;colour;source;xmin;ymin;xmax;ymax;first\n"
        "1;STR;2;3;m;1688000;4799000;1688010;4799010;1\n"
        "99999999999999999999999;STR;2;3;m;1688000;4799000;1688010;4799010;1\n")
    with pytest.raises(InputDataError, match=r"d\.txt' line 3: record 9+ is too large"):
        read_two_tables(tmp_path / "d.txt", tmp_path / "c.txt", crs=CRS)


def test_native_eo_csv_short_row_names_the_line():
    from toolbox.photogrammetry.readers.text import read_native_csv

    text = ("photo,x0,y0,z0,omega,phi,kappa,angle_unit\n"
            "p1,1688000,4799000,1500,0,0,0,rad\n"
            "p2,1688500,4799000\n")
    with pytest.raises(InputDataError, match="eo.csv line 3: 3 fields, expected at least 7"):
        read_native_csv(text, "eo.csv")
    # an optional trailing column may be left out
    table = read_native_csv("photo,x0,y0,z0,omega,phi,kappa,note\np1,1,2,3,0,0,0\n", "eo.csv",
                            "rad")
    assert list(table.orientations) == ["p1"]


def test_crashes_the_sweep_found_are_one_line_errors(tmp_path, plane_dem):
    """Found by the hypothesis sweep of the error contract (slow tier): an integer beyond 64
    bits (OverflowError in numpy), a raster whose header opens but whose blocks are cut
    (rasterio's 'Read failed' during validation), an input name too long for the system
    (OSError from Path.exists)."""
    import toolbox
    from toolbox.errors import InputDataError, ParameterError
    from toolbox.io.raster import has_valid_pixel
    from toolbox.parameters import Integer, ValidationContext

    with pytest.raises(ParameterError, match=r"INDEX_EVERY is too large for an integer .*'1e30'"):
        Integer("INDEX_EVERY").validate("1e30", ValidationContext())
    assert Integer("N").validate(str(2 ** 62), ValidationContext()) == 2 ** 62

    path, _, _ = plane_dem
    import rasterio

    with rasterio.open(path) as src:  # the DEM's grid, tiled and uncompressed, cut in half:
        profile, data = src.profile, src.read()  # nodata but the last cell, which is lost
    data[:] = profile["nodata"]
    data[0, -1, -1] = 300.0
    profile.update(tiled=True, blockxsize=16, blockysize=16, compress=None)
    whole = tmp_path / "whole.tif"
    with rasterio.open(whole, "w", **profile) as dst:
        dst.write(data)
    cut = tmp_path / "cut.tif"
    cut.write_bytes(whole.read_bytes()[: whole.stat().st_size // 2])
    with pytest.raises(InputDataError, match="cut.tif': the file is truncated or corrupt"):
        has_valid_pixel(cut)

    with pytest.raises(ParameterError, match="INPUT cannot use 'aaa.*File name too long"):
        toolbox.run("orientation:convert", {"INPUT": "a" * 5000, "FORMAT_OUT": "orthority",
                                            "OUTPUT": tmp_path / "c.geojson"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.tif", "plane.tif", "whole.tif"]
