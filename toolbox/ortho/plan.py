"""Before warping one photo: geometry checks, the DEM window it sees, its footprint, mean
height, GSD and the output grid (:func:`plan_photo`)."""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.ortho.metrics import ground_sample_distance, nice_cell_size


def check_geometry(photo: Any, terrain_height: float | None = None) -> None:
    """Refuse a camera that cannot see the terrain: an optical axis that does not descend, or
    (given ``terrain_height``) a projection centre at or below the terrain."""
    eo = photo.require_exterior()
    axis = eo.rotation @ np.array([0.0, 0.0, -1.0])
    if not axis[2] < 0:
        raise InputDataError(f"photo {photo.id!r}: the camera looks away from the ground (its "
                             f"optical axis points {'up' if axis[2] > 0 else 'horizontally'}; "
                             f"omega = {math.degrees(eo.omega):.1f}, phi = "
                             f"{math.degrees(eo.phi):.1f} degrees): check the angles and their "
                             "unit")
    if terrain_height is not None and not eo.z0 > terrain_height:
        raise InputDataError(f"photo {photo.id!r}: the projection centre (Z0 = {eo.z0:.2f}) is "
                             f"not above the terrain ({terrain_height:.2f}); check Z0 and the "
                             "DEM's height datum")


def tilt_warning(photo: Any, limit_deg: float = 10.0) -> str | None:
    """A warning when omega or phi exceed ``limit_deg`` (a vertical photo has a few degrees at
    most: tens of degrees usually mean angles read in the wrong unit)."""
    eo = photo.require_exterior()
    o, p = (math.degrees(a) for a in (eo.omega, eo.phi))
    if max(abs(o), abs(p)) > limit_deg:
        return (f"photo {photo.id!r}: omega = {o:.1f} deg, phi = {p:.1f} deg: a vertical aerial "
                f"photo is tilted by a few degrees at most; if the angles were read in the wrong "
                f"unit (they were taken as {eo.source_unit}), fix the unit")
    return None


def lattice_grid(bounds: tuple[float, float, float, float], cell: float, crs: Any,
                 origin: tuple[float, float] = (0.0, 0.0), name: str = "CELL_SIZE") -> Any:
    """A north-up grid covering ``bounds`` whose edges lie on the lattice ``origin + k·cell``
    (default: multiples of the cell), so orthos of one block share one grid and mosaic
    without resampling."""
    from affine import Affine

    from toolbox.io.grid import GridSpec, cell_slack

    ox, oy = origin
    eps = cell_slack(cell, *bounds, ox, oy)  # an edge on the lattice up to rounding stays on it
    xmin = ox + math.floor((bounds[0] - ox) / cell + eps) * cell
    ymin = oy + math.floor((bounds[1] - oy) / cell + eps) * cell
    xmax = ox + math.ceil((bounds[2] - ox) / cell - eps) * cell
    ymax = oy + math.ceil((bounds[3] - oy) / cell - eps) * cell
    probe = GridSpec.from_bounds((xmin, ymin, xmax, ymax), cell, crs, snap=False, name=name)
    return GridSpec(Affine(cell, 0.0, xmin, 0.0, -cell, ymin + probe.height * cell),
                    probe.width, probe.height, crs)


def check_dem_crs(info: Any, name: str = "DEM") -> None:
    """Refuse a DEM without a CRS whose coordinates look like geographic degrees (heights
    cannot be placed on a projected ortho grid without knowing the datum)."""
    if info.crs is not None:
        return
    xmin, ymin, xmax, ymax = info.bounds
    if -180 <= xmin and xmax <= 360 and -90 <= ymin and ymax <= 90 and info.res[0] < 1.0:
        raise InputDataError(f"{name} {info} has no CRS and its coordinates ({xmin:.4f}.."
                             f"{xmax:.4f}, {ymin:.4f}..{ymax:.4f}) look like geographic degrees; "
                             "assign its CRS (e.g. gdal_edit.py -a_srs EPSG:4326) or reproject it")


def dem_range(info: Any, band: int = 1) -> tuple[float, float]:
    """The DEM's approximate height range (:func:`~toolbox.photogrammetry.surface.
    dem_height_range`), computed once per file and band in a process (a block's photos ask it
    twice each: GDAL opens the file and reads its overviews every time), also when photos are
    planned on several threads at once (each computed it: the NGI DEM opened and its statistics
    computed twice, 6.5 ms of CPU each)."""
    from pathlib import Path

    from toolbox.photogrammetry.surface import dem_height_range

    path = Path(info.path)
    try:
        key = (str(path.resolve()), path.stat().st_mtime_ns, band)
    except OSError:
        return dem_height_range(info, band)
    with _DEM_RANGES_LOCK:
        if key not in _DEM_RANGES:
            _DEM_RANGES[key] = dem_height_range(info, band)
        return _DEM_RANGES[key]


_DEM_RANGES: dict[tuple, tuple[float, float]] = {}  # dem_range's, by (path, mtime, band)
_DEM_RANGES_LOCK = threading.Lock()


def photo_surface(info: Any, photo: Any, crs: Any, band: int = 1) -> Any:
    """The DEM window every ray of the photo can meet, as a
    :class:`~toolbox.photogrammetry.surface.DemSurface` in ``crs`` (reprojected bilinearly at the
    DEM's resolution when the DEM is in another CRS)."""
    from toolbox.io.crs import one_horizontal_crs
    from toolbox.photogrammetry.surface import surface_for_photo

    if info.crs is None or crs is None or one_horizontal_crs(info.crs, crs, info.bounds):
        return surface_for_photo(info, photo, band, dem_range(info, band))
    import rasterio

    from toolbox.raster.reproject import default_grid, read_onto

    with rasterio.open(info.path) as src:
        t, width, height = default_grid(src, crs)
        # float64 with NaN where the DEM has no data (an integer DEM's nodata value would be
        # kept as a height)
        data = read_onto(src, t, width, height, crs, indexes=band, dtype="float64")[0]
    from toolbox.photogrammetry.surface import DemSurface, photo_ground_bounds

    whole = DemSurface.from_transform(data, t, crs)
    low, high = whole.z_range
    pad = 0.1 * (high - low) + 1.0
    b = photo_ground_bounds(photo, low - pad, high + pad,
                            (t.c, t.f + t.e * height, t.c + t.a * width, t.f))
    c0 = max(int((b[0] - t.c) / t.a) - 2, 0)
    c1 = min(int((b[2] - t.c) / t.a) + 3, width)
    r0 = max(int((b[3] - t.f) / t.e) - 2, 0)
    r1 = min(int((b[1] - t.f) / t.e) + 3, height)
    if c1 - c0 < 2 or r1 - r0 < 2:
        raise InputDataError(f"DEM {info} does not cover the photo {photo.id!r}")
    from affine import Affine

    return DemSurface.from_transform(data[r0:r1, c0:c1], t @ Affine.translation(c0, r0), crs)


def inside_polygon(xs: np.ndarray, ys: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Which points of the grid ``xs`` x ``ys`` (1-D, ``xs`` increasing) lie inside the simple
    polygon ``vertices`` ((K, 2+), the ring open or closed): (len(ys), len(xs)) booleans by the
    even-odd rule, a ray from each point towards +x crossing the edges (a point on an edge may
    fall either side). Row by row: the edges crossing a row's y and where, each crossing
    counted for the cells west of it. NumPy's, so planning a photo does not import shapely
    (0.03 s CPU of every ``ortho:batch`` run)."""
    xs, ys = np.asarray(xs, dtype="float64"), np.asarray(ys, dtype="float64")
    px, py = vertices[:, 0], vertices[:, 1]
    x0, y0 = np.roll(px, 1), np.roll(py, 1)  # edge k runs from vertex k - 1 to vertex k
    keep = y0 != py  # a horizontal edge: no crossing
    x0, y0, x1, y1 = x0[keep], y0[keep], px[keep], py[keep]
    y = ys[:, None]
    crosses = (y0 > y) != (y1 > y)  # (rows, edges)
    with np.errstate(invalid="ignore", divide="ignore"):
        at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    rows, edges = np.nonzero(crosses)
    first_east = np.searchsorted(xs, at[rows, edges], side="left")  # cells x < at: [0, this)
    counts = np.zeros((len(ys), len(xs) + 1), dtype=np.int32)
    np.add.at(counts, (rows, first_east), 1)
    west_of = np.cumsum(counts[:, ::-1], axis=1)[:, ::-1][:, 1:]  # crossings east of each cell
    return (west_of % 2).astype(bool)


def mean_height_inside(surface: Any, vertices: np.ndarray) -> float:
    """Mean DEM height of the cell centres inside a footprint polygon (``vertices`` (K, 2+):
    the photo's mean terrain height); the mean of the whole window when no centre falls
    inside."""
    rows, cols = surface.shape
    xs = surface.x0 + np.arange(cols) * surface.cell_x
    ys = surface.y0 - np.arange(rows) * surface.cell_y
    inside = inside_polygon(xs, ys, vertices) & np.isfinite(surface.z)
    return float(surface.z[inside].mean() if inside.any() else np.nanmean(surface.z))


def orientation_transformer(photo: Any, crs: Any) -> Any:
    """pyproj Transformer from the ortho's CRS to the orientation's (always_xy), or None when
    they are the same (or either is unknown): two definitions of one CRS (an ESRI WKT and its
    EPSG code) are the same when the projection centre moves by at most 1 mm from one to the
    other (:func:`toolbox.io.crs.one_crs`)."""
    from toolbox.io.crs import one_crs, parse_crs

    eo = photo.require_exterior()
    eo_crs = eo.crs
    if eo_crs is None or crs is None:
        return None
    eo_crs, crs = parse_crs(eo_crs), parse_crs(crs)
    if one_crs(eo_crs, crs, (eo.x0, eo.y0, eo.x0, eo.y0)):
        return None
    from pyproj import Transformer

    return Transformer.from_crs(crs, eo_crs, always_xy=True)


def reference_height(photo: Any, mean_height: float, principal: Any,
                     limit_deg: float = 10.0) -> float:
    """The height of the GSD (the default cell) and of the relief displacements: the mean
    terrain height of the footprint for a near-vertical photo; for an optical axis more than
    ``limit_deg`` off the nadir (an oblique photo, whose mean height may lie a few metres under
    a low camera, or above it) the height where the principal ray meets the DEM, when it
    does. :class:`InputDataError` when neither lies below the camera."""
    eo = photo.require_exterior()
    axis = eo.rotation @ np.array([0.0, 0.0, -1.0])
    tilted = math.degrees(math.acos(max(-1.0, min(1.0, -float(axis[2]))))) > limit_deg
    if (tilted or not mean_height < eo.z0) and principal.on_dem:
        return float(principal.xyz[2])
    if not mean_height < eo.z0:
        raise InputDataError(f"photo {photo.id!r}: the terrain of its footprint lies above the "
                             f"camera on average ({mean_height:.2f} >= Z0 = {eo.z0:.2f}) and "
                             "its principal ray misses the DEM: no ground sample distance (the "
                             "default cell); extend the DEM over the principal ray")
    return mean_height


@dataclass
class OrthoPlan:
    """What an ortho of one photo needs before warping: the DEM window the photo sees, its
    footprint on the DEM (8 points a side: for reports), the mean terrain height, the photo's
    GSD there, the output grid and ``extent``, the bounds of the footprint traced densely
    (:func:`footprint_points_per_side`): what the default grid covers."""

    photo: Any
    surface: Any
    footprint_xy: np.ndarray  # (K, 2+) the footprint's vertices in the ortho's CRS
    mean_height: float
    gsd: float
    grid: Any
    extent: tuple[float, float, float, float] | None = None

    @property
    def footprint(self) -> Any:
        """The footprint as a shapely Polygon."""
        import shapely

        return shapely.Polygon(self.footprint_xy)


FOOTPRINT_STEP_PX = 16  # photo pixels between the monoplotted points of the footprint's outline
REPORT_POINTS_PER_SIDE = 8  # the footprint kept in the plan (mean height, reports)


def footprint_points_per_side(photo: Any) -> int:
    """Points per side of the footprint outline: one every :data:`FOOTPRINT_STEP_PX` pixels of
    the longer side or a little more, a multiple of :data:`REPORT_POINTS_PER_SIDE` (so the
    report footprint's points are among the outline's), at least 8, at most 1024; 256 when the
    image size is unknown."""
    size = photo.camera.image_size_px
    if size is None:
        return 256
    step = REPORT_POINTS_PER_SIDE
    return int(min(1024, max(step, step * math.ceil(max(size) / FOOTPRINT_STEP_PX / step))))


def plan_photo(photo: Any, dem: Any, crs: Any, band: int = 1, cell: float | None = None,
               bounds: tuple[float, float, float, float] | None = None,
               origin: tuple[float, float] = (0.0, 0.0), output_crs: Any = None) -> OrthoPlan:
    """Check the geometry and choose the grid of one photo's ortho.

    ``crs`` is the orientation's; ``output_crs`` the ortho's (default the same; then the
    footprint is transformed, densified, to bound the grid). Defaults (as the thesis' software
    proposes, S002 par. 3.8): cell = the photo's ground sample distance at the mean terrain
    height of its footprint (2 significant digits); extent = the footprint on the DEM (the frame
    outline monoplotted on the DEM at every :data:`FOOTPRINT_STEP_PX` photo pixels of its
    sides, so that a valley or a lens' curve between two samples is not cut off: 8 points a
    side cut up to 87 m of real coverage); edges on the lattice ``origin + k·cell``.
    """
    from toolbox.io.crs import parse_crs
    from toolbox.photogrammetry.coverage import photo_footprint

    crs = None if crs is None else parse_crs(crs)
    output_crs = crs if output_crs is None else parse_crs(output_crs)
    check_dem_crs(dem)
    check_geometry(photo)
    low, _ = dem_range(dem, band)
    check_geometry(photo, low)
    surface = photo_surface(dem, photo, crs, band)
    eo = photo.require_exterior()
    under = float(surface.height(np.array([eo.x0]), np.array([eo.y0]))[0])
    check_geometry(photo, under if math.isfinite(under) else None)
    plane = float(np.nanmean(surface.z))
    dense = footprint_points_per_side(photo)
    footprint = photo_footprint(photo, surface, plane, dense)
    outline = footprint.vertices
    # the report footprint: every (dense / 8)-th point of the outline, the points a footprint
    # of 8 a side would monoplot (each ray on its own), without monoplotting them again
    polygon = outline[::dense // REPORT_POINTS_PER_SIDE]
    mean_height = reference_height(photo, mean_height_inside(surface, polygon),
                                   footprint.principal_point)
    gsd = ground_sample_distance(photo, mean_height)
    cell = nice_cell_size(gsd) if cell is None else float(cell)
    to_orientation = orientation_transformer(photo, output_crs)
    if to_orientation is not None:
        import shapely

        def to_output(xy: np.ndarray) -> np.ndarray:
            x, y = to_orientation.transform(xy[:, 0], xy[:, 1], direction="INVERSE")
            return np.column_stack([x, y])

        def transformed(vertices: np.ndarray) -> np.ndarray:
            ring = shapely.force_2d(shapely.Polygon(vertices))
            dense = shapely.segmentize(ring, max(ring.length / 400.0, cell))
            return shapely.get_coordinates(shapely.transform(dense, to_output))

        polygon, outline = transformed(polygon), transformed(outline)
    both = np.concatenate([polygon[:, :2], outline[:, :2]])
    extent = (float(both[:, 0].min()), float(both[:, 1].min()), float(both[:, 0].max()),
              float(both[:, 1].max()))
    # no cell beyond the DEM window the photo sees has a height: an oblique photo's footprint
    # runs to the fallback plane far away (or to the horizon), the grid stops at the DEM
    xmin, ymin, xmax, ymax = surface.bounds  # the cells' outer edges
    dem_box = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
    if to_orientation is not None:
        dem_box = transformed(dem_box)
    cut = (max(extent[0], float(dem_box[:, 0].min())), max(extent[1], float(dem_box[:, 1].min())),
           min(extent[2], float(dem_box[:, 0].max())), min(extent[3], float(dem_box[:, 1].max())))
    if cut[0] < cut[2] and cut[1] < cut[3]:
        extent = cut
    grid = lattice_grid(extent if bounds is None else bounds, cell, output_crs, origin)
    return OrthoPlan(photo, surface, polygon, mean_height, gsd, grid, extent)
