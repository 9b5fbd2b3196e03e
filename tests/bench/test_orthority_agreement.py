"""The agreement measures of bench/orthority_bench.py (bench/orthority_agreement.py) on known
truth: a textured image moved by a known sub-pixel amount with scipy's Fourier shift theorem
(an independent way to make the shift), and known DN differences."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

from orthority_agreement import compare_arrays, compare_files  # noqa: E402


def texture(shape=(256, 320), seed=1) -> np.ndarray:
    """Smooth random texture, about 0..255 (band-limited: a Fourier shift of it is exact)."""
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    t = gaussian_filter(rng.normal(size=shape), 2.0)
    return 127.5 + 127.5 * t / np.abs(t).max()


def moved(image: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """``image``'s content moved by dx columns right and dy rows down (periodic)."""
    from scipy.ndimage import fourier_shift

    return np.fft.ifftn(fourier_shift(np.fft.fftn(image), (dy, dx))).real


@pytest.mark.parametrize("dx, dy", [(0.37, -0.23), (-0.05, 0.11), (0.0, 0.0), (1.26, 0.5)])
def test_known_subpixel_shift_recovered(dx, dy):
    a = texture()
    b = moved(a, dx, dy)
    valid = np.ones(a.shape, bool)
    got = compare_arrays(a[None], b[None], valid)
    assert got.patches == 12  # 3 x 4 patches of 64 cells inside a 4-cell margin
    assert got.shift_median[0] == pytest.approx(dx, abs=0.01)
    assert got.shift_median[1] == pytest.approx(dy, abs=0.01)
    assert got.shift_max == pytest.approx(np.hypot(dx, dy), abs=0.01)


def test_mean_abs_dn_over_valid_cells_only():
    a = np.tile(texture()[None], (3, 1, 1))
    b = a.copy()
    b[0] += 0.6  # band 0 off by 0.6 DN: mean over 3 bands 0.2
    valid = np.ones(a.shape[1:], bool)
    valid[:, :40] = False
    b[:, :, :40] += 100.0  # differences outside the valid cells do not count
    got = compare_arrays(a, b, valid)
    assert got.cells == valid.sum()
    assert got.mean_abs_dn == pytest.approx(0.2, abs=1e-9)
    assert got.mean_abs_dn_inner == pytest.approx(0.2, abs=1e-9)
    assert got.shift_max < 0.01


def test_files_on_one_lattice_compared_on_common_window(tmp_path):
    """Two GeoTIFFs of different extents on one lattice: the common window is found (a one-cell
    misregistration of the windows would show as a shift of 1), masks respected."""
    import rasterio
    from rasterio.transform import from_origin

    base = np.clip(texture((300, 300)), 0, 255).round().astype("uint8")
    cell = 5.0
    # a: rows/cols 0..255 of base; b: rows 20..299, cols 10..289, with an alpha band
    with rasterio.open(tmp_path / "a.tif", "w", driver="GTiff", width=256, height=256, count=3,
                       dtype="uint8", transform=from_origin(1000, 2000, cell, cell),
                       crs="EPSG:32633", nodata=0) as dst:
        dst.write(np.repeat(base[None, :256, :256], 3, axis=0))
    alpha = np.full((280, 280), 255, "uint8")
    alpha[:, :30] = 0
    b = np.concatenate([np.repeat(base[None, 20:300, 10:290], 3, axis=0), alpha[None]])
    with rasterio.open(tmp_path / "b.tif", "w", driver="GTiff", width=280, height=280, count=4,
                       dtype="uint8", transform=from_origin(1000 + 10 * cell, 2000 - 20 * cell,
                                                            cell, cell),
                       crs="EPSG:32633", photometric="RGB", alpha="YES") as dst:
        dst.write(b)
    got = compare_files(tmp_path / "b.tif", tmp_path / "a.tif")
    assert got.mean_abs_dn == 0.0
    assert got.shift_max < 0.01 and got.patches > 0
    # common window 236 x 246 cells, minus b's 30 transparent columns and a's zero cells
    assert got.cells <= 236 * (246 - 30)
    with rasterio.open(tmp_path / "c.tif", "w", driver="GTiff", width=256, height=256, count=3,
                       dtype="uint8", transform=from_origin(1002, 2000, cell, cell),
                       crs="EPSG:32633") as dst:
        dst.write(np.repeat(base[None, :256, :256], 3, axis=0))
    with pytest.raises(ValueError, match="lattice"):
        compare_files(tmp_path / "c.tif", tmp_path / "a.tif")
