"""Ground coverage of oriented photos: footprints, nadir and principal points, overlaps.

A footprint is the image format's outline (densified: ``points_per_side`` points per side)
projected onto the terrain by monoplotting (:func:`toolbox.photogrammetry.collinearity.monoplot`),
or onto the plane ``Z = mean height`` when no DEM is given. Vertices whose rays miss the DEM
(outside it, on nodata) fall back to the plane at the DEM's mean height (a ray that meets
neither, over the horizon or with the plane above the camera: where its track leaves the DEM)
and are counted in ``vertices_off_dem`` (the footprint is then ``partial``), never silently
dropped.

The nadir point is the ground point vertically below the projection centre; the principal
point is where the ray through the principal point (image ``(ξ0, η0)``) meets the terrain.
Overlap between two footprints is ``area(A ∩ B) / area(A)`` (and ``/ area(B)``), in percent: for
consecutive photos of a strip it is the forward overlap (≈ 60% in standard flights, brief
section 10), for photos of adjacent strips the side overlap (≈ 20-30%).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from toolbox.photogrammetry.collinearity import OK, STATUS_NAMES
from toolbox.photogrammetry.photo import Photo
from toolbox.photogrammetry.surface import DemSurface


@dataclass
class GroundPoint:
    """A point projected on the terrain: ``xyz`` (3,), ``on_dem`` False when the plane was used,
    ``status`` the monoplot status name."""

    xyz: np.ndarray
    on_dem: bool
    status: str


@dataclass
class Footprint:
    """A photo's ground coverage."""

    photo: Photo
    vertices: np.ndarray  # (K, 3), counter-clockwise in the image
    vertex_status: np.ndarray  # (K,) monoplot status codes (OK when on the DEM)
    plane_height: float  # height of the fallback plane
    nadir: GroundPoint = field(default=None)  # type: ignore[assignment]
    principal_point: GroundPoint = field(default=None)  # type: ignore[assignment]

    @property
    def vertices_off_dem(self) -> int:
        return int(np.count_nonzero(self.vertex_status != OK))

    @property
    def polygon(self):
        import shapely

        return shapely.Polygon(self.vertices)

    @property
    def mean_height(self) -> float:
        return float(np.mean(self.vertices[:, 2]))


def _project_points(photo: Photo, xy_mm: np.ndarray, surface: DemSurface | None,
                    plane_height: float) -> tuple[np.ndarray, np.ndarray]:
    """Image mm -> ground on the DEM, falling back to the plane; (xyz, status codes)."""
    if surface is None:
        xyz = photo.image_to_ground(xy_mm, plane_height)
        return xyz, np.full(len(xy_mm), -1, dtype=np.int8)  # -1: no DEM given
    result = photo.monoplot_image(xy_mm, surface)
    xyz = result.xyz.copy()
    failed = np.flatnonzero(result.status != OK)
    if failed.size:
        xyz[failed] = photo.image_to_ground(xy_mm[failed], plane_height, invalid="nan")
        beyond = failed[np.isnan(xyz[failed, 0])]
        if beyond.size:  # above the horizon, or a plane above the camera: to the DEM's edge
            xyz[beyond] = _dem_edge(photo, xy_mm[beyond], surface, plane_height)
    return xyz, result.status


def _dem_edge(photo: Photo, xy_mm: np.ndarray, surface: DemSurface, height: float
              ) -> np.ndarray:
    """Where the horizontal tracks of the rays through ``xy_mm`` leave the DEM's extent (beyond
    its farthest corner for a track that misses it), at ``height``: the footprint vertex of a
    ray that meets neither the DEM nor the fallback plane (it runs to the horizon, or the plane
    lies above the camera)."""
    eo = photo.require_exterior()
    x0, y0, z0 = eo.x0, eo.y0, eo.z0
    down = photo.image_to_ground(xy_mm, z0 - 1.0, invalid="nan")
    up = photo.image_to_ground(xy_mm, z0 + 1.0, invalid="nan")
    ends = np.where(np.isfinite(down[:, :1]), down, up)[:, :2] - (x0, y0)
    ends = np.where(np.isfinite(ends), ends, 0.0)
    xmin, ymin, xmax, ymax = surface.bounds
    reach = float(np.hypot(np.array([xmin, xmax]) - x0, np.array([[ymin], [ymax]]) - y0).max())
    length = np.hypot(ends[:, 0], ends[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        d = ends / length[:, None]
        t1 = (np.array([xmin, ymin]) - (x0, y0)) / d
        t2 = (np.array([xmax, ymax]) - (x0, y0)) / d
    t_in = np.nanmax(np.minimum(t1, t2), axis=1)
    t_out = np.nanmin(np.maximum(t1, t2), axis=1)
    t = np.where((t_out >= np.maximum(t_in, 0.0)) & np.isfinite(t_out), t_out, reach)
    t = np.where(length > 0, t, 0.0)
    d = np.where(np.isfinite(d), d, 0.0)
    return np.column_stack([x0 + t * d[:, 0], y0 + t * d[:, 1], np.full(len(t), height)])


def photo_footprint(photo: Photo, surface: DemSurface | None, plane_height: float,
                    points_per_side: int = 8) -> Footprint:
    """Footprint, nadir and principal point of one photo (see the module docstring).

    ``surface`` None projects onto the plane ``Z = plane_height``; otherwise the plane is only
    the fallback for rays that miss the DEM.
    """
    outline = photo.frame_outline_mm(points_per_side)
    vertices, status = _project_points(photo, outline, surface, plane_height)
    eo = photo.require_exterior()
    if surface is None:
        nadir = GroundPoint(np.array([eo.x0, eo.y0, plane_height]), False, "no_dem")
    else:
        h = float(surface.height(np.array([eo.x0]), np.array([eo.y0]))[0])
        nadir = GroundPoint(np.array([eo.x0, eo.y0, h if np.isfinite(h) else plane_height]),
                            bool(np.isfinite(h)), "ok" if np.isfinite(h) else "outside_dem")
    pp_xyz, pp_status = _project_points(photo, np.array([photo.camera.principal_point_mm]),
                                        surface, plane_height)
    code = int(pp_status[0])
    principal = GroundPoint(pp_xyz[0], code == OK, STATUS_NAMES.get(code, "no_dem"))
    fp = Footprint(photo, vertices, status, plane_height, nadir, principal)
    return fp


@dataclass
class Overlap:
    """Overlap of two footprints: the intersection polygon and its share of each (percent)."""

    a: str
    b: str
    kind: str  # forward (consecutive in a strip), side (side neighbours in two strips), other
    geometry: Any
    percent_of_a: float
    percent_of_b: float


def overlaps(footprints: list[Footprint], consecutive: set[tuple[str, str]]) -> list[Overlap]:
    """Every pair of footprints that overlap (found with a shapely STRtree), classified as
    ``forward`` for the consecutive pairs given, ``side`` between side neighbours (photos of
    two strips, one of them the photo of its strip that overlaps the other most), else
    ``other`` (e.g. the diagonal neighbours of a block: 12 % in a 60/20 % block, which the
    side-overlap rule is not about)."""
    import shapely

    polygons = [fp.polygon for fp in footprints]
    tree = shapely.STRtree(polygons)
    pairs = tree.query(polygons, predicate="intersects")
    result = []
    for i, j in zip(*pairs, strict=True):
        if i >= j:
            continue
        a, b = footprints[i], footprints[j]
        inter = shapely.intersection(polygons[i], polygons[j])
        if inter.is_empty or inter.area <= 0:
            continue
        if (a.photo.id, b.photo.id) in consecutive or (b.photo.id, a.photo.id) in consecutive:
            kind = "forward"
        elif (a.photo.strip or "") != (b.photo.strip or ""):
            kind = "side"
        else:
            kind = "other"
        result.append(Overlap(a.photo.id, b.photo.id, kind, inter,
                              100.0 * inter.area / polygons[i].area,
                              100.0 * inter.area / polygons[j].area))
    strip = {fp.photo.id: fp.photo.strip or "" for fp in footprints}
    best: dict[tuple[str, str], float] = {}  # (photo, other strip) -> its largest overlap there
    for ov in result:
        if ov.kind == "side":
            for me, other, pct in ((ov.a, ov.b, ov.percent_of_a), (ov.b, ov.a, ov.percent_of_b)):
                key = (me, strip[other])
                best[key] = max(best.get(key, 0.0), pct)
    for ov in result:
        if ov.kind == "side" and not (ov.percent_of_a >= best[(ov.a, strip[ov.b])] or
                                      ov.percent_of_b >= best[(ov.b, strip[ov.a])]):
            ov.kind = "other"
    return result
