"""Vertical datums of the DEM and of the photos' heights (:func:`dem_for_photos`).

A DEM's CRS may carry a vertical datum (a compound CRS: UTM + EGM2008 height), and so may the
orientation's (a compound project ``crs``, a 3D CRS with ellipsoidal heights, or ``HEIGHTS``
of the ortho algorithms). Same datum, or one side silent: the DEM is used as it is (the fast
path: a vertical datum moves no cell, :func:`toolbox.io.crs.one_horizontal_crs`), and the
report says which. Different datums: the DEM's heights are converted ONCE with pyproj into a
temporary DEM of the photos' datum (the shift ``h' - h`` taken on a lattice of every 16th cell
and interpolated, checked to 1 mm at the lattice cells' centres, else computed at every cell).
A conversion that needs a PROJ grid missing here (EGM2008's ``us_nga_egm08_25.tif``...) is
refused naming the grid and how to install it; a "ballpark" operation (one that ignores the
geoid) is never used.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ParameterError
from toolbox.io.crs import (  # noqa: F401 - the height datums' CRS helpers, also here
    ELLIPSOIDAL,
    SYSTEM_GRID_DIRS,
    datum_label,
    horizontal_part,
    is_ellipsoidal,
    same_datum,
    use_system_grids,
    vertical_part,
)
from toolbox.io.raster import read_filled

SHIFT_TOLERANCE_M = 1e-3
ROWS_PER_BLOCK = 512


def project_raster_crs(project_crs: Any, raster_crs: Any, name: str = "DEM",
                       heights: bool = True, bounds: Any = None) -> Any:
    """The CRS of an orientation project used with a raster ``name`` of its area (a DEM, an
    orthophoto): their horizontal parts must be the same CRS (a vertical datum adds heights, it
    does not move the cells: a DEM published as 'projected + EGM2008 height' is in the project's
    'projected' CRS); with ``heights``, datums stated by both must agree (the DEM's heights are
    taken as the orientation's; ortho:photo and ortho:batch convert them). A CRS missing on
    either side is the other's, as :func:`toolbox.io.crs.common_crs` has it; two definitions
    of one CRS (an ESRI WKT and its EPSG code) are one (the raster's extent, ``bounds``, moves
    by at most 1 mm from one to the other: :func:`toolbox.io.crs.one_crs`)."""
    from toolbox.io.crs import common_crs

    if project_crs is None or raster_crs is None:
        return common_crs({"PROJECT": project_crs, name: raster_crs})
    common_crs({"PROJECT": horizontal_part(project_crs), name: horizontal_part(raster_crs)},
               bounds={name: bounds})
    ours, theirs = vertical_part(project_crs), vertical_part(raster_crs)
    if heights and ours is not None and theirs is not None and not same_datum(ours, theirs):
        raise InputDataError(f"{name} heights are {datum_label(theirs)} but PROJECT's are "
                             f"{datum_label(ours)}: convert the {name}'s heights to the "
                             "project's first (ortho:photo and ortho:batch convert them)")
    return project_crs


def parse_heights(value: Any, name: str = "HEIGHTS") -> Any:
    """``ellipsoidal`` or a vertical CRS (``EPSG:3855``; a compound CRS gives its vertical
    part) -> what :func:`vertical_part` returns; ParameterError naming ``name``."""
    if value is None or str(value).strip() == "":
        return None
    if str(value).strip().lower() == ELLIPSOIDAL:
        return ELLIPSOIDAL
    from toolbox.io.crs import parse_crs

    vertical = vertical_part(parse_crs(value, name))
    if vertical is None:
        raise ParameterError(name, f"{value!r} is not a vertical CRS (expected 'ellipsoidal', "
                             "a vertical CRS such as EPSG:3855 (EGM2008 height), or a compound "
                             "CRS)")
    return vertical


@dataclass
class HeightsNote:
    """What was done with the DEM's heights (the run report's ``heights``)."""

    dem: str
    photos: str
    converted: bool
    text: str
    operation: str | None = None
    shift_m: list[float] | None = None  # min, max of the conversion's h' - h
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        out = {"dem_datum": self.dem, "photos_datum": self.photos, "converted": self.converted,
               "note": self.text}
        if self.operation is not None:
            out.update(operation=self.operation, shift_m=self.shift_m)
        if "geoid_separation_m" in self.extra:
            out["geoid_separation_m"] = self.extra["geoid_separation_m"]
        return out


def height_transformer(source: Any, target: Any, dem_label: str, photos_label: str) -> Any:
    """The best *available* pyproj transformer source -> target (always_xy) that really
    changes the height datum; InputDataError naming the missing PROJ grid(s) otherwise."""
    import warnings

    from pyproj.transformer import TransformerGroup

    use_system_grids()
    with warnings.catch_warnings():  # "best transformation is not available": handled below
        warnings.simplefilter("ignore", UserWarning)
        group = TransformerGroup(source, target, always_xy=True)
    for transformer in group.transformers:
        if "ballpark" not in transformer.description.lower():
            return transformer
    grids = sorted({g.short_name for op in group.unavailable_operations for g in op.grids
                    if not g.available}, key=lambda name: (not name.endswith(".tif"), name))
    if grids:
        import pyproj.datadir

        raise InputDataError(
            f"DEM heights are {dem_label}, the photos' {photos_label}: converting them needs "
            f"the PROJ grid {' or '.join(grids)}, not on this machine; install it with "
            f"'projsync --file {grids[0]}' (or download https://cdn.proj.org/{grids[0]} into "
            f"{pyproj.datadir.get_user_data_dir()}), or give a DEM in the photos' datum (or "
            f"HEIGHTS as the DEM's datum to take its heights as they are)")
    raise InputDataError(f"DEM heights are {dem_label}, the photos' {photos_label}: PROJ knows "
                         "no transformation between these height datums; give a DEM in the "
                         "photos' datum")


class _Shift:
    """pyproj-like ``transform(x, y) -> (h' - h, 0)`` at height ``z`` (for
    :func:`toolbox.ortho.dem.lattice_transform`)."""

    def __init__(self, transformer: Any, z: float):
        self.transformer, self.z = transformer, z

    def transform(self, x: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(x, dtype="float64")
        z = np.full(x.shape, self.z)
        _, _, h = self.transformer.transform(x, np.asarray(y, dtype="float64"), z)
        return np.asarray(h) - z, np.zeros(x.shape)


def dem_for_photos(info: Any, photos_vertical: Any, folder: Path, band: int = 1
                   ) -> tuple[Any, HeightsNote]:
    """The DEM to orthorectify with, in the photos' height datum, and what was done.

    ``photos_vertical``: :func:`vertical_part` of the orientation (None: not stated). When both
    datums are known and differ, the band ``band`` is converted into ``folder/dem_heights.tif``
    (float32, the DEM's horizontal CRS + the photos' vertical) and that RasterInfo returned."""
    dem_vertical = vertical_part(info.crs)
    dem_label, photos_label = datum_label(dem_vertical), datum_label(photos_vertical)
    if dem_vertical is None or photos_vertical is None:
        text = ("no height datum stated by the DEM or the orientation: heights used as they are"
                if dem_vertical is None and photos_vertical is None else
                f"heights used as they are: the DEM's are {dem_label}, the orientation states "
                f"none (give HEIGHTS to have them converted)" if photos_vertical is None else
                f"heights used as they are: the photos' are {photos_label}, the DEM states no "
                "datum (tag its CRS with its vertical datum to have them converted)")
        note = HeightsNote(dem_label, photos_label, False, text)
        if (dem_vertical is None) != (photos_vertical is None):  # one side silent: warned
            note.extra["warning"] = True
            if is_ellipsoidal(dem_vertical) or is_ellipsoidal(photos_vertical):
                n = geoid_separation(info.crs, *_centre(info))
                if n is not None:
                    note.extra["geoid_separation_m"] = round(n, 3)
                    note.text += (f"; if the other side's heights are orthometric they differ "
                                  f"from ellipsoidal ones by the geoid undulation, {n:.1f} m "
                                  "here (EGM96): the ortho would be displaced accordingly")
        return info, note
    if same_datum(dem_vertical, photos_vertical):
        return info, HeightsNote(dem_label, photos_label, False,
                                 f"DEM and photos both in {dem_label}: no conversion")
    from pyproj import CRS
    from pyproj.crs import CompoundCRS

    horizontal = horizontal_part(info.crs)

    def with_datum(vertical: Any) -> Any:
        if is_ellipsoidal(vertical):
            return horizontal.to_3d()
        return CompoundCRS(f"{horizontal.name} + {vertical.name}", [horizontal, vertical])

    transformer = height_transformer(with_datum(dem_vertical), with_datum(photos_vertical),
                                     dem_label, photos_label)
    out_crs = horizontal if is_ellipsoidal(photos_vertical) else with_datum(photos_vertical)
    path = Path(folder) / "dem_heights.tif"
    low, high = _convert(info, band, transformer, path, CRS.from_user_input(out_crs))
    from toolbox.io.raster import open_raster_info

    note = HeightsNote(dem_label, photos_label, True,
                       f"DEM heights converted once from {dem_label} to the photos' "
                       f"{photos_label} ({transformer.description}; shift {low:+.3f} .. "
                       f"{high:+.3f} m)", transformer.description, [low, high])
    return open_raster_info(path, "DEM"), note


def _centre(info: Any) -> tuple[float, float]:
    t = info.transform
    return t.c + t.a * info.width / 2 + t.b * info.height / 2, \
        t.f + t.d * info.width / 2 + t.e * info.height / 2


def geoid_separation(crs: Any, x: float, y: float) -> float | None:
    """The EGM96 geoid undulation N (ellipsoidal minus orthometric height, metres) at (x, y) of
    ``crs``, None when the EGM96 grid (egm96_15.gtx) is not installed or the point is not
    placed (no CRS)."""
    import warnings

    from pyproj import Transformer

    from toolbox.io.crs import parse_crs

    if crs is None:
        return None
    try:
        use_system_grids()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            lon, lat = Transformer.from_crs(horizontal_part(parse_crs(crs)), "EPSG:4326",
                                            always_xy=True).transform(x, y)
            geoid = Transformer.from_crs("EPSG:4979", "EPSG:4326+5773", always_xy=True)
            height = geoid.transform(lon, lat, 0.0, errcheck=True)[2]
            if "ballpark" in geoid.get_last_used_operation().description.lower():
                return None
    except Exception:  # noqa: BLE001 - no grid, no place: the warning says no number
        return None
    return -float(height) if np.isfinite(height) and height != 0.0 else None


def _convert(info: Any, band: int, transformer: Any, path: Path, crs: Any
             ) -> tuple[float, float]:
    """Write the converted DEM block of rows by block; the shift's (min, max), metres."""
    import rasterio
    from rasterio.windows import Window

    from toolbox.io.grid import GridSpec
    from toolbox.ortho.dem import lattice_transform
    from toolbox.raster.writer import RasterWriter

    t = info.transform
    if t.b != 0 or t.d != 0:
        raise InputDataError(f"DEM {info} must be north-up (no rotation) to convert its heights")
    xs = t.c + (np.arange(info.width) + 0.5) * t.a
    low, high = np.inf, -np.inf
    grid = GridSpec(t, info.width, info.height, crs)
    # a scratch file read by the ortho's DEM sampler: no overviews
    with rasterio.open(info.path) as src, \
            RasterWriter(path, grid, 1, "float32", float("nan"), overviews=False) as dst:
        for r0 in range(0, info.height, ROWS_PER_BLOCK):
            rows = min(ROWS_PER_BLOCK, info.height - r0)
            window = Window(0, r0, info.width, rows)
            z = read_filled(src, band, window)
            if not np.isfinite(z).any():
                dst.write(window, z)
                continue
            ys = t.f + (np.arange(r0, r0 + rows) + 0.5) * t.e
            shift, _ = lattice_transform(_Shift(transformer, float(np.nanmean(z))), xs, ys,
                                         SHIFT_TOLERANCE_M)
            shift = shift.reshape(z.shape)
            if not np.isfinite(shift).all():
                raise InputDataError(f"DEM {info}: the height datum conversion "
                                     f"({transformer.description}) has no value over part of "
                                     "the DEM (outside its grid's area)")
            finite = np.isfinite(z)
            low, high = min(low, float(shift[finite].min())), max(high, float(shift[finite].max()))
            dst.write(window, z + shift)
    return low, high


@contextmanager
def dem_in_photo_datum(dem: Any, band: int, heights: str | None, crs: Any, feedback: Any,
                       executor: Any = None, output: Any = None
                       ) -> Iterator[tuple[Any, int, HeightsNote]]:
    """(DEM, band, note) for the ortho algorithms: the DEM in the orientation's height datum
    (``heights``, the HEIGHTS parameter, else the vertical part of the orientation's ``crs``),
    converted once into a temporary file removed on exit when the datums differ
    (:func:`dem_for_photos`); the note is pushed as information, as a warning when one side
    states a datum and the other none (taken as the same). On a Dask cluster (``executor``)
    the temporary file goes beside ``output`` (its staging folder, on the storage the workers
    share: they read a DEM too large to preload themselves), else in the system's temp."""
    import tempfile

    photos = parse_heights(heights) or vertical_part(crs)
    scratch = None
    if executor is not None and executor.kind == "dask" and output is not None:
        scratch = Path(output).expanduser().absolute().parent
    with tempfile.TemporaryDirectory(prefix=".toolbox-heights-" if scratch else
                                     "toolbox-heights-", dir=scratch) as folder:
        out, note = dem_for_photos(dem, photos, Path(folder), band)
        if note.extra.get("warning"):  # one datum stated, the other silent: taken as equal
            feedback.push_warning(note.text)
        else:
            feedback.push_info(note.text)
        yield out, 1 if note.converted else band, note
