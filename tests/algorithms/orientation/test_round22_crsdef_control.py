"""An orthophoto and its DEM labelled with the ESRI WKT of the project's EPSG:6707 (GDAL keeps
it in a GeoTIFF; ``pyproj.CRS.equals`` tells it from EPSG:6707 though no point moves) used by
orientation:control and report:ortho_check (round 22, crsdef). Before: exit 2, "ORTHO is in
RDN2008 / UTM zone 32N (N-E), not in the project's CRS (EPSG:6707): reproject it first"
(report:ortho_check: "ORTHO is in RDN2008 / UTM zone 32N (N-E) but PROJECT is in EPSG:6707").
Now one CRS (``toolbox.io.crs.one_crs``: the raster's extent moves by at most 1 mm), the
outputs byte-identical to the EPSG-labelled run's; ED50 / UTM 32N is still refused."""

from __future__ import annotations

import numpy as np
import pytest
from helpers_cli import cli, one_error
from rasterio.transform import from_origin

from tests.toolbox.crs_cases import ESRI_6707, write_one_photo_project
from tests.toolbox.crs_cases import write_raster as _raster

LABELS = {"epsg": "EPSG:6707", "esri": ESRI_6707, "ed50": "EPSG:23032"}
X0, Y0 = 680000.0, 4800000.0


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    """A vertical photo 800 m over flat ground in an EPSG:6707 project, four control points
    under it, their measurements, and one orthophoto (1 m) and DEM (10 m) per label."""
    folder = tmp_path_factory.mktemp("crsdef_control")
    rng = np.random.default_rng(1)
    n = 200
    _raster(folder / "p1.tif", rng.integers(0, 255, (n, n), dtype="uint8"), None,
            from_origin(0, 0, 1, 1))
    write_one_photo_project(folder, n, (X0 + 500, Y0 - 500, 1000.0, 0.0, 0.0, 0.0))
    offsets = [(-300, -200), (250, 100), (0, 0), (100, -280)]
    (folder / "control.csv").write_text("id,X,Y,Z\n" + "".join(
        f"g{k},{X0 + 500 + dx},{Y0 - 500 + dy},200\n" for k, (dx, dy) in enumerate(offsets)))
    (folder / "measured.csv").write_text("point_id,photo,col_px,row_px\n" + "".join(
        f"g{k},p1,{c},{r}\n" for k, (c, r) in enumerate([(50.1, 133.3), (141.6, 83.4),
                                                          (100, 100), (116.6, 140.0)])))
    ortho = rng.integers(0, 255, (1000, 1000), dtype="uint8")
    for tag, crs in LABELS.items():
        _raster(folder / f"ortho_{tag}.tif", ortho, crs, from_origin(X0, Y0, 1, 1))
        _raster(folder / f"dem_{tag}.tif", np.full((100, 100), 200, "float32"), crs,
                from_origin(X0, Y0, 10, 10))
    return folder


def _control(block, tag, out):
    return cli("run", "orientation:control", "--PROJECT", block / "project.yaml", "--CONTROL",
               block / "control.csv", "--ORTHO", block / f"ortho_{tag}.tif", "--DEM",
               block / f"dem_{tag}.tif", "--OUTPUT", out)


def _ortho_check(block, tag, out):
    return cli("run", "report:ortho_check", "--PROJECT", block / "project.yaml", "--ORTHO",
               block / f"ortho_{tag}.tif", "--CHECK_POINTS", block / "control.csv",
               "--MEASUREMENTS", block / "measured.csv", "--DEM", block / f"dem_{tag}.tif",
               "--OUTPUT", out)


@pytest.mark.parametrize("run", [_control, _ortho_check], ids=["control", "ortho_check"])
def test_an_ortho_and_dem_labelled_with_the_esri_wkt_are_in_the_project_crs(block, tmp_path,
                                                                            run):
    out = {tag: tmp_path / f"{tag}.csv" for tag in LABELS}
    for tag in ("epsg", "esri"):
        code, _, err = run(block, tag, out[tag])
        assert code == 0, err
    assert out["esri"].read_bytes() == out["epsg"].read_bytes()
    code, _, err = run(block, "ed50", out["ed50"])
    line = one_error(err)
    assert code == 2 and "ORTHO is in EPSG:23032" in line and "EPSG:6707" in line, line
    assert not out["ed50"].exists()
