"""Epipolar (normalised) images of a stereo pair: the "normal case" (S002 par. 3.7).

Both photos are re-projected, through their projection centres, onto one common image plane
parallel to the base: the **common rotation** ``Rn`` has its x axis along the base
``B = C_right - C_left``, its z axis the mean of the two photos' z axes (made orthogonal to B),
``y = z x x``. With the **normalised principal distance** ``cn`` (mm) and **pixel** ``p`` (mm),
the normalised image coordinates ``(xn, yn)`` (mm, y up) of a ray ``d`` (ground-parallel) are
``v = Rn^T d``, ``xn = -cn v_x / v_z``, ``yn = -cn v_y / v_z``. Since the two centres differ only
along Rn's x axis, a ground point has the same ``yn`` in both: **rows are epipolar lines**.

Pixels: image k (0 = left, 1 = right) covers ``xn`` from ``x_min[k]`` and ``yn`` down from
``y_max`` (the same for both), so ``xn = x_min[k] + col·p``, ``yn = y_max - row·p`` with
``(col, row)`` continuous pixel coordinates (top-left corner 0, centres at +0.5). The GeoTIFFs
carry exactly this as their transform (no CRS): their "map" coordinates are ``(xn, yn)`` in mm.

Disparity ``d = col_left - col_right`` (pixels). The x-parallax is
``px = xn_left - xn_right = d·p + (x_min[0] - x_min[1])`` and the ground point is (normal case,
``Z = c·B / p``)::

    P = C_left + (|B| / px) · Rn @ (xn_left, yn, -cn)

The original pixel of a normalised one: its ray ``Rn @ (xn, yn, -cn)`` from the photo's centre
goes through the collinearity equations, the radial distortion and the interior orientation
(:meth:`toolbox.photogrammetry.photo.Photo.ground_to_pixel`): the images are resampled with the
distortion removed, by windows on the shared raster engine (``cv2.remap``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ParameterError

FORMAT = "epipolar-pair"
OUTLINE_POINTS = 16  # per side of the image frame, to follow distortion and perspective
MAX_PIXELS = 1 << 30  # per normalised image: refuse absurd geometry (near-vertical base)


@dataclass(frozen=True)
class EpipolarGeometry:
    """The common geometry of a normalised pair (module docstring)."""

    rotation: np.ndarray  # (3, 3) Rn, columns = normalised image axes in ground axes
    principal_distance_mm: float
    pixel_mm: float
    centres: np.ndarray  # (2, 3) projection centres, left then right
    x_min_mm: tuple[float, float]
    widths: tuple[int, int]
    y_max_mm: float
    height: int
    photos: tuple[str, str]
    crs_wkt: str | None = None

    @property
    def base(self) -> np.ndarray:
        return self.centres[1] - self.centres[0]

    @property
    def base_length(self) -> float:
        return float(np.linalg.norm(self.base))

    def transform(self, side: int):
        """Affine of image ``side`` (0 left, 1 right): pixel corner -> (xn, yn) mm."""
        from affine import Affine

        p = self.pixel_mm
        return Affine(p, 0.0, self.x_min_mm[side], 0.0, -p, self.y_max_mm)

    def grid(self, side: int):
        from toolbox.io.grid import GridSpec

        return GridSpec(self.transform(side), self.widths[side], self.height, None)

    # -- object space <-> normalised pixels --------------------------------------------------------
    def ground_to_pixels(self, xyz: np.ndarray, side: int) -> np.ndarray:
        """Ground (N, 3) -> normalised (col, row) of image ``side`` (N, 2); NaN behind."""
        v = (np.asarray(xyz, dtype="float64") - self.centres[side]) @ self.rotation
        with np.errstate(invalid="ignore", divide="ignore"):
            xn = -self.principal_distance_mm * v[:, 0] / v[:, 2]
            yn = -self.principal_distance_mm * v[:, 1] / v[:, 2]
        bad = v[:, 2] >= 0
        xn[bad] = yn[bad] = np.nan
        return np.column_stack([(xn - self.x_min_mm[side]) / self.pixel_mm,
                                (self.y_max_mm - yn) / self.pixel_mm])

    def triangulate(self, col_left, row, disparity) -> np.ndarray:
        """Ground points (..., 3) of left pixels ``(col_left, row)`` and disparities
        ``col_left - col_right`` (pixels); NaN where the parallax is not positive."""
        col_left, row, disparity = np.broadcast_arrays(
            *(np.asarray(a, dtype="float64") for a in (col_left, row, disparity)))
        p = self.pixel_mm
        xn = self.x_min_mm[0] + col_left * p
        yn = self.y_max_mm - row * p
        px = disparity * p + (self.x_min_mm[0] - self.x_min_mm[1])
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(px > 0, self.base_length / px, np.nan)
        ray = np.stack([xn, yn, np.full_like(xn, -self.principal_distance_mm)], axis=-1)
        return self.centres[0] + (scale[..., None] * ray) @ self.rotation.T

    def disparity_of_depth(self, depth_m: float) -> float:
        """Disparity (pixels) of a point at ``depth_m`` along the normalised axis."""
        px = self.principal_distance_mm * self.base_length / depth_m
        return (px - (self.x_min_mm[0] - self.x_min_mm[1])) / self.pixel_mm

    # -- file ---------------------------------------------------------------------------------------
    def as_dict(self) -> dict[str, Any]:
        return {
            "format": FORMAT, "version": 1,
            "photos": {"left": self.photos[0], "right": self.photos[1]},
            "rotation": self.rotation.tolist(),
            "principal_distance_mm": self.principal_distance_mm, "pixel_mm": self.pixel_mm,
            "centres": self.centres.tolist(), "base": self.base.tolist(),
            "base_length": self.base_length,
            "x_min_mm": list(self.x_min_mm), "widths": list(self.widths),
            "y_max_mm": self.y_max_mm, "height": self.height, "crs": self.crs_wkt,
            "conventions": (
                "Rn columns = normalised image axes (x along the base) in ground axes; image k: "
                "xn = x_min_mm[k] + col*pixel_mm, yn = y_max_mm - row*pixel_mm (mm, pixel "
                "corner at 0, centres at +0.5); disparity d = col_left - col_right; parallax "
                "px = d*pixel_mm + x_min_mm[0] - x_min_mm[1]; ground point P = centres[0] + "
                "(base_length/px) * Rn @ (xn_left, yn, -principal_distance_mm)"),
        }

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> EpipolarGeometry:
        if doc.get("format") != FORMAT:
            raise InputDataError(f"not an epipolar pair file (format {doc.get('format')!r})")
        return cls(np.asarray(doc["rotation"], dtype="float64"),
                   float(doc["principal_distance_mm"]), float(doc["pixel_mm"]),
                   np.asarray(doc["centres"], dtype="float64"), tuple(doc["x_min_mm"]),
                   tuple(int(w) for w in doc["widths"]), float(doc["y_max_mm"]),
                   int(doc["height"]), (doc["photos"]["left"], doc["photos"]["right"]),
                   doc.get("crs"))

    def write(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.as_dict(), indent=2) + "\n")

    @classmethod
    def read(cls, path: str | Path) -> EpipolarGeometry:
        return cls.from_dict(json.loads(Path(path).read_text()))


def common_rotation(left: Any, right: Any) -> np.ndarray:
    """Rn (3, 3) of two oriented photos (module docstring)."""
    base = right.exterior.centre - left.exterior.centre
    length = float(np.linalg.norm(base))
    if length == 0:
        raise InputDataError(f"photos {left.id!r} and {right.id!r} have the same projection "
                             "centre: no stereo base")
    ex = base / length
    z = left.exterior.rotation[:, 2] + right.exterior.rotation[:, 2]
    ey = np.cross(z, ex)
    if np.linalg.norm(ey) < 1e-6 * np.linalg.norm(z):
        raise InputDataError(f"the base of {left.id!r}-{right.id!r} is along the viewing "
                             "direction: no normal case")
    ey /= np.linalg.norm(ey)
    ez = np.cross(ex, ey)
    return np.column_stack([ex, ey, ez])


def _normalised_outline(photo: Any, rotation: np.ndarray, cn: float) -> np.ndarray:
    """The photo's frame outline in normalised coordinates (mm), (N, 2)."""
    outline = photo.frame_outline_mm(OUTLINE_POINTS)
    ideal = photo.camera.image_to_camera(outline)
    rays = np.column_stack([ideal, np.full(len(ideal), -photo.camera.c)]) \
        @ photo.exterior.rotation.T
    v = rays @ rotation
    if np.any(v[:, 2] >= 0):
        raise InputDataError(f"photo {photo.id!r} looks away from the common image plane (more "
                             "than 90 degrees from it): not a normal-case pair")
    return np.column_stack([-cn * v[:, 0] / v[:, 2], -cn * v[:, 1] / v[:, 2]])


def epipolar_geometry(left: Any, right: Any, pixel_mm: float | None = None,
                      principal_distance_mm: float | None = None) -> EpipolarGeometry:
    """The normalised pair of two oriented photos. Defaults: the left photo's principal
    distance and pixel size (the interior orientation's mean pixel)."""
    for photo in (left, right):
        photo.require_exterior()
    rotation = common_rotation(left, right)
    cn = float(principal_distance_mm or left.camera.c)
    given = pixel_mm is not None
    if pixel_mm is None:
        pixel_mm = float(left.require_pixel_transform().pixel_size_mm)
    outlines = [_normalised_outline(p, rotation, cn) for p in (left, right)]
    y_lo = max(o[:, 1].min() for o in outlines)
    y_hi = min(o[:, 1].max() for o in outlines)
    if y_hi <= y_lo:
        raise InputDataError(f"photos {left.id!r} and {right.id!r} share no epipolar line "
                             "(their normalised images do not overlap across the base)")
    y_max = math.floor(y_hi / pixel_mm) * pixel_mm
    height = int(math.floor((y_max - y_lo) / pixel_mm))
    x_min, widths = [], []
    for o in outlines:
        lo = math.floor(o[:, 0].min() / pixel_mm) * pixel_mm
        x_min.append(lo)
        widths.append(int(math.ceil((o[:, 0].max() - lo) / pixel_mm)))
    for side, w in enumerate(widths):
        if w * height > MAX_PIXELS and given:
            raise ParameterError("PIXEL_SIZE_MM", f"{pixel_mm:g} mm gives a normalised image of "
                                 f"{(left, right)[side].id!r} of {w:,} x {height:,} pixels, over "
                                 f"the limit of {MAX_PIXELS:,}: use a larger PIXEL_SIZE_MM (or "
                                 "leave it empty: the photo's pixel)")
        if w * height > MAX_PIXELS:
            raise InputDataError(f"the normalised image of {(left, right)[side].id!r} would have "
                                 f"{w} x {height} pixels: the photos are too oblique to the base")
    crs = left.exterior.crs
    if crs is not None:
        from pyproj import CRS

        crs = CRS.from_user_input(crs)
    return EpipolarGeometry(rotation, cn, float(pixel_mm),
                            np.vstack([left.exterior.centre, right.exterior.centre]),
                            (x_min[0], x_min[1]), (widths[0], widths[1]), y_max, height,
                            (left.id, right.id), None if crs is None else crs.to_wkt())


MAP_STEP = 8  # pixels between exactly computed map nodes; bilinear in between


def _lattice(n: int, step: int) -> np.ndarray:
    """Indices 0, step, 2 step, ..., n - 1 (the last one always included)."""
    return np.unique(np.r_[np.arange(0, n, step), n - 1])


def _upsample(coarse: np.ndarray, rows: np.ndarray, cols: np.ndarray, height: int,
              width: int) -> np.ndarray:
    """Bilinear interpolation of ``coarse`` (values at lattice ``rows`` x ``cols``) onto every
    index of a ``height`` x ``width`` array."""
    def weights(nodes: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        if len(nodes) == 1:
            return np.zeros(n, np.int64), np.zeros(n)
        k = np.clip(np.searchsorted(nodes, np.arange(n), side="right") - 1, 0, len(nodes) - 2)
        return k, (np.arange(n) - nodes[k]) / (nodes[k + 1] - nodes[k])

    kc, tc = weights(cols, width)
    kr, tr = weights(rows, height)
    across = coarse[:, kc] * (1 - tc) + coarse[:, np.minimum(kc + 1, len(cols) - 1)] * tc
    return across[kr] * (1 - tr)[:, None] + across[np.minimum(kr + 1, len(rows) - 1)] * tr[:, None]


class EpipolarMap:
    """Coordinate map (:class:`toolbox.raster.maps.CoordinateMap`) of normalised image ``side``
    onto its original photo: normalised pixel -> ray -> original pixel (distortion added).

    The chain is computed exactly every ``step`` pixels (and on the tile's last row and
    column) and interpolated bilinearly in between: the map is smooth (a rotation and a
    radial polynomial), so the interpolation error is far below 0.01 pixel for ``step`` 8,
    at a 64th of the memory and time (``step`` 1: every pixel exactly)."""

    def __init__(self, geometry: EpipolarGeometry, photo: Any, side: int, step: int = MAP_STEP):
        self.geometry, self.photo, self.side, self.step = geometry, photo, side, step

    def __call__(self, tile: Any, aux: dict) -> tuple[np.ndarray, np.ndarray]:
        x, y = tile.cell_centres(halo=False)  # (xn, yn) of the pixel centres, mm
        if self.step > 1:
            rows, cols = _lattice(len(y), self.step), _lattice(len(x), self.step)
            xn, yn = np.meshgrid(x[cols], y[rows])
            coarse = self.pixels(xn, yn)
            if all(np.isfinite(c).all() for c in coarse):
                return tuple(_upsample(c.astype(np.float64), rows, cols, len(y), len(x))
                             .astype("float32") for c in coarse)
        xn, yn = np.meshgrid(x, y)
        return self.pixels(xn, yn)

    def pixels(self, xn: np.ndarray, yn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Original photo (col, row) float32 of normalised coordinates (mm); NaN behind."""
        g = self.geometry
        rays = np.stack([xn, yn, np.full_like(xn, -g.principal_distance_mm)], axis=-1) \
            @ g.rotation.T
        # a ground point on each ray 1000 ray-lengths out: the collinearity chain gives its pixel
        points = g.centres[self.side] + rays.reshape(-1, 3) * 1000.0
        colrow = self.photo.ground_to_pixel(points, behind="nan")
        shape = np.shape(xn)
        return (colrow[:, 0].reshape(shape).astype("float32"),
                colrow[:, 1].reshape(shape).astype("float32"))


@dataclass
class PairReport:
    """Overlap and normal-case precision of a pair at a terrain height."""

    overlap: float  # shared ground area / the smaller footprint
    base_m: float
    distance_m: float  # mean flying height above the terrain height
    base_ratio: float
    sigma_z_m: float
    sigma_parallax_um: float

    def as_dict(self) -> dict[str, float]:
        return dict(self.__dict__)


def pair_report(left: Any, right: Any, terrain_height: float,
                sigma_parallax_um: float = 5.0) -> PairReport:
    """Footprint overlap at ``terrain_height`` and σZ = m_b·(Z/B)·σp (S002 eq. [35]-[40])."""
    import shapely

    from toolbox.photogrammetry.normal_case import normal_case_precision

    feet = []
    for photo in (left, right):
        outline = photo.frame_outline_mm(OUTLINE_POINTS)
        ground = photo.image_to_ground(outline, terrain_height, invalid="nan")
        if not np.isfinite(ground).all():
            raise InputDataError(f"photo {photo.id!r}: part of its frame does not reach the "
                                 f"terrain height {terrain_height:g} (rays above the horizon)")
        feet.append(shapely.make_valid(shapely.Polygon(ground[:, :2])))
    shared = feet[0].intersection(feet[1]).area
    overlap = shared / min(f.area for f in feet)
    base = float(np.linalg.norm(right.exterior.centre - left.exterior.centre))
    distance = float((left.exterior.z0 + right.exterior.z0) / 2.0 - terrain_height)
    if distance <= 0:
        raise InputDataError(f"the projection centres are not above the terrain height "
                             f"{terrain_height:g}")
    precision = normal_case_precision(left.camera.c, base, distance, sigma_parallax_um)
    return PairReport(float(overlap), base, distance, base / distance,
                      float(precision["sigma_z_m"]), sigma_parallax_um)


def check_pair(report: PairReport, ids: tuple[str, str], min_overlap: float,
               sigma_z: float | None) -> None:
    """InputDataError for a pair without enough overlap or with a base too short for
    ``sigma_z`` (metres)."""
    if report.overlap < min_overlap:
        raise InputDataError(f"photos {ids[0]!r} and {ids[1]!r} overlap by "
                             f"{100 * report.overlap:.1f} % of a footprint at the terrain "
                             f"height, less than MIN_OVERLAP {100 * min_overlap:.0f} %")
    if sigma_z is not None and report.sigma_z_m > sigma_z:
        raise InputDataError(
            f"the base of {ids[0]!r}-{ids[1]!r} is too short for SIGMA_Z {sigma_z:g} m: "
            f"B = {report.base_m:.1f} m at Z = {report.distance_m:.1f} m (B/Z = "
            f"{report.base_ratio:.3f}) gives sigma_Z = {report.sigma_z_m:.3f} m with "
            f"sigma_p = {report.sigma_parallax_um:g} um (S002 eq. [37])")


def photo_image(photo: Any, override: Any = None, name: str = "LEFT_IMAGE") -> Path:
    """The image file of ``photo``: ``override`` (a path or RasterInfo) or the project's."""
    if override is not None:
        return Path(getattr(override, "path", override))
    if photo.image is None or not Path(photo.image).exists():
        where = "has no image" if photo.image is None else f"image '{photo.image}' does not exist"
        raise InputDataError(f"photo {photo.id!r} {where}: give {name}")
    return Path(photo.image)


def resample_image(geometry: EpipolarGeometry, photo: Any, side: int, image: Path,
                   output: Path, resampling: str = "bilinear", feedback: Any = None,
                   executor: Any = None, overviews: bool = True,
                   pixel_photo: Any = None) -> Any:
    """Write normalised image ``side`` of ``photo``'s ``image`` to ``output`` (GeoTIFF whose
    transform is the normalised mm frame, no CRS; an alpha band marks pixels outside the
    photo). Windows of 2048 pixels on the raster engine: memory bounded by the window.

    ``pixel_photo`` (default ``photo``) maps rays to the image's pixels: the model-camera photo
    whose distortion-free frame equivalent (:func:`toolbox.stereo.frames.as_frame_photo`) is
    ``photo``, so that the distortion is removed."""
    import warnings

    import rasterio

    from toolbox.photogrammetry.photo import fit_image_size
    from toolbox.raster.warp import warp_to_geotiff

    if photo.camera.image_size_px is not None:  # another photo's image would be warped
        with warnings.catch_warnings():            # without a word
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            with rasterio.open(image) as src:
                actual = (src.width, src.height)
        fit_image_size(photo, *actual, image)
    tags = {"EPIPOLAR_PHOTO": photo.id, "EPIPOLAR_SIDE": ("left", "right")[side]}
    return warp_to_geotiff(image, EpipolarMap(geometry, pixel_photo or photo, side),
                           geometry.grid(side),
                           output, resampling=resampling, outside="alpha", feedback=feedback,
                           tags=tags, executor=executor, overviews=overviews)
