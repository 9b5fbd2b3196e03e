"""Resampling a source window at given coordinates with OpenCV: ``cv2.remap`` and
``cv2.warpPerspective`` for any dtype and band count, the photo's edge replicated, OpenCV kept
single-threaded inside the engine's threads, the inside test of a map.

OpenCV samples pixel centres at integers: a map handed to these functions is already in
OpenCV's convention (source coordinate - 0.5 - window offset, see :mod:`toolbox.raster.maps`).
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

RESAMPLING_METHODS = ("nearest", "bilinear", "cubic", "lanczos")
# not OpenCV's: :mod:`toolbox.raster.quadratic` (the thesis' quadratic, for orthophotos)
EXTRA_RESAMPLING = ("quadratic",)
# source pixels needed beyond the bounding box of the sample points, per method (kernel radius)
RESAMPLING_MARGIN = {"nearest": 1, "bilinear": 1, "cubic": 2, "lanczos": 4, "quadratic": 2}
CV2_DTYPES = ("uint8", "uint16", "int16", "float32", "float64")


_OPENCV_LOCK = threading.Lock()
_OPENCV_USERS = [0, 0]  # blocks inside single_threaded_opencv, OpenCV's setting before them


@contextmanager
def single_threaded_opencv() -> Iterator[None]:
    """Run OpenCV single-threaded inside the block: warps whose tiles already run on one
    thread per core (the raster engine's) would otherwise put OpenCV's own pool to work on top
    of them, more threads than cores. OpenCV's setting is process-wide: blocks may overlap
    (photos of a block on threads), and the setting before the first comes back after the
    last."""
    import cv2

    with _OPENCV_LOCK:
        if _OPENCV_USERS[0] == 0:
            _OPENCV_USERS[1] = cv2.getNumThreads()
            cv2.setNumThreads(1)
        _OPENCV_USERS[0] += 1
    try:
        yield
    finally:
        with _OPENCV_LOCK:
            _OPENCV_USERS[0] -= 1
            if _OPENCV_USERS[0] == 0:
                cv2.setNumThreads(_OPENCV_USERS[1])


def cv2_interpolation(resampling: str) -> int:
    """The OpenCV interpolation flag of a resampling name (see :data:`RESAMPLING_METHODS`)."""
    import cv2

    flags = {"nearest": cv2.INTER_NEAREST, "bilinear": cv2.INTER_LINEAR,
             "cubic": cv2.INTER_CUBIC, "lanczos": cv2.INTER_LANCZOS4}
    if resampling not in flags:
        raise ValueError(f"resampling must be one of {', '.join(RESAMPLING_METHODS)}, "
                         f"got {resampling!r}")
    return flags[resampling]


def inside_mask(cols: np.ndarray, rows: np.ndarray, width: int, height: int,
                col_shift: float = 0.0, row_shift: float = 0.0) -> np.ndarray:
    """Output pixels whose centre maps into the photo ``[0, width] x [0, height]`` (NaN: no).

    ``cols``/``rows`` may be given shifted (``cols - col_shift``...), as the cv2 maps are.
    """
    inside = cols >= np.float32(-col_shift)
    inside &= cols <= np.float32(width - col_shift)
    inside &= rows >= np.float32(-row_shift)
    inside &= rows <= np.float32(height - row_shift)
    return inside


def remap(source: np.ndarray, map_x: np.ndarray, map_y: np.ndarray,
          resampling: str = "bilinear", border: float = 0) -> np.ndarray:
    """Sample ``source`` at OpenCV map coordinates (pixel centres at integers).

    ``source`` is (rows, cols) or (rows, cols, bands) of any numeric dtype (OpenCV handles
    uint8, uint16, int16, float32 and float64 directly; other types go through float64 and are
    rounded back). Any number of bands (OpenCV takes at most 4 at a time). Outside the source
    the value is ``border`` (``cv2.BORDER_CONSTANT``, which OpenCV skips quickly); callers that
    need the photo's edge pixels extended pad the source first (see
    :func:`pad_at_photo_edges`).
    """
    import cv2

    if resampling == "quadratic":
        from toolbox.raster.quadratic import remap_quadratic

        return remap_quadratic(source, map_x, map_y)
    flag = cv2_interpolation(resampling)
    value = (float(border),) * 4
    return by_four_bands(source, lambda part: cv2.remap(part, map_x, map_y, flag,
                                                         borderMode=cv2.BORDER_CONSTANT,
                                                         borderValue=value))


def by_four_bands(source: np.ndarray, warp_one) -> np.ndarray:
    """``warp_one`` (an OpenCV warp of a (rows, cols[, <= 4 bands]) array) applied to
    ``source`` of any dtype and band count: types OpenCV lacks go through float64 and are rounded
    back, bands go 4 at a time, and the trailing band axis OpenCV drops is restored."""
    dtype = source.dtype
    work = source if dtype.name in CV2_DTYPES else source.astype("float64")

    def one(part: np.ndarray) -> np.ndarray:
        res = warp_one(part)
        return res[:, :, None] if part.ndim == 3 and res.ndim == 2 else res

    if work.ndim == 2 or work.shape[2] <= 4:
        out = one(work)
    else:
        out = np.concatenate([one(np.ascontiguousarray(work[:, :, k:k + 4]))
                              for k in range(0, work.shape[2], 4)], axis=2)
    if out.dtype != dtype:
        if dtype.kind in "iu":
            info = np.iinfo(dtype)
            out = np.clip(np.rint(out), info.min, info.max)
        out = out.astype(dtype)
    return out


def pad_at_photo_edges(pixels: np.ndarray, pads: tuple[int, int, int, int]) -> np.ndarray:
    """Replicate the edge pixels of ``pixels`` ((h, w) or (h, w, bands)) outwards by ``pads`` =
    (top, bottom, left, right) pixels; unchanged when every pad is 0."""
    import cv2

    if not any(pads):
        return pixels
    top, bottom, left, right = pads
    if pixels.dtype.name in CV2_DTYPES + ("int8", "int32"):
        return cv2.copyMakeBorder(pixels, top, bottom, left, right, cv2.BORDER_REPLICATE)
    widths = ((top, bottom), (left, right)) + (((0, 0),) if pixels.ndim == 3 else ())
    return np.pad(pixels, widths, mode="edge")


def interleave(data: np.ndarray) -> np.ndarray:
    """(bands, h, w) -> (h, w) or pixel-interleaved (h, w, bands) for OpenCV."""
    import cv2

    if data.shape[0] == 1:
        return data[0]
    if data.shape[0] <= 4 and data.dtype.name in CV2_DTYPES:
        return cv2.merge(list(data))
    return np.ascontiguousarray(np.moveaxis(data, 0, -1))


def deinterleave(sampled: np.ndarray, out: np.ndarray) -> None:
    """Copy (h, w) or (h, w, bands) ``sampled`` into band-sequential ``out`` (bands, h, w)."""
    import cv2

    if sampled.ndim == 2:
        out[0] = sampled
    elif sampled.shape[2] <= 4 and sampled.dtype.name in CV2_DTYPES and out.flags.c_contiguous:
        cv2.split(sampled, list(out))
    else:
        for k in range(sampled.shape[2]):
            out[k] = sampled[:, :, k]


def warp_perspective(source: np.ndarray, matrix: np.ndarray, size: tuple[int, int],
                     resampling: str = "bilinear", border: float = 0) -> np.ndarray:
    """``cv2.warpPerspective`` with ``WARP_INVERSE_MAP`` (``matrix``: output pixel index ->
    OpenCV source coordinates), ``border`` outside the source, any dtype and band count (as
    :func:`remap`). ``size`` is (width, height) of the output."""
    import cv2

    flag = cv2_interpolation(resampling) | cv2.WARP_INVERSE_MAP
    value = (float(border),) * 4
    return by_four_bands(source, lambda part: cv2.warpPerspective(
        part, matrix, size, flags=flag, borderMode=cv2.BORDER_CONSTANT, borderValue=value))
