"""RPC orthos (ortho:photo on an image with RPCs) against GDAL's own RPC transformer as the
independent oracle: ``gdalwarp -rpc -to RPC_DEM=dem.tif -et 0`` (exact at every pixel).

The geometry is compared through a *ramp* image carrying the RPCs: its two bands hold each
pixel centre's column and row (product convention), so a bilinear warp writes at every output
cell the image position the tool mapped it to (bilinear interpolation of a linear ramp is
exact): ours minus GDAL's is the geometric disagreement in pixels. Cases: Orthority's real
QuickBird image on the NGI DEM, a synthetic RPC on a synthetic DEM, and the GCP bias refinement
(a shift, and a scale + shift, that GDAL's RPCs express through their offsets and scales)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rasterio

import toolbox
from toolbox.cameras import read_rpc, refine_bias
from toolbox.raster.writer import write_raster

sys.path.insert(0, str(Path(__file__).parent))
from rpc_scene import (  # noqa: E402
    NODATA,
    disagreement,
    gdal_ortho,
    needs_gdalwarp,
    synthetic_rpc,
    write_gcps,
    write_ramp,
    write_synthetic_dem,
)


def ours(ramp: Path, dem: Path, out: Path, **extra) -> tuple[np.ndarray, dict]:
    stats = toolbox.run("ortho:photo", {"INPUT": ramp, "DEM": dem, "OUTSIDE": "nodata",
                                        "NODATA": NODATA, "OVERVIEWS": False, "OUTPUT": out,
                                        **extra})["STATISTICS"]
    with rasterio.open(out) as src:
        return src.read().astype("float64"), stats


@needs_gdalwarp
def test_quickbird_rpc_ortho_equals_gdalwarp(orthority_data, tmp_path):
    qb, dem = orthority_data / "rpc" / "qb2_basic1b.tif", orthority_data / "ngi" / "dem.tif"
    with rasterio.open(qb) as src:
        rpcs = src.rpcs
    ramp = write_ramp(tmp_path / "ramp.tif", rpcs, 850, 1450)
    # the NGI DEM is EGM2008; that grid is not installed: take its heights as they are, as
    # GDAL does with RPC_DEM_APPLY_VDATUM_SHIFT=FALSE
    # at the image's GSD (coarser, GDAL widens its bilinear kernel: another filter), over the
    # image's middle (fast)
    a, stats = ours(ramp, dem, tmp_path / "ours.tif", HEIGHTS="EPSG:3855", CELL_SIZE=6.5,
                    EXTENT="-57500,-3731000,-55500,-3728000")
    assert stats["heights"]["converted"] is False and stats["camera"] == "rpc"
    assert stats["photo_gsd_m"] == pytest.approx(6.5, abs=0.1)
    assert stats["outside_dem_fraction"] == 0.0
    b = gdal_ortho(ramp, dem, tmp_path / "ours.tif", tmp_path / "gdal.tif")
    worst, compared, only_one = disagreement(a, b, (850, 1450))
    assert compared > 130_000 and worst < 0.05 and only_one < 0.001 * compared
    # the real image runs end to end (the command line's runs: test_rpc_bad_input_is_one_line)
    toolbox.run("ortho:photo", {"INPUT": qb, "DEM": dem, "HEIGHTS": "EPSG:3855",
                                "CELL_SIZE": 40.0, "OUTPUT": tmp_path / "qb.tif"})
    with rasterio.open(tmp_path / "qb.tif") as src:
        assert src.count == 2 and src.res == (40.0, 40.0)  # grey + alpha
        assert (src.read(2) > 0).mean() > 0.8


MIDDLE = "656000,4983300,659200,4986500"  # 3.2 km square in the synthetic image's middle


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """A hilly DEM (EPSG:32632, heights ellipsoidal as RPCs expect) under the synthetic RPC."""
    folder = tmp_path_factory.mktemp("rpc")
    write_synthetic_dem(folder / "dem.tif")
    return folder


@needs_gdalwarp
def test_synthetic_rpc_ortho_equals_gdalwarp(synthetic, tmp_path):
    ramp = write_ramp(tmp_path / "ramp.tif", synthetic_rpc(), 1200, 1000)
    a, stats = ours(ramp, synthetic / "dem.tif", tmp_path / "ours.tif", CELL_SIZE=8.0, EXTENT=MIDDLE)
    assert stats["heights"]["note"].startswith("heights used as they are")
    b = gdal_ortho(ramp, synthetic / "dem.tif", tmp_path / "ours.tif", tmp_path / "gdal.tif")
    worst, compared, only_one = disagreement(a, b, (1200, 1000))
    assert compared > 150_000 and worst < 0.05 and only_one < 0.001 * compared


def test_rpc_scheduler_local_is_not_overridden_by_the_environment(synthetic, tmp_path,
                                                                 monkeypatch):
    """The RPC path hands SCHEDULER's executor to the warp too: with SCHEDULER local a
    DASK_SCHEDULER_ADDRESS naming no cluster (nothing listens on port 9) is not contacted, and
    the ortho equals a run without the variable (issue 31)."""
    ramp = write_ramp(tmp_path / "ramp.tif", synthetic_rpc(), 1200, 1000)
    monkeypatch.delenv("DASK_SCHEDULER_ADDRESS", raising=False)
    a, _ = ours(ramp, synthetic / "dem.tif", tmp_path / "plain.tif", CELL_SIZE=16.0)
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", "tcp://127.0.0.1:9")
    b, _ = ours(ramp, synthetic / "dem.tif", tmp_path / "env.tif", CELL_SIZE=16.0,
                SCHEDULER="local")
    assert (a != NODATA).sum() > 1000 and np.array_equal(a, b)


@needs_gdalwarp
@pytest.mark.parametrize("bias, truth", [("shift", dict(dx=3.7, dy=-2.2)),
                                         ("affine", dict(dx=-1.5, dy=2.5, scale=1.002))])
def test_gcp_bias_refinement_matches_gdal_on_the_true_rpcs(synthetic, tmp_path, bias, truth):
    """The image's RPCs are off by an image-space bias; GCPs measured on it (their pixels
    through the true RPCs) refine them: the ortho equals GDAL's on the true RPCs."""
    ramp = write_ramp(tmp_path / "ramp.tif", synthetic_rpc(), 1200, 1000)
    true_ramp = write_ramp(tmp_path / "true.tif", synthetic_rpc(**truth), 1200, 1000)
    true_camera = read_rpc(true_ramp, "EPSG:32632")
    control, measured = write_gcps(tmp_path, true_camera, "ramp.tif", 6, seed=8)
    a, stats = ours(ramp, synthetic / "dem.tif", tmp_path / "ours.tif", CELL_SIZE=8.0, EXTENT=MIDDLE,
                    CONTROL=control, MEASUREMENTS=measured, BIAS=bias)
    assert stats["bias"]["model"] == bias and stats["bias"]["gcps"] == 6
    assert stats["bias"]["rms_before_px"] > 2.0 and stats["bias"]["rms_after_px"] < 1e-3
    b = gdal_ortho(true_ramp, synthetic / "dem.tif", tmp_path / "ours.tif",
                   tmp_path / "gdal.tif")
    worst, compared, _ = disagreement(a, b, (1200, 1000))
    assert compared > 150_000 and worst < 0.05
    plain, _ = ours(ramp, synthetic / "dem.tif", tmp_path / "plain.tif", CELL_SIZE=8.0, EXTENT=MIDDLE)
    assert disagreement(plain, b, (1200, 1000))[0] > 2.0  # without the GCPs: off by the bias


def test_quickbird_bias_from_its_real_gcps(orthority_data):
    """Orthority's GCPs of the QuickBird image (pixel ``ji``, OpenCV convention; WGS84
    lon/lat/height): its RPCs are off by 3.6 px; a shift brings the fit and every point left
    out of it under 0.2 px."""
    features = json.loads((orthority_data / "rpc" / "gcps.geojson").read_text())["features"]
    ground = np.array([f["geometry"]["coordinates"] for f in features])
    pixels = np.array([f["properties"]["ji"] for f in features]) + 0.5
    camera = read_rpc(orthority_data / "rpc" / "qb2_basic1b.tif")
    fitted, report = refine_bias(camera, ground, pixels, "shift")
    assert report["rms_before_px"] > 3.0 and report["rms_after_px"] < 0.15
    for k in range(len(ground)):
        keep = np.arange(len(ground)) != k
        loo, _ = refine_bias(camera, ground[keep], pixels[keep], "shift")
        assert np.hypot(*(loo.project(ground[k:k + 1])[0] - pixels[k])) < 0.25


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "toolbox", "run", "ortho:photo", *args],
                          capture_output=True, text=True)


def test_rpc_bad_input_is_one_line(synthetic, tmp_path):
    ramp = write_ramp(tmp_path / "ramp.tif", synthetic_rpc(), 1200, 1000)
    out = tmp_path / "o.tif"
    control = tmp_path / "control.csv"
    control.write_text("id,X,Y,Z\ng1,657000,4984000,300\n")
    cases = [
        ((), "DEM"),  # RPC without a DEM
        (("--DEM", str(synthetic / "dem.tif"), "--OCCLUSION"), "OCCLUSION"),
        (("--DEM", str(synthetic / "dem.tif"), "--CONTROL", str(control)), "MEASUREMENTS"),
        (("--DEM", str(synthetic / "dem.tif"), "--CRS", "EPSG:4326"), "projected"),
    ]
    for extra, word in cases:
        run = cli("--INPUT", str(ramp), *extra, "--OUTPUT", str(out))
        assert run.returncode == 2, (extra, run.stderr)
        assert run.stderr.count("\n") == 1 and word in run.stderr, run.stderr
        assert not out.exists()
    plain = tmp_path / "plain.tif"
    write_raster(plain, np.zeros((10, 10), "float32"), rasterio.Affine.identity(), None)
    run = cli("--INPUT", str(plain), "--DEM", str(synthetic / "dem.tif"), "--OUTPUT", str(out))
    assert run.returncode == 2 and "or an INPUT with RPCs" in run.stderr
    assert run.stderr.count("\n") == 1 and not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_quickbird_ortho_with_its_real_gcps(orthority_data, tmp_path):
    """Orthority's GCPs of the QuickBird image as CONTROL (in the DEM's CRS) and MEASUREMENTS:
    the RPCs' 3.6 px bias is taken out (shift), and the ortho moves by it."""
    from pyproj import Transformer

    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.vertical import horizontal_part

    qb, dem = orthority_data / "rpc" / "qb2_basic1b.tif", orthority_data / "ngi" / "dem.tif"
    crs = horizontal_part(open_raster_info(dem).crs)
    features = json.loads((orthority_data / "rpc" / "gcps.geojson").read_text())["features"]
    to_crs = Transformer.from_crs("EPSG:4326", crs, always_xy=True)
    control, measured = ["id,X,Y,Z"], ["point_id,photo,col_px,row_px"]
    for f in features:
        (lon, lat, h), (j, i) = f["geometry"]["coordinates"], f["properties"]["ji"]
        x, y = to_crs.transform(lon, lat)
        control.append(f"{f['properties']['id']},{x:.4f},{y:.4f},{h:.4f}")
        measured.append(f"{f['properties']['id']},qb2_basic1b.tif,{j + 0.5:.4f},{i + 0.5:.4f}")
    (tmp_path / "control.csv").write_text("\n".join(control) + "\n")
    (tmp_path / "measured.csv").write_text("\n".join(measured) + "\n")
    common = {"INPUT": qb, "DEM": dem, "HEIGHTS": "EPSG:3855", "CELL_SIZE": 30.0,
              "EXTENT": "-58000,-3732000,-55000,-3727000", "OVERVIEWS": False}
    stats = toolbox.run("ortho:photo", {**common, "CONTROL": tmp_path / "control.csv",
                                        "MEASUREMENTS": tmp_path / "measured.csv",
                                        "BIAS": "shift", "OUTPUT": tmp_path / "fixed.tif"}
                        )["STATISTICS"]
    assert stats["bias"]["gcps"] == len(features) == 5
    assert stats["bias"]["rms_before_px"] > 3.0 and stats["bias"]["rms_after_px"] < 0.15
    toolbox.run("ortho:photo", {**common, "OUTPUT": tmp_path / "plain.tif"})
    with rasterio.open(tmp_path / "fixed.tif") as a, rasterio.open(tmp_path / "plain.tif") as b:
        assert np.abs(a.read(1).astype(float) - b.read(1).astype(float)).mean() > 1.0
