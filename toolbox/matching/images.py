"""Reading photos for matching: a reduced level (decimated read, bounded memory) and
full-resolution windows, as 8-bit grey levels.

Pixel convention: (col, row) with the top-left pixel's centre at (0.5, 0.5). A level of
``scale`` s maps full-resolution pixel coordinates ``u`` to level coordinates ``u / s``
(corner-based, so centres map to centres for integer decimation).
"""

from __future__ import annotations

import threading
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.matching.positions import exif_lonlat
from toolbox.raster.photo_grid import open_photo_grid, warn_orientation_tag


@contextmanager
def _quiet():
    """Scans carry no georeferencing: silence rasterio's warning about it."""
    import rasterio

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        yield


@dataclass
class ImageSource:
    """A photo on disk: size, bands and data type, read lazily.

    ``stretch`` maps the raw values to 0..255 (``(low, high)``); computed from the first level
    read (2 and 98 percentiles) unless the file is 8-bit.
    """

    path: Path
    width: int
    height: int
    bands: int
    dtype: str
    stretch: tuple[float, float] | None = None
    lonlat: tuple[float, float] | None = None  # EXIF GPS position (degrees), when tagged
    _grey_full: np.ndarray | None = field(default=None, repr=False)
    _handle: Any = field(default=None, repr=False)  # the open dataset of window reads
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    #: photos up to this many pixels are held whole in memory (grey, 1 byte a pixel) once a
    #: window is asked for; bigger ones are read window by window
    WHOLE_LIMIT = 16_000_000

    @classmethod
    def open(cls, path: str | Path, name: str = "photo") -> ImageSource:
        import rasterio

        path = Path(path)
        if not path.exists():
            raise InputDataError(f"{name}: image {path} does not exist")
        try:
            with _quiet(), open_photo_grid(path) as src:
                info = cls(path, src.width, src.height, src.count, src.dtypes[0])
                info.lonlat = exif_lonlat(src.tags())
                warn_orientation_tag(src, path, name)
                bits = src.tags(1, "IMAGE_STRUCTURE").get("NBITS")
        except rasterio.errors.RasterioError as exc:
            raise InputDataError(f"{name}: cannot read image {path}: "
                                 f"{str(exc).splitlines()[0]}") from None
        if info.dtype == "uint8":  # a 1..7-bit grey one (no colour table): its full range
            info.stretch = (0.0, float(2 ** int(bits) - 1) if bits and 0 < int(bits) < 8
                            else 255.0)
        return info

    def scale_for(self, max_size: int) -> float:
        """Decimation factor (>= 1) so that the longer side fits in ``max_size`` pixels."""
        return max(1.0, max(self.width, self.height) / float(max_size))

    def _grey(self, data: np.ndarray) -> np.ndarray:
        data = data.astype("float32")
        grey = data[:3].mean(axis=0) if data.shape[0] >= 3 else data[0]
        if self.stretch is None:
            lo, hi = np.percentile(grey, (2, 98)) if grey.size else (0.0, 1.0)
            self.stretch = (float(lo), float(max(hi, lo + 1.0)))
        lo, hi = self.stretch
        return np.clip((grey - lo) * (255.0 / (hi - lo)), 0, 255).astype(np.uint8)

    def level(self, scale: float) -> tuple[np.ndarray, tuple[float, float]]:
        """The whole photo decimated by about ``scale`` (>= 1; area average), grey uint8, and
        the exact factors ``(sx, sy)`` (full-resolution pixels per level pixel)."""
        from rasterio.enums import Resampling

        w = max(1, int(round(self.width / scale)))
        h = max(1, int(round(self.height / scale)))
        with _quiet(), open_photo_grid(self.path) as src:  # never an overview
            data = src.read(out_shape=(self.bands, h, w),
                            resampling=Resampling.average if scale > 1 else Resampling.nearest)
        return self._grey(data), (self.width / w, self.height / h)

    def __getstate__(self) -> dict:
        """Pickled for a Dask worker: the path, size and stretch; no open dataset, lock or
        whole-photo copy (the worker reads its own)."""
        state = dict(self.__dict__)
        state.update(_handle=None, _grey_full=None)
        del state["_lock"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()

    def close(self) -> None:
        """Release the dataset of window reads and the whole-photo copy (reopened on demand)."""
        with self._lock:
            if self._handle is not None:
                self._handle.close()
                self._handle = None
            self._grey_full = None

    def window(self, col0: int, row0: int, width: int, height: int) -> np.ndarray:
        """Full-resolution grey window (pixels outside the image are 0), shape (height, width)."""
        from rasterio.windows import Window

        if self.width * self.height <= self.WHOLE_LIMIT:
            if self._grey_full is None:
                self._grey_full = self.level(1.0)[0]
            out = np.zeros((height, width), np.uint8)
            c0, r0 = max(0, col0), max(0, row0)
            c1, r1 = min(self.width, col0 + width), min(self.height, row0 + height)
            if c1 > c0 and r1 > r0:
                out[r0 - row0:r1 - row0, c0 - col0:c1 - col0] = self._grey_full[r0:r1, c0:c1]
            return out
        # clipped read and zero padding (rasterio's boundless reads go through a VRT that
        # misplaces windows of images with a rotated geotransform)
        c0, r0 = max(0, col0), max(0, row0)
        c1, r1 = min(self.width, col0 + width), min(self.height, row0 + height)
        data = np.zeros((self.bands, height, width), dtype=self.dtype)
        if c1 > c0 and r1 > r0:
            # one dataset kept open (its block cache serves neighbouring windows): reopening
            # the file for every window cost more than the reads of a refinement pass
            with self._lock, _quiet():
                if self._handle is None:
                    self._handle = open_photo_grid(self.path)
                data[:, r0 - row0:r1 - row0, c0 - col0:c1 - col0] = self._handle.read(
                    window=Window(c0, r0, c1 - c0, r1 - r0))
        if self.stretch is None:
            self.level(self.scale_for(1024))  # sets the stretch
        return self._grey(data)
