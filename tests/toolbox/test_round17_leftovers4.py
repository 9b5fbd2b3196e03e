"""Round 17, defects the other helpers noticed (leftovers4).

- a geotransform with rotation terms like 1e-15 (what reprojections and GIS exports write) is
  north-up: its far corner moves by far less than a cell; it was refused as "rotated".
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
from affine import Affine

import toolbox


def _tilted_plane(path: Path, b: float, d: float) -> Path:
    """A 50 x 40 plane rising 0.1 m per metre eastwards, 0.5 m cells, rotation terms b, d."""
    t = Affine(0.5, b, 500000.0, d, -0.5, 4000000.0)
    xx = np.mgrid[0:40, 0:50][1]
    with rasterio.open(path, "w", driver="GTiff", width=50, height=40, count=1,
                       dtype="float32", crs="EPSG:32631", transform=t) as dst:
        dst.write((0.1 * 0.5 * xx).astype("float32"), 1)
    return path


def test_negligible_rotation_terms_read_as_north_up(tmp_path):
    from toolbox.io.raster import open_raster_info, require_north_up

    info = open_raster_info(_tilted_plane(tmp_path / "dem.tif", 1e-15, -1e-15), role="dem")
    assert (info.transform.b, info.transform.d) == (0.0, 0.0)
    require_north_up(info.transform, "INPUT", info.path)  # no error
    out = toolbox.run("dem:slope", {"INPUT": str(info.path),
                                    "OUTPUT": str(tmp_path / "slope.tif")})
    with rasterio.open(out["OUTPUT"] if isinstance(out, dict) else tmp_path / "slope.tif") as src:
        slope = src.read(1, masked=True)
        assert src.transform.b == 0 and src.transform.d == 0
    assert np.ma.median(slope) == pytest.approx(np.degrees(np.arctan(0.1)), abs=1e-4)
    toolbox.run("carto:contours", {"INPUT": str(info.path), "INTERVAL": 0.5,
                                   "OUTPUT": str(tmp_path / "contours.gpkg")})


def test_real_rotation_still_refused(tmp_path):
    from toolbox.errors import ParameterError
    from toolbox.io.raster import open_raster_info, require_north_up

    info = open_raster_info(_tilted_plane(tmp_path / "dem.tif", 1e-6, 0.0), role="dem")
    assert info.transform.b == 1e-6  # 40 rows x 1e-6 m: 8e-5 of a cell
    with pytest.raises(ParameterError, match="rotated"):
        require_north_up(info.transform, "INPUT", info.path)


def test_read_error_classifier_ignores_a_handled_probe(tmp_path):
    """A probe of INPUT as a raster (GDAL: "not recognized", handled: it is a vector layer)
    and then a failed write: the write's error is not read as "INPUT truncated or corrupt"."""
    import geopandas as gpd
    import shapely

    from toolbox import registry
    from toolbox.ortho.rpc import has_rpc
    from toolbox.runner.failures import as_read_error, collect_gdal_errors

    points = tmp_path / "points.gpkg"
    gpd.GeoDataFrame({"z": [1.0]}, geometry=[shapely.Point(0, 0)],
                     crs="EPSG:32631").to_file(points)
    alg = registry.get("mosaic:cut")
    with collect_gdal_errors() as messages:
        assert has_rpc(points) is False  # the probe, handled
        with pytest.raises(rasterio.errors.RasterioIOError) as failed:
            rasterio.open(tmp_path / "missing" / "out.tif", "w", driver="GTiff", width=1,
                          height=1, count=1, dtype="uint8")
        error = as_read_error(failed.value, messages, alg, {"INPUT": str(points)})
    assert "points.gpkg" not in str(error)
    assert "out.tif" in str(error)  # the write's own words


def test_points_and_lines_without_geometry_are_skipped_with_a_warning(tmp_path, caplog):
    import logging

    import geopandas as gpd
    import shapely

    from toolbox.io.vector_points import read_points_xyz

    points = [shapely.Point(x, y, x + y) for x, y in [(0, 0), (10, 0), (0, 10), (10, 10)]]
    gpd.GeoDataFrame({"id": range(6)}, geometry=[points[0], None, *points[1:], shapely.Point()],
                     crs="EPSG:32631").to_file(tmp_path / "points.gpkg")
    gpd.GeoDataFrame({"id": [1, 2]}, geometry=[None, shapely.LineString([(1, 1, 2), (9, 9, 18)])],
                     crs="EPSG:32631").to_file(tmp_path / "lines.gpkg")
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        xyz = read_points_xyz(str(tmp_path / "points.gpkg"))
    assert len(xyz) == 4
    said = [r.getMessage() for r in caplog.records if "no geometry" in r.getMessage()]
    assert len(said) == 1 and "2 of 6" in said[0] and "rows 2, 6" in said[0]
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        toolbox.run("tin:delaunay", {"INPUT": str(tmp_path / "points.gpkg"),
                                     "BREAKLINES": str(tmp_path / "lines.gpkg"),
                                     "OUTPUT": str(tmp_path / "tin.gpkg")})
    said = [r.getMessage() for r in caplog.records if "no geometry" in r.getMessage()]
    assert sorted(m.split(":")[0] for m in said) == ["BREAKLINES", "INPUT"]
    assert any("1 of 2" in m and "row 1," in m for m in said)


def test_dxf_entities_on_frozen_or_off_layers_left_out_with_a_warning(tmp_path):
    import ezdxf

    from toolbox.attribution.sources import read_sources

    doc = ezdxf.new("R2010")
    doc.layers.add("FAB01002", color=8)
    doc.layers.add("COSTRUZIONE").freeze()
    doc.layers.add("AUSILIARIE").off()
    msp = doc.modelspace()
    msp.add_line((0, 0, 1), (5, 0, 1), dxfattribs={"layer": "FAB01002"})
    msp.add_line((0, 1, 1), (5, 1, 1), dxfattribs={"layer": "COSTRUZIONE"})
    msp.add_line((0, 2, 1), (5, 2, 1), dxfattribs={"layer": "COSTRUZIONE"})
    msp.add_point((3, 3, 2), dxfattribs={"layer": "AUSILIARIE"})
    doc.saveas(tmp_path / "model.dxf")

    class Said:
        def __init__(self):
            self.warnings = []

        def push_warning(self, text):
            self.warnings.append(text)

    said = Said()
    frames, _ = read_sources([str(tmp_path / "model.dxf")], "EPSG:32633", said)
    assert frames[0]["code"].tolist() == ["FAB01002"]
    assert len(said.warnings) == 1
    assert "2 on 'COSTRUZIONE' (frozen)" in said.warnings[0]
    assert "1 on 'AUSILIARIE' (off)" in said.warnings[0]


def test_mosaic_says_once_which_mask_wins_for_nodata_and_alpha(tmp_path):
    """rasterio's "nodata attribute is shadowing the alpha band", repeated at every mask read,
    gives way to one toolbox warning per input saying what the mosaic does."""
    from tests.conftest import run_cli

    for k, x0 in enumerate((500000.0, 500030.0)):
        alpha = np.full((40, 50), 255, "uint8")
        alpha[:, :5] = 0
        with rasterio.open(tmp_path / f"o{k}.tif", "w", driver="GTiff", width=50, height=40,
                           count=4, dtype="uint8", crs="EPSG:32633", nodata=0,
                           transform=Affine(1, 0, x0, 0, -1, 4000040), photometric="RGB") as dst:
            dst.write(np.full((3, 40, 50), 100 + 50 * k, "uint8"), [1, 2, 3])
            dst.write(alpha, 4)
            dst.colorinterp = [rasterio.enums.ColorInterp.red, rasterio.enums.ColorInterp.green,
                               rasterio.enums.ColorInterp.blue, rasterio.enums.ColorInterp.alpha]
    done = run_cli("run", "mosaic:build", "--INPUT", tmp_path / "o0.tif", "--INPUT",
                   tmp_path / "o1.tif", "--OUTPUT", tmp_path / "m.tif")
    assert done.returncode == 0, done.stderr
    assert "shadowing" not in done.stderr
    said = [line for line in done.stderr.splitlines() if "nodata value (0) and an alpha" in line]
    assert [line.split(":")[1].strip() for line in said] == ["o0", "o1"]
    with rasterio.open(tmp_path / "m.tif") as src:  # what it says: the nodata value wins
        assert src.read(1)[20, 0] == 100


def _north_and_south_dems(tmp_path):
    """The same 30 x 20 cells of z = x/10 + y/20 (local metres) stored north-up and south-up,
    and four 3D points at height 5 over the DEM's south part (not symmetric)."""
    import geopandas as gpd
    import shapely

    width, height, x0, y1 = 30, 20, 500000.0, 4000020.0
    cols, rows = np.meshgrid(np.arange(width), np.arange(height))
    z = (0.1 * (cols + 0.5) + 0.05 * (height - rows - 0.5)).astype("float32")
    profile = dict(driver="GTiff", width=width, height=height, count=1, dtype="float32",
                   crs="EPSG:32633")
    with rasterio.open(tmp_path / "north.tif", "w", **profile,
                       transform=Affine(1, 0, x0, 0, -1, y1)) as dst:
        dst.write(z, 1)
    with rasterio.open(tmp_path / "south.tif", "w", **profile,
                       transform=Affine(1, 0, x0, 0, 1, y1 - height)) as dst:
        dst.write(z[::-1], 1)
    corners = [(2, 2), (28, 2), (2, 8), (28, 8)]
    gpd.GeoDataFrame(geometry=[shapely.Point(x0 + dx, y1 - height + dy, 5.0)
                               for dx, dy in corners], crs="EPSG:32633").to_file(
        tmp_path / "pts.gpkg")
    return Affine(1, 0, x0, 0, -1, y1)


def test_south_up_reference_dem_is_read_flipped(tmp_path):
    """tin:volume against a south-up REFERENCE_DEM (refused as not north-up): the analytic
    volume."""
    import json

    _north_and_south_dems(tmp_path)
    toolbox.run("tin:delaunay", {"INPUT": str(tmp_path / "pts.gpkg"),
                                 "OUTPUT": str(tmp_path / "tin.gpkg")})
    toolbox.run("tin:volume", {"TIN": str(tmp_path / "tin.gpkg"),
                               "REFERENCE_DEM": str(tmp_path / "south.tif"),
                               "REPORT": str(tmp_path / "volume.json")})
    report = json.loads((tmp_path / "volume.json").read_text())
    # 26 x 6 cell centres inside; mean DEM 0.1 * 15 + 0.05 * 5 = 1.75 under the TIN's 5
    assert report["cut_volume"] == pytest.approx((5 - 1.75) * 156, rel=1e-6)


def test_south_up_template_gives_the_same_cells_north_up(tmp_path):
    north_up = _north_and_south_dems(tmp_path)
    for name in ("north", "south"):
        toolbox.run("dem:idw", {"INPUT": str(tmp_path / "pts.gpkg"),
                                "TEMPLATE": str(tmp_path / f"{name}.tif"),
                                "OUTPUT": str(tmp_path / f"idw_{name}.tif")})
    with rasterio.open(tmp_path / "idw_north.tif") as a, \
            rasterio.open(tmp_path / "idw_south.tif") as b:
        assert a.transform == b.transform == north_up
        assert np.array_equal(a.read(1), b.read(1), equal_nan=True)


def _project_without_strips(path, prefix, centres):
    """A project of nadir photos ``prefix``0.. at ``centres`` (x, y), no strip ids, loaded."""
    from toolbox.photogrammetry.project import load_project

    photos = "\n".join(
        f"  - {{id: {prefix}{k}, camera: cam, exterior: {{X0: {x}, Y0: {y}, Z0: 3000, "
        f"omega: 0, phi: 0, kappa: 0}}}}" for k, (x, y) in enumerate(centres))
    path.write_text(
        "version: 1\ncrs: EPSG:3003\nangle_unit: deg\ncameras:\n"
        "  - {name: cam, principal_distance_mm: 150.0, frame_size_mm: [230, 230]}\n"
        f"photos:\n{photos}\n")
    return load_project(path)


def test_photos_without_strip_ids_are_not_paired_across_a_turn(tmp_path, caplog):
    """A serpentine list (east along strip 1, back west along strip 2) without strip ids: the
    photos across the turn were paired; strips are now inferred, with a warning."""
    import logging

    centres = [(1000 + 600 * k, 5000) for k in range(4)] + \
        [(1000 + 600 * k, 6000) for k in (3, 2, 1, 0)]
    project = _project_without_strips(tmp_path / "p.yaml", "P", centres)
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        pairs = [(a.id, b.id) for a, b in project.consecutive_pairs()]
    assert pairs == [("P0", "P1"), ("P1", "P2"), ("P2", "P3"),
                     ("P4", "P5"), ("P5", "P6"), ("P6", "P7")]
    said = [r.getMessage() for r in caplog.records if "strips inferred" in r.getMessage()]
    assert len(said) == 1 and "2 strips inferred" in said[0]
    # a straight strip: one strip, no warning
    straight = [(1000 + 600 * k, 5000 + 3 * k) for k in range(6)]
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="toolbox"):
        project = _project_without_strips(tmp_path / "s.yaml", "S", straight)
        assert len(project.consecutive_pairs()) == 5
    assert not [r for r in caplog.records if "strips inferred" in r.getMessage()]
