"""Flight plan of a photogrammetric block: photo scale, strips, photo centres, models, control.

Conventions: ground coordinates in a projected CRS (metres); the flight frame has ``u`` along
the strips (unit vector ``(sin az, cos az)``, az = azimuth clockwise from grid north) and ``v``
across them (``(cos az, -sin az)``, to the right), both from the area's centroid. FORMAT is the
frame ``across x along`` the flight, mm.

Rules (002 par. 1.3.5 and domain.md section 10; 004 sl. 19-24):

- photo scale from the map scale by 002's Table 3 (c = 150 mm; middle of the printed range,
  log-interpolated between rows), flying height above ground ``H = c·m_b`` (eq. [2]);
- ground side ``L = format·m_b``, base ``B = (1 - R1)·L_along``, strip spacing
  ``A = (1 - R2)·L_across``; the minimum photo count ``S / (B·A)`` (eq. [3] with the side
  overlap R2 where the thesis prints R1);
- strips cover the area's width with spacing A, centred on it; in each strip the photos (base B,
  centred on the strip's share of the area) are enough for stereo cover of it: n photos cover
  ``(n - 3)·B + L_along`` of ground in stereo, one more photo than the bare count at each end;
- control: planimetric (XY) points along the block's long edges every ``edge_interval`` models
  (edge control, 004 sl. 19), full (XYZ) points at both ends of every strip, height (Z) points on
  lines across the block every ``height_interval`` models, one per side-overlap line
  (sl. 23-24; XYZ where a line meets an edge point); each control location as a pair of points
  (sl. 22), a tenth of the base apart along the strip.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from toolbox.errors import InputDataError, ParameterError

# 002 Table 3: map scale -> photo scale range (c = 150 mm)
PHOTO_SCALE_TABLE = ((500, 3000, 4000), (1000, 5000, 6000), (2000, 7500, 9000),
                     (5000, 12000, 18000), (10000, 18000, 25000), (25000, 25000, 40000),
                     (50000, 40000, 50000))


def photo_scale_for_map(map_scale: float) -> tuple[float, tuple[float, float]]:
    """Photo scale number for a map scale number (002 Table 3): the middle of the printed range,
    log-interpolated between rows; and the range itself (interpolated the same way)."""
    maps = np.log([r[0] for r in PHOTO_SCALE_TABLE])
    if not PHOTO_SCALE_TABLE[0][0] <= map_scale <= PHOTO_SCALE_TABLE[-1][0]:
        raise ParameterError("MAP_SCALE", f"002 Table 3 covers 1:500 to 1:50000, got "
                             f"1:{map_scale:g}; give PHOTO_SCALE instead")
    x = math.log(map_scale)
    lo = math.exp(np.interp(x, maps, np.log([r[1] for r in PHOTO_SCALE_TABLE])))
    hi = math.exp(np.interp(x, maps, np.log([r[2] for r in PHOTO_SCALE_TABLE])))
    return 0.5 * (lo + hi), (lo, hi)


class BlockTooLarge(InputDataError):
    """The planned block has more stereo models than allowed (``models`` is None when the
    strips alone are absurdly many)."""

    def __init__(self, strips: int, models: int | None, limit: int) -> None:
        self.strips, self.models, self.limit = strips, models, limit
        counted = f"more than {limit:,} stereo models" if models is None else \
            f"at least {models:,} stereo models"
        super().__init__(f"the block has {strips:,} strips and {counted}, over the limit of "
                         f"{limit:,}")


@dataclass
class FlightSpec:
    """What to plan (mm, m, fractions, degrees)."""

    photo_scale: float
    principal_distance_mm: float = 150.0
    format_mm: tuple[float, float] = (230.0, 230.0)  # across x along the flight
    forward: float = 0.60
    side: float = 0.25
    terrain_height: float = 0.0  # mean ground height, m
    azimuth_deg: float | None = None  # None: along the long side of the area
    edge_interval: int = 4  # models between full control points along the long edges
    height_interval: int = 4  # models between height-control lines
    pairs: bool = True

    def __post_init__(self) -> None:
        for name, value, lo, hi in (("FORWARD_OVERLAP", self.forward, 0.5, 0.95),
                                    ("SIDE_OVERLAP", self.side, 0.0, 0.9)):
            if not lo <= value <= hi:
                raise ParameterError(name, f"must be between {100 * lo:g} and {100 * hi:g} % "
                                     f"(stereo cover needs >= 50 % forward), got "
                                     f"{100 * value:g} %")


@dataclass
class FlightPlan:
    """The planned block (ground metres; angles radians)."""

    spec: FlightSpec
    azimuth: float  # rad, clockwise from grid north
    origin: np.ndarray  # (2,) centroid of the area
    flying_height: float  # above ground, m
    ground_side: tuple[float, float]  # across, along (m)
    base: float
    spacing: float
    area_m2: float
    strip_v: np.ndarray  # (s,) strip axes, v
    photo_strip: np.ndarray  # (n,) strip index
    photo_index: np.ndarray  # (n,) index within the strip
    photo_uv: np.ndarray  # (n, 2)
    area_uv: object = None  # the area (shapely) in the flight frame
    control_uv: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    control_kind: list[str] = field(default_factory=list)  # "XYZ", "XY" or "Z"
    control_reason: list[str] = field(default_factory=list)

    @property
    def frame(self) -> np.ndarray:
        """(2, 2) rows: u and v unit vectors on the ground axes."""
        s, c = math.sin(self.azimuth), math.cos(self.azimuth)
        return np.array([[s, c], [c, -s]])

    def to_ground(self, uv: np.ndarray) -> np.ndarray:
        return self.origin + np.asarray(uv, dtype=float) @ self.frame

    @property
    def photo_xy(self) -> np.ndarray:
        return self.to_ground(self.photo_uv)

    @property
    def control_xy(self) -> np.ndarray:
        return self.to_ground(self.control_uv)

    @property
    def n_strips(self) -> int:
        return len(self.strip_v)

    @property
    def models(self) -> list[tuple[int, int]]:
        """Consecutive photo pairs (indices) of each strip."""
        out = []
        for s in range(self.n_strips):
            idx = np.flatnonzero(self.photo_strip == s)
            out += [(int(a), int(b)) for a, b in zip(idx[:-1], idx[1:], strict=True)]
        return out

    @property
    def minimum_photos(self) -> float:
        """002 eq. [3]: S / ((1 - R1)(1 - R2)·L²) with the true across and along sides."""
        return self.area_m2 / (self.base * self.spacing)


def plan_flight(area, spec: FlightSpec, max_models: int | None = None) -> FlightPlan:
    """Strips, photo centres and control for ``area`` (a shapely polygon, projected metres).
    With ``max_models``, a block of more stereo models is refused (:class:`BlockTooLarge`)
    before any strip's photos are allocated."""
    import shapely

    if area.is_empty or area.area <= 0:
        raise InputDataError("the project area is empty (no polygon area)")
    mb = spec.photo_scale
    h = spec.principal_distance_mm * mb / 1000.0
    across, along = (f * mb / 1000.0 for f in spec.format_mm)
    base, spacing = (1 - spec.forward) * along, (1 - spec.side) * across
    if spec.azimuth_deg is None:
        rect = np.asarray(shapely.minimum_rotated_rectangle(area).exterior.coords)[:3]
        edges = np.diff(rect, axis=0)
        long = edges[int(np.argmax(np.hypot(*edges.T)))]
        azimuth = math.atan2(long[0], long[1]) % math.pi
    else:
        azimuth = math.radians(spec.azimuth_deg)
    centre = np.asarray(area.centroid.coords[0])
    plan = FlightPlan(spec, azimuth, centre, h, (across, along), base, spacing, float(area.area),
                      np.zeros(0), np.zeros(0, dtype=int), np.zeros(0, dtype=int),
                      np.zeros((0, 2)))
    coords = shapely.get_coordinates(area)
    uv_all = (coords - centre) @ plan.frame.T
    vmin, vmax = uv_all[:, 1].min(), uv_all[:, 1].max()
    n_strips = max(1, math.ceil((vmax - vmin - across) / spacing - 1e-9) + 1)
    if max_models is not None and n_strips > 100 * (max_models + 1):
        raise BlockTooLarge(n_strips, None, max_models)  # absurd: not even counted
    strip_v = 0.5 * (vmin + vmax) + (np.arange(n_strips) - 0.5 * (n_strips - 1)) * spacing
    # the area in the flight frame, to cut each strip's share of it
    inv = plan.frame  # ground = origin + uv @ frame  ->  uv = (ground - origin) @ frame.T
    local = shapely.transform(area, lambda xy: (xy - centre) @ inv.T)
    big = 10.0 * (np.ptp(uv_all, axis=0).max() + across + along)
    strips, index, uvs, kept = [], [], [], []
    n_models = 0
    for s, v in enumerate(strip_v):
        lo = v - spacing / 2 if s > 0 else -big
        hi = v + spacing / 2 if s < n_strips - 1 else big
        band = shapely.box(-big, lo, big, hi).intersection(local)
        if band.is_empty or band.area <= 0:
            continue  # a concave area may leave a strip with nothing to cover
        u0, _, u1, _ = band.bounds
        n = max(2, math.ceil((u1 - u0 - along) / base - 1e-9) + 3)
        n_models += n - 1
        if max_models is not None and n_models > max_models:
            raise BlockTooLarge(n_strips, n_models, max_models)
        us = 0.5 * (u0 + u1) + (np.arange(n) - 0.5 * (n - 1)) * base
        strips += [len(kept)] * n
        kept.append(v)
        index += list(range(n))
        uvs.append(np.column_stack([us, np.full(n, v)]))
    plan.strip_v = np.array(kept)
    plan.area_uv = local
    plan.photo_strip = np.array(strips, dtype=int)
    plan.photo_index = np.array(index, dtype=int)
    plan.photo_uv = np.vstack(uvs)
    _control(plan)
    return plan


def _control(plan: FlightPlan) -> None:
    """Fill plan.control_* by the rules of the module docstring (kinds XYZ, XY, Z; a location
    that two rules ask for gets the union of their components)."""
    spec, base, a = plan.spec, plan.base, plan.spacing
    locations: dict[tuple[float, float], tuple[set[str], list[str]]] = {}

    def add(u: float, v: float, comps: str, reason: str) -> None:
        kind, reasons = locations.setdefault((round(u, 3), round(v, 3)), (set(), []))
        kind.update(comps)
        if reason not in reasons:
            reasons.append(reason)

    last = plan.n_strips - 1
    for s in range(plan.n_strips):
        uv = plan.photo_uv[plan.photo_strip == s]
        v = plan.strip_v[s]
        # the short edges: full control at both strip ends, on the strip's side-overlap lines
        ends = (uv[0, 0] + base / 2, uv[-1, 0] - base / 2) if len(uv) > 2 else (uv[0, 0],)
        for u in ends:
            for dv in (-a / 2, a / 2):
                add(u, v + dv, "XYZ", "strip end")
        # planimetric control along the long edges (outer side of the first and last strips)
        for side, dv in ((0, -a / 2), (last, a / 2)):
            if s == side:
                for k in _stations(len(uv), spec.edge_interval):
                    add(uv[k, 0], v + dv, "XY", "long edge")
        # height-control lines across the block, one point per side-overlap line
        for k in _stations(len(uv), spec.height_interval):
            for dv in (-a / 2, a / 2):
                add(uv[k, 0], v + dv, "Z", "height line")
    uv, kinds, reasons = [], [], []
    for (u, v), (kind, why) in sorted(locations.items()):
        offsets = (-0.05 * base, 0.05 * base) if spec.pairs else (0.0,)
        for du in offsets:
            uv.append((u + du, v))
            kinds.append("".join(c for c in "XYZ" if c in kind))
            reasons.append(", ".join(why))
    plan.control_uv = np.array(uv, dtype=float).reshape(-1, 2)
    plan.control_kind = kinds
    plan.control_reason = reasons


def _stations(n_photos: int, interval: int) -> list[int]:
    """Inner photo positions 1, 1 + interval, ... and the last inner one (n - 2)."""
    if n_photos < 3:
        return [0, n_photos - 1][:n_photos]
    return sorted({*range(1, n_photos - 1, interval), n_photos - 2})
