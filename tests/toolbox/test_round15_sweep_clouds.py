"""Round 15 sweep of LAS/LAZ inputs: withheld points, CRS from GeoTIFF keys."""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

laspy = pytest.importorskip("laspy")


def _grid_cloud(path, withheld=None, z=None, crs="EPSG:32633"):
    xs, ys = np.meshgrid(500000.0 + 10 * np.arange(5), 4500000.0 + 10 * np.arange(5))
    x, y = xs.ravel(), ys.ravel()
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([0.01, 0.01, 0.01])
    header.offsets = np.array([500000.0, 4500000.0, 0.0])
    if crs is not None:
        from pyproj import CRS

        header.add_crs(CRS.from_user_input(crs))
    las = laspy.LasData(header)
    las.x, las.y = x, y
    las.z = 100.0 + 0.1 * (x - 500000) if z is None else z
    las.classification = np.full(len(x), 2, np.uint8)
    las.return_number = np.ones(len(x), np.uint8)
    las.number_of_returns = np.ones(len(x), np.uint8)
    if withheld is not None:
        las.withheld = withheld
    las.write(path)
    return x, y, np.asarray(las.z)


def test_withheld_points_are_not_read(tmp_path):
    """LAS spec: a withheld point 'should not be included in processing' (deleted). It was
    gridded like any other (a deleted 9999 m spike in the DEM)."""
    from toolbox.io.pointcloud import PointFilter, open_point_cloud, read_xyz

    withheld = np.zeros(25, bool)
    withheld[[3, 12]] = True
    z = np.full(25, 100.0)
    z[withheld] = 9999.0
    x, y, _ = _grid_cloud(tmp_path / "w.las", withheld, z)
    ref = open_point_cloud(tmp_path / "w.las")
    for flt in (PointFilter(), PointFilter((2,)), PointFilter(None, "last")):
        xyz, report = read_xyz(ref, flt)
        assert len(xyz) == 23 and xyz[:, 2].max() == 100.0
        np.testing.assert_allclose(xyz[:, 0], x[~withheld])
        assert report.as_dict()["points_withheld"] == 2
        assert report.read == 25 and report.kept == 23
    _grid_cloud(tmp_path / "all.las", np.ones(25, bool))
    from toolbox.errors import InputDataError

    with pytest.raises(InputDataError, match="25 flagged withheld"):
        read_xyz(open_point_cloud(tmp_path / "all.las"))


def _geokeys_cloud(path, keys, doubles=None, ascii_=None):
    """A small LAS 1.2 cloud whose CRS is only GeoTIFF keys (no WKT VLR)."""
    from laspy.vlrs.known import GeoAsciiParamsVlr, GeoDoubleParamsVlr, GeoKeyDirectoryVlr, GeoKeyEntryStruct

    header = laspy.LasHeader(point_format=1, version="1.2")
    header.scales = np.array([0.01, 0.01, 0.01])
    header.offsets = np.array([636000.0, 848000.0, 0.0])
    directory = GeoKeyDirectoryVlr()
    directory.geo_keys = [GeoKeyEntryStruct(*k) for k in keys] + [GeoKeyEntryStruct(0, 0, 0, 0)]
    directory.geo_keys_header.number_of_keys = len(directory.geo_keys)  # a padded directory
    header.vlrs.append(directory)
    if doubles is not None:
        record = GeoDoubleParamsVlr()
        record.doubles = [ctypes.c_double(v) for v in doubles]
        header.vlrs.append(record)
    if ascii_ is not None:
        record = GeoAsciiParamsVlr()
        record.strings = [ascii_]
        header.vlrs.append(record)
    las = laspy.LasData(header)
    las.x = 636500.0 + np.array([0.0, 100.0, 0.0, 100.0])
    las.y = 849000.0 + np.array([0.0, 0.0, 100.0, 100.0])
    las.z = np.array([400.0, 401.0, 402.0, 403.0])
    las.write(path)


def test_user_defined_geotiff_projection_is_read(tmp_path):
    """GeoTIFF keys of a user-defined Lambert projection in international feet on the EPSG
    datum NAD83(HARN) (autzen_trim.laz's keys, the geographic key an EPSG code): laspy took
    the file as geographic EPSG:4152 (refused as 'geographic, reproject it', even with --CRS).
    Truth: the vendor's own WKT for those keys (autzen_trim.laz's WKT VLR)."""
    from pyproj import CRS, Transformer

    from toolbox.io.pointcloud import open_point_cloud

    keys = [(1024, 0, 1, 1), (1025, 0, 1, 1), (2048, 0, 1, 4152), (3072, 0, 1, 32767),
            (3074, 0, 1, 32767), (3075, 0, 1, 8), (3076, 0, 1, 9002), (3078, 34736, 1, 2),
            (3079, 34736, 1, 3), (3084, 34736, 1, 1), (3085, 34736, 1, 0),
            (3086, 34736, 1, 4), (3087, 34736, 1, 5)]
    doubles = [41.75, -120.5, 43.0, 45.5, 1312335.958005249, 0.0]
    _geokeys_cloud(tmp_path / "u.las", keys, doubles, "NAD_1983_HARN_Lambert_Conformal_Conic|")
    crs = open_point_cloud(tmp_path / "u.las").crs
    assert crs is not None and crs.is_projected
    assert crs.axis_info[0].unit_conversion_factor == pytest.approx(0.3048)
    truth = CRS.from_proj4("+proj=lcc +lat_0=41.75 +lon_0=-120.5 +lat_1=43 +lat_2=45.5 "
                           "+x_0=400000 +y_0=0 +ellps=GRS80 +units=ft +no_defs")
    got = Transformer.from_crs(crs, crs.geodetic_crs, always_xy=True).transform(636500, 849000)
    want = Transformer.from_crs(truth, truth.geodetic_crs, always_xy=True).transform(636500,
                                                                                     849000)
    assert crs.datum.name.startswith("NAD83")
    assert got == pytest.approx(want, abs=1e-7)


def test_vertical_geotiff_key_is_kept(tmp_path):
    """ProjectedCSTypeGeoKey 32633 + VerticalCSTypeGeoKey 5703: the vertical CRS was dropped."""
    from toolbox.io.pointcloud import open_point_cloud

    _geokeys_cloud(tmp_path / "v.las", [(1024, 0, 1, 1), (3072, 0, 1, 32633),
                                        (4096, 0, 1, 5703)])
    crs = open_point_cloud(tmp_path / "v.las").crs
    assert crs.is_compound
    assert [c.to_epsg() for c in crs.sub_crs_list] == [32633, 5703]


def test_epsg_geotiff_key_unchanged(tmp_path):
    from toolbox.io.pointcloud import open_point_cloud

    _geokeys_cloud(tmp_path / "e.las", [(1024, 0, 1, 1), (3072, 0, 1, 32633)])
    assert open_point_cloud(tmp_path / "e.las").crs.to_epsg() == 32633


def test_ground_points_keep_the_input_records(tmp_path):
    """dem:ground GROUND_POINTS ('the input points classified'): every dimension was dropped
    (intensity, returns, GPS time, colour, extra bytes; format 6, returns 1/1), and with Z_FIELD
    the field was written as Z. Truth: laspy reading the input; only classification differs."""
    import toolbox

    xs, ys = np.meshgrid(np.arange(0.0, 40.0, 1.0), np.arange(0.0, 40.0, 1.0))
    x, y = 500000.0 + xs.ravel(), 4500000.0 + ys.ravel()
    roof = (xs.ravel() >= 15) & (xs.ravel() < 25) & (ys.ravel() >= 15) & (ys.ravel() < 25)
    z = 100.0 + 8.0 * roof
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([0.01, 0.01, 0.01])
    header.offsets = np.array([500000.0, 4500000.0, 0.0])
    header.add_extra_dim(laspy.ExtraBytesParams(name="zalt", type=np.float64))
    from pyproj import CRS

    header.add_crs(CRS.from_epsg(32633))
    las = laspy.LasData(header)
    las.x, las.y, las.z = x, y, z
    las.zalt = z + 0.5
    las.intensity = np.arange(len(x)) % 60000
    las.gps_time = np.arange(len(x)) * 0.5
    las.red = np.arange(len(x)) % 65535
    las.return_number = np.ones(len(x), np.uint8)
    las.number_of_returns = np.ones(len(x), np.uint8)
    las.classification = np.where(roof, 6, 1).astype(np.uint8)
    las.write(tmp_path / "in.las")
    toolbox.run("dem:ground", {"INPUT": str(tmp_path / "in.las"), "Z_FIELD": "zalt",
                               "FILTER_CELL": 1.0, "MAX_WINDOW": 16.0, "METHOD": "nearest",
                               "OUTPUT": str(tmp_path / "dtm.tif"),
                               "NONGROUND": str(tmp_path / "ng.tif"),
                               "GROUND_POINTS": str(tmp_path / "out.las")})
    out = laspy.read(tmp_path / "out.las")
    assert out.header.point_format.id == 3 and len(out.points) == len(x)
    for name in ("X", "Y", "Z", "intensity", "gps_time", "red", "zalt"):
        np.testing.assert_array_equal(np.asarray(out[name]), np.asarray(las[name]), name)
    np.testing.assert_array_equal(np.asarray(out.classification), np.where(roof, 1, 2))
    assert out.header.parse_crs().to_epsg() == 32633
    np.testing.assert_allclose(out.header.mins, [x.min(), y.min(), 100.0])
    np.testing.assert_allclose(out.header.maxs, [x.max(), y.max(), 108.0])


def test_las14_count_only_in_the_legacy_field(tmp_path):
    """A LAS 1.4 file whose 64-bit point count is 0 and legacy count N (some writers): laspy
    read no point, INPUT was refused as 'has no points' (exit 2). LASlib reads the legacy
    count when it is set; the points are those of the file."""
    import struct

    from toolbox.io.pointcloud import open_point_cloud, read_xyz

    header = laspy.LasHeader(point_format=1, version="1.4")
    header.scales = np.array([0.01, 0.01, 0.01])
    las = laspy.LasData(header)
    las.x = np.array([0.0, 10.0, 0.0, 10.0])
    las.y = np.array([0.0, 0.0, 10.0, 10.0])
    las.z = np.array([1.0, 2.0, 3.0, 4.0])
    las.write(tmp_path / "a.las")
    raw = bytearray((tmp_path / "a.las").read_bytes())
    struct.pack_into("<I", raw, 107, 4)  # legacy count
    struct.pack_into("<Q", raw, 247, 0)  # LAS 1.4 count
    (tmp_path / "b.las").write_bytes(bytes(raw))
    ref = open_point_cloud(tmp_path / "b.las")
    assert ref.point_count == 4
    xyz, _ = read_xyz(ref)
    np.testing.assert_allclose(xyz[:, 2], [1.0, 2.0, 3.0, 4.0])


def test_streamed_gridding_of_a_cloud_whose_header_bounds_are_stale(tmp_path, monkeypatch):
    """Header bounds smaller than the points (a header not updated after an edit): the
    streamed path refused the file (exit 2, 'a broken file'), the in-memory path gridded it.
    Truth: scipy's nearest point at each cell centre."""
    import struct

    import rasterio
    from scipy.spatial import cKDTree

    import toolbox

    rng = np.random.default_rng(3)
    x = 500000.0 + rng.uniform(0, 100, 300)
    y = 4500000.0 + rng.uniform(0, 100, 300)
    z = 100.0 + 0.1 * (x - 500000.0) + rng.uniform(0, 1, 300)
    _grid_cloud(tmp_path / "a.las")  # the header layout of a 1.2 file with a CRS
    header = laspy.read(tmp_path / "a.las").header
    las = laspy.LasData(header)
    las.x, las.y, las.z = x, y, z
    las.classification = np.full(300, 2, np.uint8)
    las.write(tmp_path / "b.las")
    raw = bytearray((tmp_path / "b.las").read_bytes())
    struct.pack_into("<6d", raw, 179, 500050.0, 500000.0, 4500050.0, 4500000.0, 110.0, 100.0)
    (tmp_path / "b.las").write_bytes(bytes(raw))
    stored = laspy.read(tmp_path / "b.las")  # the coordinates as stored (0.01 m)
    x, y, z = np.asarray(stored.x), np.asarray(stored.y), np.asarray(stored.z)
    monkeypatch.setenv("TOOLBOX_STREAM_POINTS", "10")
    toolbox.run("dem:nearest", {"INPUT": str(tmp_path / "b.las"), "CELL_SIZE": 10.0,
                                "EXTENT": "500000,4500000,500100,4500100",
                                "OUTPUT": str(tmp_path / "n.tif")})
    with rasterio.open(tmp_path / "n.tif") as ds:
        grid, nodata = ds.read(1), ds.nodata
    cx, cy = np.meshgrid(500005.0 + 10 * np.arange(10), 4500095.0 - 10 * np.arange(10))
    _, index = cKDTree(np.column_stack([x, y])).query(np.column_stack([cx.ravel(), cy.ravel()]))
    truth = z[index].reshape(10, 10)
    inside = grid != nodata
    assert inside.sum() > 60
    np.testing.assert_allclose(grid[inside], truth[inside], atol=1e-4)


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_classified_copy_of_las14_format_1_fills_the_legacy_counts(tmp_path, suffix):
    """LAS 1.4 specification: with point format 0-5 the legacy point count 'must' hold the
    count (readers of LAS 1.0-1.3 read only it); laspy writes 0 there."""
    import struct

    from toolbox.io.pointcloud import PointFilter, open_point_cloud, write_classified_copy

    header = laspy.LasHeader(point_format=1, version="1.4")
    las = laspy.LasData(header)
    las.x, las.y, las.z = np.arange(10.0), np.arange(10.0) % 3, np.ones(10)
    las.return_number = np.array([1, 2] * 5, np.uint8)
    las.number_of_returns = np.full(10, 2, np.uint8)
    las.write(tmp_path / "in.las")
    out = tmp_path / f"out{suffix}"
    ref = open_point_cloud(tmp_path / "in.las")
    assert write_classified_copy(ref, PointFilter(), out, np.full(10, 2)) == 10
    raw = out.read_bytes()
    assert struct.unpack_from("<6I", raw, 107) == (10, 5, 5, 0, 0, 0)
    assert struct.unpack_from("<Q", raw, 247) == (10,)
    np.testing.assert_array_equal(np.asarray(laspy.read(out).classification), 2)


def test_geotiff_keys_naming_no_crs_stay_no_crs(tmp_path):
    """Keys with a unit only, or a user-defined projection without its parameters: GDAL makes
    an 'unnamed' local CRS of them; the cloud stays without CRS (CRS must be given)."""
    from toolbox.errors import ParameterError
    from toolbox.io.pointcloud import check_cloud_crs, open_point_cloud

    for name, keys in (("u.las", [(1024, 0, 1, 1), (3076, 0, 1, 9002)]),
                       ("p.las", [(1024, 0, 1, 1), (3072, 0, 1, 32767), (3074, 0, 1, 32767)])):
        _geokeys_cloud(tmp_path / name, keys)
        ref = open_point_cloud(tmp_path / name)
        assert ref.crs is None
        with pytest.raises(ParameterError, match="has no CRS"):
            check_cloud_crs(ref, None)
