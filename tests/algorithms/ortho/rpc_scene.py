"""Shared by the RPC ortho tests: ramp images carrying RPCs, GDAL's RPC warp as the oracle, the
disagreement of two ramp orthos, and a synthetic RPC (see test_ortho_rpc's docstring)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.rpc import RPC

from toolbox.photogrammetry.synthetic import hills_dem
from toolbox.raster.writer import write_raster

GDALWARP = shutil.which("gdalwarp")
needs_gdalwarp = pytest.mark.skipif(GDALWARP is None, reason="gdalwarp (GDAL's CLI) not found")
NODATA = -9999.0


def write_ramp(path: Path, rpcs: RPC, width: int, height: int) -> Path:
    cols, rows = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    with rasterio.open(path, "w", driver="GTiff", width=width, height=height, count=2,
                       dtype="float32", rpcs=rpcs) as dst:
        dst.write(np.stack([cols, rows]).astype("float32"))
    return path


def gdal_ortho(ramp: Path, dem: Path, like: Path, out: Path) -> np.ndarray:
    """GDAL's RPC warp of ``ramp`` onto the grid of ``like`` (exact transformer, bilinear, the
    DEM's heights as they are)."""
    with rasterio.open(like) as src:
        b, res, wkt = src.bounds, src.res, src.crs.to_wkt()
    srs = out.with_suffix(".wkt")
    srs.write_text(wkt)
    subprocess.run([GDALWARP, "-q", "-overwrite", "-rpc", "-to", f"RPC_DEM={dem}", "-to",
                    "RPC_DEM_APPLY_VDATUM_SHIFT=FALSE", "-t_srs", str(srs), "-te",
                    *map(repr, (b.left, b.bottom, b.right, b.top)), "-tr", *map(repr, res),
                    "-r", "bilinear", "-et", "0", "-dstnodata", str(NODATA), "-wt", "Float32",
                    str(ramp), str(out)], check=True, capture_output=True)
    with rasterio.open(out) as src:
        return src.read().astype("float64")


def disagreement(a: np.ndarray, b: np.ndarray, size: tuple[int, int]) -> tuple[float, int, int]:
    """Largest |ours - GDAL's| (px) over the cells both map inside the image (one pixel in from
    its edges: the ramp is linear there), the cells compared, and the cells only one maps."""
    w, h = size
    seen_a, seen_b = a[0] != NODATA, b[0] != NODATA
    ok = seen_a & seen_b & (a[0] > 1) & (a[0] < w - 1) & (a[1] > 1) & (a[1] < h - 1)
    return float(np.abs(a[:2, ok] - b[:2, ok]).max()), int(ok.sum()), int((seen_a != seen_b).sum())


def synthetic_rpc(dx: float = 0.0, dy: float = 0.0, scale: float = 1.0) -> RPC:
    """A 1200 x 1000 px RPC near (11 E, 45 N); ``scale``, ``dx``, ``dy``: the image-space
    affinity col' = scale·col + dx (rows likewise) folded into the offsets and scales."""
    num_s, num_l = np.zeros(20), np.zeros(20)
    num_s[[1, 2, 3, 4, 7]] = [1.0, 0.05, 0.02, 0.01, -0.003]
    num_l[[1, 2, 3, 6, 8]] = [-0.04, -1.0, 0.03, 0.005, 0.002]
    den = np.zeros(20)
    den[[0, 1, 2]] = [1.0, 0.001, -0.002]
    # product pixel = s·(v·S + off + 0.5) + d  =>  off' = s·off + 0.5·s + d - 0.5, S' = s·S
    return RPC(height_off=500.0, height_scale=400.0, lat_off=45.0, lat_scale=0.05,
               line_den_coeff=den.tolist(), line_num_coeff=num_l.tolist(),
               line_off=scale * 500.0 + 0.5 * scale + dy - 0.5, line_scale=scale * 520.0,
               long_off=11.0, long_scale=0.07, samp_den_coeff=den.tolist(),
               samp_num_coeff=num_s.tolist(), samp_off=scale * 600.0 + 0.5 * scale + dx - 0.5,
               samp_scale=scale * 620.0)


def write_synthetic_dem(path: Path) -> Path:
    """A hilly DEM (EPSG:32632, heights ellipsoidal as RPCs expect) under :func:`synthetic_rpc`."""
    z, transform = hills_dem((650000.0, 4977000.0, 665000.0, 4993000.0), cell=30.0,
                             relief=600.0, base=200.0, seed=5)
    write_raster(path, z, transform, "EPSG:32632", nodata=NODATA)
    return path


def write_gcps(folder: Path, camera, image: str, n: int, seed: int) -> tuple[Path, Path]:
    """``n`` GCPs: ground points on the DEM's area, their pixels through ``camera`` (the truth),
    as CONTROL (id, X, Y, Z) and MEASUREMENTS (point_id, photo, col_px, row_px) CSVs."""
    rng = np.random.default_rng(seed)
    px = np.column_stack([rng.uniform(100, 1100, n), rng.uniform(100, 900, n)])
    z = rng.uniform(250, 700, n)
    ground = camera.pixel_to_ground(px, z)
    control = folder / "control.csv"
    control.write_text("id,X,Y,Z\n" + "".join(f"g{k},{x:.6f},{y:.6f},{h:.6f}\n"
                                              for k, (x, y, h) in enumerate(ground)))
    measured = folder / "measurements.csv"
    measured.write_text("point_id,photo,col_px,row_px\n" + "".join(
        f"g{k},{image},{c:.6f},{r:.6f}\n" for k, (c, r) in enumerate(px)))
    return control, measured
