"""The report:ortho_check job: check points measured on an orthophoto from files (the project,
the check points' ground coordinates and image measurements, the orthophoto); the measuring
itself is :mod:`.quality_ortho`."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolbox.cartography.quality_ortho import (
    OUTSIDE,
    CheckResult,
    match_offset,
    ortho_window,
    photo_chip,
)
from toolbox.errors import InputDataError, ParameterError


@dataclass
class OrthoCheckRequest:
    """What to measure: ``chip_m`` half size of the reference chip and ``search_m`` the largest
    offset looked for, both in ground units (0: 12 and 8 orthophoto cells); ``photo`` the photo
    to take the chips from (None: per point, the measuring photo where it is nearest the image
    centre)."""

    ortho: Path
    project: Path
    check_points: Path
    measurements: Path
    photo: str | None = None
    chip_m: float = 0.0
    search_m: float = 0.0
    min_score: float = 0.6
    dem: Path | None = None  # the orthophoto's DEM: each point's Z is compared with it


def _grey(data: np.ndarray) -> np.ndarray:
    data = data.astype("float32")
    return data[:3].mean(axis=0) if data.shape[0] >= 3 else data[0]


def _ortho_patch(src, x: float, y: float, cell: float, half: int
                 ) -> tuple[np.ndarray, object]:
    """The grey cells (NaN = no data) of the open orthophoto ``src`` that :func:`ortho_window`
    samples around (x, y) for ``half`` cells of ``cell`` (3 cells to spare, clipped to the
    raster), and their transform: one window per check point, not the whole orthophoto in
    memory (a 40,000 x 40,000-cell RGB orthophoto is 19 GB as float32)."""
    import math

    from rasterio.windows import Window

    from toolbox.io.raster import read_dataset_masked

    t = src.transform
    col, row = ~t * (x, y)
    pc = int(math.ceil(half * cell / abs(t.a))) + 3
    pr = int(math.ceil(half * cell / abs(t.e))) + 3
    c0, r0 = max(int(math.floor(col)) - pc, 0), max(int(math.floor(row)) - pr, 0)
    c1 = min(int(math.floor(col)) + pc + 1, src.width)
    r1 = min(int(math.floor(row)) + pr + 1, src.height)
    if c1 <= c0 or r1 <= r0:  # wholly outside: every sample NaN
        return np.full((1, 1), np.nan, "float32"), t
    window = Window(c0, r0, c1 - c0, r1 - r0)
    data = read_dataset_masked(src, window=window).astype("float32").filled(np.nan)
    return _grey(data), src.window_transform(window)


def _photo_reader(path: Path):
    """``read_window(c0, r0, c1, r1)`` of a photo file: grey float window clipped to the image
    and its origin (col, row)."""
    from rasterio.windows import Window

    from toolbox.raster.photo_grid import open_photo_grid

    def read(c0: int, r0: int, c1: int, r1: int):
        with open_photo_grid(path) as src:  # the grid the ortho was made from: its colours
            c0c, r0c = max(c0, 0), max(r0, 0)
            c1c, r1c = min(c1, src.width), min(r1, src.height)
            if c1c <= c0c or r1c <= r0c:
                return None, (c0c, r0c)
            data = src.read(window=Window(c0c, r0c, c1c - c0c, r1c - r0c))
        return _grey(data), (c0c, r0c)

    return read


def _check_points(req: OrthoCheckRequest, crs=None):
    from toolbox.photogrammetry.tables import ground_points

    ids, xyz, roles = ground_points(req.check_points, name="CHECK_POINTS", crs=crs)
    roles = list(roles)
    if "check" in roles:  # a control table with roles: its check points only
        keep = [k for k, r in enumerate(roles) if r == "check"]
        ids, xyz = [ids[k] for k in keep], np.asarray(xyz)[keep]
    return list(ids), np.asarray(xyz, float)


def _same_crs_as_project(project, named: dict, bounds: tuple | None = None) -> None:
    """The rasters (``{name: rasterio CRS}``) are in the project's CRS (the check points' and
    the orientations'): one in another CRS would match nothing, or leave every height
    difference blank, in silence. One without a CRS is taken to be in it. Horizontal parts
    are compared (a DEM published with its vertical datum is in its projected CRS), and the
    DEM's height datum, where both state one, against the project's. Another definition of
    the project's CRS (an ESRI WKT) is it when the raster's extent (``bounds``) moves by at most
    1 mm from one to the other."""
    from pyproj import CRS

    from toolbox.ortho.vertical import project_raster_crs

    for name, crs in named.items():
        project_raster_crs(project.crs, CRS.from_wkt(crs.to_wkt()) if crs else None, name,
                           heights=name == "DEM", bounds=bounds)


def measure_checks(req: OrthoCheckRequest, feedback=None) -> tuple[list[CheckResult], dict]:
    """Every check point measured on the orthophoto; returns the results and the settings
    used (cell, chip and search sizes in ground units)."""
    import rasterio

    from toolbox.photogrammetry.tables import image_measurements, load_project_parameter

    project = load_project_parameter(req.project)
    ids, xyz = _check_points(req, project.crs)
    m_ids, m_photos, m_xy, kind = image_measurements(req.measurements, None, "auto",
                                                     "MEASUREMENTS")
    if kind == "image":  # x_mm, y_mm in the fiducial system: to pixels by each photo's IO
        m_xy = np.array([_mm_to_pixel(project, ph, xy) for ph, xy in zip(m_photos, m_xy,
                                                                         strict=True)])
    if req.photo is not None and req.photo not in project.photos:
        raise InputDataError(f"PHOTO: {req.photo!r} is not in the project (photos: "
                             f"{', '.join(project.photos)})")
    with rasterio.open(req.ortho) as src:
        if not src.crs and project.crs is not None:  # as orientation:control has it
            from toolbox.io.crs import unlabelled_raster

            warn = feedback.push_warning if feedback is not None else \
                logging.getLogger("toolbox").warning
            unlabelled_raster("ORTHO", tuple(src.bounds), project.crs, "PROJECT", xyz[:, :2],
                              "CHECK_POINTS", warn)
        _same_crs_as_project(project, {"ORTHO": src.crs}, tuple(src.bounds))
        transform, shape = src.transform, (src.height, src.width)
    if req.dem is not None:
        with rasterio.open(req.dem) as src:
            _same_crs_as_project(project, {"DEM": src.crs}, tuple(src.bounds))
    cell = abs(transform.a)
    half = max(int(round((req.chip_m or 12 * cell) / cell)), 3)
    reach = max(int(round((req.search_m or 8 * cell) / cell)), 1)
    for name, cells in (("CHIP", half), ("SEARCH", reach)):  # a chip beyond the ortho: no sense
        if cells > max(shape):
            raise ParameterError(name, f"{cells * cell:g} m is {cells:,} cells of {cell:g} m, "
                                 f"more than the whole orthophoto ({shape[1]} x "
                                 f"{shape[0]} cells)")
    results = []
    surface = _dem_surface(req.dem) if req.dem is not None else None
    dz = xyz[:, 2] - surface.height(xyz[:, 0], xyz[:, 1]) if surface is not None else \
        np.full(len(ids), np.nan)
    with rasterio.open(req.ortho) as ortho:  # read by a window per check point
        for pid, p in zip(ids, xyz, strict=True):
            results.append(_measure_one(req, project, ortho, pid, p, m_ids, m_photos, m_xy,
                                        cell, half, reach, surface))
    for r, d in zip(results, dz, strict=True):
        r.dz_dem = float(d)
    off = [f"{r.point_id} ({r.dz_dem:+.1f} m)" for r in results if abs(r.dz_dem) > 2 * cell]
    if feedback is not None and off:
        feedback.push_warning(f"{len(off)} check point(s) lie off the DEM by more than 2 cells "
                              f"in height: {', '.join(off[:5])}; the orthophoto shows the ground "
                              "the DEM describes, so their offsets measure the difference too")
    if feedback is not None and not any(r.status == "matched" for r in results):
        feedback.push_warning(f"none of {len(results)} check points was found on the "
                              f"orthophoto ({', '.join(sorted({r.status for r in results}))})")
    return results, {"cell_m": cell, "chip_half_m": half * cell, "search_m": reach * cell,
                     "min_score": req.min_score}


def _measure_one(req: OrthoCheckRequest, project, ortho, pid, p, m_ids, m_photos, m_xy,
                 cell: float, half: int, reach: int, surface=None) -> CheckResult:
    """Check point ``pid`` at ground ``p``: its chip from the photo it was measured on nearest
    the centre, matched in the open orthophoto ``ortho`` within ``reach`` cells."""
    seen = [(ph, m_xy[k]) for k, (i, ph) in enumerate(zip(m_ids, m_photos, strict=True))
            if i == pid and ph in project.photos and (req.photo is None or ph == req.photo)]
    result = CheckResult(pid, "", *map(float, p))
    if not seen:
        result.status = "not measured on a photo"
        return result
    photo_id, measured = min(seen, key=lambda s: _off_centre(project.photo(s[0]), s[1]))
    photo = project.photo(photo_id)
    result.photo = photo_id
    if photo.image is None or not Path(photo.image).exists():
        raise InputDataError(f"PROJECT: photo {photo_id!r} has no image file to take the "
                             f"chip of check point {pid!r} from")
    chip = photo_chip(photo, _photo_reader(Path(photo.image)), p, measured, cell, half,
                      surface)
    if chip is None:
        result.status = OUTSIDE + " the photo"
        return result
    search = ortho_window(*_ortho_patch(ortho, p[0], p[1], cell, half + reach),
                          p[0], p[1], cell, half + reach)
    result.dx, result.dy, result.score, result.status = match_offset(
        chip, search, cell, req.min_score)
    if result.status == OUTSIDE:
        result.status = OUTSIDE + " the orthophoto"
    return result


def _mm_to_pixel(project, photo_id: str, xy_mm) -> np.ndarray:
    """One image measurement in mm (fiducial system) as a pixel (centres at +0.5); NaN for a
    photo the project lacks."""
    if photo_id not in project.photos:
        return np.full(2, np.nan)
    photo = project.photo(photo_id)
    if photo.pixel_transform is None:
        raise InputDataError(f"MEASUREMENTS: photo {photo_id!r} is measured in mm but has no "
                             "interior orientation (fiducial system -> pixels) in PROJECT")
    return np.asarray(photo.pixel_transform.image_to_pixel(np.asarray(xy_mm, float)[None]))[0]


def _dem_surface(dem: Path):
    """The orthophoto's DEM as a surface (bilinear heights, NaN off it)."""
    import rasterio

    from toolbox.io.raster import read_filled
    from toolbox.photogrammetry.surface import DemSurface

    with rasterio.open(dem) as src:
        return DemSurface.from_transform(read_filled(src, 1), src.transform)


def _off_centre(photo, px) -> float:
    w, h = photo.camera.image_size_px if getattr(photo.camera, "image_size_px", None) \
        else (0, 0)
    return float(np.hypot(px[0] - w / 2, px[1] - h / 2))


def write_results(path: Path, results: list[CheckResult]) -> None:
    """The per-point CSV: id, photo, surveyed X Y Z, offsets dx dy and their length (m), NCC
    score, status."""
    from toolbox.photogrammetry.tables import write_csv

    def f(v: float, d: int) -> str:
        return "" if not np.isfinite(v) else f"{v:.{d}f}"

    write_csv(path, ["point_id", "photo", "X", "Y", "Z", "dx_m", "dy_m", "d_m", "score",
                     "status", "z_minus_dem_m"],
              [[r.point_id, r.photo, f(r.x, 3), f(r.y, 3), f(r.z, 3), f(r.dx, 3), f(r.dy, 3),
                f(r.distance, 3), f(r.score, 3), r.status, f(r.dz_dem, 2)] for r in results])
