"""LAS/LAZ point clouds as input of the DEM gridding and the TIN: laspy writes files with known
points, classes and returns; gridding from them must equal gridding from the same points in a
GeoPackage; filters, CRS rules and the clear errors."""

from __future__ import annotations

from pathlib import Path

import geopandas as gpd
import laspy
import numpy as np
import pytest
import rasterio
import shapely
from click.testing import CliRunner

import toolbox
from toolbox.errors import InputDataError, ParameterError
from toolbox.io.pointcloud import (
    PointFilter,
    open_point_cloud,
    read_xyz,
    write_point_cloud,
)

X0, Y0 = 1_688_000.0, 4_799_500.0


def _cloud(n=3000, seed=4):
    """Points on a known surface with classes 2 (ground) / 5 (vegetation) / 6 (building) and
    returns: returns numbers 1..number_of_returns."""
    rng = np.random.default_rng(seed)
    x = X0 + rng.uniform(0, 200, n)
    y = Y0 + rng.uniform(0, 150, n)
    z = 300 + 0.05 * (x - X0) - 0.02 * (y - Y0)
    cls = rng.choice([2, 5, 6], n, p=[0.6, 0.25, 0.15]).astype(np.uint8)
    nret = rng.integers(1, 4, n)
    rnum = np.minimum(rng.integers(1, 4, n), nret)
    return np.column_stack([x, y, np.round(z, 3)]), cls, rnum, nret


def _write_las(path, xyz, cls, rnum, nret, crs="EPSG:3003"):
    """Independent of the toolbox's writer: laspy directly (LAS 1.4, format 6)."""
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.offsets = [X0, Y0, 0.0]
    header.scales = [0.001, 0.001, 0.001]
    if crs is not None:
        from pyproj import CRS

        header.add_crs(CRS.from_user_input(crs))
    las = laspy.LasData(header)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    las.classification = cls
    las.return_number = rnum
    las.number_of_returns = nret
    las.write(str(path))
    return path


@pytest.fixture
def cloud(tmp_path):
    xyz, cls, rnum, nret = _cloud()
    return {"xyz": xyz, "cls": cls, "rnum": rnum, "nret": nret,
            "laz": _write_las(tmp_path / "c.laz", xyz, cls, rnum, nret),
            "las": _write_las(tmp_path / "c.las", xyz, cls, rnum, nret),
            "nocrs": _write_las(tmp_path / "nocrs.laz", xyz, cls, rnum, nret, crs=None)}


def _gpkg(path, xyz):
    gpd.GeoDataFrame(geometry=shapely.points(xyz[:, 0], xyz[:, 1], xyz[:, 2]),
                     crs="EPSG:3003").to_file(path)
    return path


def _grid(inp, out, **extra):
    params = {"INPUT": str(inp), "CELL_SIZE": 5.0, "EXTENT": f"{X0},{Y0},{X0 + 200},{Y0 + 150}",
              "OUTPUT": str(out), **extra}
    result = toolbox.run("dem:idw", params)
    with rasterio.open(out) as ds:
        return ds.read(1), ds.crs, result


def test_reader_filters_match_numpy_selection(cloud):
    ref = open_point_cloud(cloud["laz"])
    assert ref.compressed and ref.point_count == len(cloud["xyz"])
    assert ref.crs.to_epsg() == 3003
    cases = {PointFilter(): np.ones(len(cloud["xyz"]), bool),
             PointFilter((2,)): cloud["cls"] == 2,
             PointFilter((2, 6), "first"): np.isin(cloud["cls"], [2, 6]) & (cloud["rnum"] == 1),
             PointFilter(None, "last"): cloud["rnum"] == cloud["nret"]}
    for flt, mask in cases.items():
        xyz, report = read_xyz(ref, flt, chunk_points=700)  # several chunks
        assert report.read == len(cloud["xyz"]) and report.kept == mask.sum(), flt
        assert np.allclose(xyz, cloud["xyz"][mask], atol=6e-4), flt  # 1 mm quantisation
    assert report.classes == {c: int((cloud["cls"] == c).sum()) for c in (2, 5, 6)}
    # another dimension as the height (Z_FIELD): here the return number
    xyz, _ = read_xyz(ref, PointFilter((5,)), z_field="return_number")
    assert np.array_equal(xyz[:, 2], cloud["rnum"][cloud["cls"] == 5])


def test_gridding_from_laz_equals_gridding_from_gpkg(cloud, tmp_path):
    ground = cloud["xyz"][cloud["cls"] == 2]
    # the GeoPackage holds exactly what the LAS stores (millimetre grid)
    ref_dem, ref_crs, _ = _grid(_gpkg(tmp_path / "g.gpkg", ground), tmp_path / "ref.tif")
    for name in ("laz", "las"):
        dem, crs, res = _grid(cloud[name], tmp_path / f"{name}.tif", CLASSES="2")
        assert crs == ref_crs
        assert np.allclose(dem, ref_dem, atol=1e-4), name
        assert res["STATISTICS"]["inputs"]["point_cloud"]["points_kept"] == len(ground)


def test_tin_from_laz(cloud, tmp_path):
    out = tmp_path / "tin.gpkg"
    res = toolbox.run("tin:delaunay", {"INPUT": str(cloud["laz"]), "CLASSES": "2",
                                       "RETURNS": "first", "OUTPUT": str(out)})
    nodes = gpd.read_file(out, layer="nodes")
    want = (cloud["cls"] == 2) & (cloud["rnum"] == 1)
    assert len(nodes) == want.sum()
    assert nodes.crs.to_epsg() == 3003
    assert res["STATISTICS"]["point_cloud"]["points_kept"] == want.sum()


def test_no_crs_refused_unless_given(cloud, tmp_path):
    with pytest.raises(ParameterError, match="no CRS"):
        _grid(cloud["nocrs"], tmp_path / "a.tif")
    assert not (tmp_path / "a.tif").exists()
    dem, crs, _ = _grid(cloud["nocrs"], tmp_path / "b.tif", CRS="EPSG:3003")
    assert crs.to_epsg() == 3003 and np.isfinite(dem).any()


@pytest.mark.parametrize("version, fmt, vlr", [("1.2", 3, "GeoKeyDirectoryVlr"),
                                               ("1.4", 6, "WktCoordinateSystemVlr")])
def test_crs_from_geotiff_keys_or_wkt(tmp_path, version, fmt, vlr):
    """The CRS of a LAS 1.2 file with GeoTIFF keys only and of a LAS 1.4 file with an OGC WKT
    VLR only (each written by laspy) reaches the gridded DEM."""
    from pyproj import CRS

    header = laspy.LasHeader(point_format=fmt, version=version)
    header.offsets, header.scales = [X0, Y0, 0.0], [0.001] * 3
    header.add_crs(CRS.from_epsg(3003))
    kinds = [type(v).__name__ for v in header.vlrs]
    assert vlr in kinds and ("WktCoordinateSystemVlr" in kinds) == (version == "1.4")
    las = laspy.LasData(header)
    rng = np.random.default_rng(3)
    las.x, las.y = X0 + rng.uniform(0, 50, 100), Y0 + rng.uniform(0, 50, 100)
    las.z = rng.uniform(0, 5, 100)
    las.write(tmp_path / "c.laz")
    assert open_point_cloud(tmp_path / "c.laz").crs == CRS.from_epsg(3003)
    _, crs, _ = _grid(tmp_path / "c.laz", tmp_path / "c.tif")
    assert crs.to_epsg() == 3003


def test_missing_class_and_bad_filters(cloud, tmp_path):
    with pytest.raises(InputDataError, match=r"CLASSES 9 not in .* 2 \(\d+ points\)"):
        _grid(cloud["laz"], tmp_path / "a.tif", CLASSES="2,9")
    with pytest.raises(ParameterError, match="CLASSES"):
        _grid(cloud["laz"], tmp_path / "a.tif", CLASSES="ground")
    gpkg = _gpkg(tmp_path / "g.gpkg", cloud["xyz"][:50])
    with pytest.raises(ParameterError, match="applies only to a LAS/LAZ"):
        _grid(gpkg, tmp_path / "a.tif", RETURNS="first")
    assert not (tmp_path / "a.tif").exists()


def test_laz_without_backend_is_a_clear_error(cloud, tmp_path, monkeypatch):
    monkeypatch.setattr(laspy.LazBackend, "detect_available", staticmethod(lambda: ()))
    with pytest.raises(InputDataError, match="no LAZ backend is installed: pip install lazrs"):
        _grid(cloud["laz"], tmp_path / "a.tif")
    assert not (tmp_path / "a.tif").exists()
    dem, _, _ = _grid(cloud["las"], tmp_path / "b.tif")  # uncompressed LAS still reads
    assert np.isfinite(dem).any()


def test_cli_bad_class_exit_2_one_line(cloud, tmp_path):
    from toolbox.cli import main

    out = tmp_path / "x.tif"
    res = CliRunner().invoke(main, ["run", "dem:nearest", "--INPUT", str(cloud["laz"]),
                                    "--CLASSES", "7", "--CELL_SIZE", "10", "--OUTPUT", str(out)])
    assert res.exit_code == 2, res.output
    assert "CLASSES 7 not in" in res.stderr and "Traceback" not in res.output
    assert len(res.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_writer_roundtrip_with_laspy(tmp_path):
    rng = np.random.default_rng(1)
    xyz = np.column_stack([X0 + rng.uniform(0, 10, 2500), Y0 + rng.uniform(0, 10, 2500),
                           rng.uniform(200, 300, 2500)])
    rgb = rng.integers(0, 256, (2500, 3)).astype(np.uint8)
    cls = rng.integers(1, 3, 2500)
    path = tmp_path / "w.laz"
    assert write_point_cloud(path, xyz, "EPSG:3003", classification=cls, rgb=rgb,
                             chunk_points=1000) == 2500
    las = laspy.read(path)
    assert np.allclose(np.column_stack([las.x, las.y, las.z]), xyz, atol=6e-4)
    assert np.array_equal(np.asarray(las.classification), cls)
    assert np.array_equal(np.asarray(las.red), rgb[:, 0].astype(np.uint16) * 257)
    assert las.header.parse_crs().to_epsg() == 3003


# -- COPC ---------------------------------------------------------------------------------------
COPC_SAMPLE = Path(__file__).resolve().parents[1] / "data" / "pointclouds" / "simple.copc.laz"


def test_copc_read_with_filters_and_crs(tmp_path):
    """laspy's public COPC sample (tests/data/pointclouds/README.md; laspy cannot write COPC):
    the chunked LAZ reading of it equals laspy's CopcReader (the octree's nodes) point for point,
    the filters equal numpy selections, the CRS comes from its WKT VLR, and dem:nearest grids its
    ground class."""
    from laspy import CopcReader

    ref = open_point_cloud(COPC_SAMPLE)
    assert ref.info["copc"] is True and ref.point_count == 1065
    assert ref.crs.name == "NAD83 / Oregon LCC (m) + NAVD88 height (ftUS)"
    with CopcReader.open(str(COPC_SAMPLE)) as reader:  # the independent reference: by nodes
        nodes = reader.query()
    truth = np.column_stack([np.asarray(nodes.x), np.asarray(nodes.y), np.asarray(nodes.z)])
    cls, rn = np.asarray(nodes.classification), np.asarray(nodes.return_number)
    nr = np.asarray(nodes.number_of_returns)

    def same(a, b):
        key = lambda p: p[np.lexsort(p.T[::-1])]  # noqa: E731
        np.testing.assert_allclose(key(a), key(b), atol=1e-6)

    xyz, report = read_xyz(ref)
    same(xyz, truth)
    assert report.classes == {1: int((cls == 1).sum()), 2: int((cls == 2).sum())}
    xyz, _ = read_xyz(ref, PointFilter((2,)))
    same(xyz, truth[cls == 2])
    xyz, _ = read_xyz(ref, PointFilter(None, "first"))
    same(xyz, truth[rn <= 1])
    xyz, _ = read_xyz(ref, PointFilter((1,), "last"))
    same(xyz, truth[(cls == 1) & (rn >= nr)])
    with pytest.raises(InputDataError, match="CLASSES 6 not in"):
        read_xyz(ref, PointFilter((6,)))
    out = toolbox.run("dem:nearest", {"INPUT": str(COPC_SAMPLE), "CLASSES": "2",
                                      "CELL_SIZE": 50.0, "OUTPUT": str(tmp_path / "g.tif")})
    assert out["STATISTICS"]["points_used"] == int((cls == 2).sum())
    with rasterio.open(tmp_path / "g.tif") as ds:
        assert "Oregon" in ds.crs.to_wkt()
