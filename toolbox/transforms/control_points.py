"""Control-point tables for rectification: ids, image and ground coordinates, roles.

A table is any point layer OGR reads (the geometry holds the ground X, Y and optionally Z) or a
CSV with X/Y(/Z) columns (see :mod:`toolbox.io.vector`), plus the image coordinates of each point
in two columns:

- ``IMAGE_UNITS = pixels``: ``col``/``row`` (also ``column``/``row``, ``col_px``/``row_px``,
  ``pixel``/``line``, ``x_px``/``y_px``). **Pixel convention**: the origin is the top-left corner
  of the top-left pixel, columns grow to the right and rows *down*, and the centre of the
  top-left pixel is (0.5, 0.5) (GDAL's pixel/line convention, also used for embedded GCPs).
- ``IMAGE_UNITS = mm``: ``x_mm``/``y_mm`` (also ``xi``/``eta``): fiducial (image) system,
  origin at the fiducial centre, x right, y *up* (domain brief section 1).

Optional columns: an id (``id``, ``name``, ``point``, ``gcp``, ``label``) and a role (``role``,
``type``, ``use``, ``check``, ``kind``) whose values are ``control`` (also empty, ``gcp``,
``0``, ``no``, ``false``), ``check`` (also ``checkpoint``, ``cp``, ``1``, ``yes``, ``true``) or
``ignore`` (also ``skip``, ``off``). Check points are excluded from the fit and reported
separately; ignored points are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolbox.errors import InputDataError

IMAGE_UNITS = ("pixels", "mm")
IMAGE_FIELD_PAIRS = {
    "pixels": (("col", "row"), ("column", "row"), ("col_px", "row_px"), ("pixel", "line"),
               ("x_px", "y_px"), ("x_pixel", "y_pixel"), ("image_col", "image_row")),
    "mm": (("x_mm", "y_mm"), ("xi", "eta"), ("image_x", "image_y"), ("x_image", "y_image")),
}
ID_FIELDS = ("id", "name", "point", "point_id", "gcp", "label")
ROLE_FIELDS = ("role", "type", "use", "check", "kind")
ROLE_WORDS = {
    "control": {"", "control", "gcp", "ctrl", "0", "no", "n", "false", "f", "nan", "none"},
    "check": {"check", "checkpoint", "check_point", "check point", "cp", "chk", "1", "yes", "y",
              "true", "t"},
    "ignore": {"ignore", "ignored", "skip", "off", "disabled", "exclude", "excluded"},
}
ROLES = ("control", "check", "ignore")


@dataclass
class ControlPoints:
    """Matched image and ground coordinates.

    ids : list of N str
    image : (N, 2) float64, image coordinates (pixels: col, row down; mm: x right, y up)
    ground : (N, 2) float64, ground X, Y (CRS units, or a local object system)
    z : (N,) float64 ground heights, or None when the table has none
    role : (N,) str array, "control" or "check"
    units : "pixels" or "mm"
    """

    ids: list[str]
    image: np.ndarray
    ground: np.ndarray
    z: np.ndarray | None
    role: np.ndarray
    units: str = "pixels"

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def control(self) -> np.ndarray:
        return self.role == "control"

    @property
    def check(self) -> np.ndarray:
        return self.role == "check"

    def subset(self, mask: np.ndarray) -> ControlPoints:
        ids = [i for i, keep in zip(self.ids, mask, strict=True) if keep]
        return ControlPoints(ids, self.image[mask], self.ground[mask],
                             None if self.z is None else self.z[mask], self.role[mask],
                             self.units)


def _match(fields: list[str], wanted: str) -> str | None:
    lower = {f.lower(): f for f in fields}
    return lower.get(wanted.lower())


def find_image_fields(fields: list[str], units: str) -> tuple[str, str] | None:
    """The first known (x, y) column pair for ``units`` present in ``fields`` (any case)."""
    for x_name, y_name in IMAGE_FIELD_PAIRS[units]:
        x, y = _match(fields, x_name), _match(fields, y_name)
        if x is not None and y is not None:
            return x, y
    return None


def find_field(fields: list[str], candidates: tuple[str, ...]) -> str | None:
    """The first of ``candidates`` present in ``fields`` (any case), else None."""
    for name in candidates:
        found = _match(fields, name)
        if found is not None:
            return found
    return None


def parse_roles(values, name: str = "role") -> np.ndarray:
    """Map free-text role values to ``control`` / ``check`` / ``ignore``.

    Raises :class:`InputDataError` naming the first value it does not know.
    """
    out = []
    for i, value in enumerate(values):
        if isinstance(value, (bool, np.bool_)):
            text = "true" if value else "false"
        elif isinstance(value, (float, np.floating)) and np.isfinite(value) and value == int(value):
            text = str(int(value))
        else:
            text = "" if value is None else str(value).strip().lower()
        for role, words in ROLE_WORDS.items():
            if text in words:
                out.append(role)
                break
        else:
            raise InputDataError(f"{name} of point {i + 1} is {value!r}; expected control, check "
                                 "or ignore (also gcp/cp, 0/1, yes/no, true/false)")
    return np.array(out, dtype=object)


def control_points_from_frame(frame, units: str = "pixels", image_fields: tuple[str, str] | None = None,
                              id_field: str | None = None, role_field: str | None = None,
                              name: str = "INPUT") -> ControlPoints:
    """Read control points from a GeoDataFrame of points (ground X, Y[, Z] in the geometry).

    Columns not given are detected by name (module docstring). Points with role ``ignore`` are
    dropped. Raises :class:`InputDataError` for missing columns, non-numeric or NaN
    coordinates, non-point geometries and duplicate ids.
    """
    import shapely

    if units not in IMAGE_UNITS:
        raise ValueError(f"units must be one of {IMAGE_UNITS}, got {units!r}")
    fields = [c for c in frame.columns if c != frame.geometry.name]
    if len(frame) == 0:
        raise InputDataError(f"{name} has no control points")
    if image_fields is None:
        image_fields = find_image_fields(fields, units)
        if image_fields is None:
            pairs = ", ".join("/".join(p) for p in IMAGE_FIELD_PAIRS[units])
            raise InputDataError(f"{name} has no image-coordinate columns for IMAGE_UNITS={units}: "
                                 f"expected one of {pairs} (or name them with IMAGE_X_FIELD and "
                                 f"IMAGE_Y_FIELD); its columns are: {', '.join(fields) or '(none)'}")
    geoms = frame.geometry.values
    if np.any(shapely.is_missing(geoms)) or np.any(shapely.is_empty(geoms)):
        raise InputDataError(f"{name}: some control points have no ground coordinates (empty or "
                             "null geometry)")
    if set(shapely.get_type_id(geoms).tolist()) != {0}:
        raise InputDataError(f"{name} must hold single points (ground X, Y of each control point)")
    has_z = bool(frame.geometry.has_z.all())
    coords = shapely.get_coordinates(geoms, include_z=has_z)
    ground = coords[:, :2].astype("float64")
    z = coords[:, 2].astype("float64") if has_z else None
    try:
        image = np.column_stack([np.asarray(frame[f], dtype="float64") for f in image_fields])
    except (TypeError, ValueError):
        raise InputDataError(f"{name}: image columns {image_fields[0]}/{image_fields[1]} must be "
                             "numeric") from None
    ids_field = id_field or find_field(fields, ID_FIELDS)
    ids = ([str(v) for v in frame[ids_field]] if ids_field is not None
           else [str(i + 1) for i in range(len(frame))])
    roles_field = role_field or find_field(fields, ROLE_FIELDS)
    role = (parse_roles(frame[roles_field].tolist(), roles_field) if roles_field is not None
            else np.array(["control"] * len(frame), dtype=object))
    bad = ~(np.isfinite(image).all(axis=1) & np.isfinite(ground).all(axis=1))
    if bad.any():
        first = [ids[i] for i in np.flatnonzero(bad)[:5]]
        raise InputDataError(f"{name}: {int(bad.sum())} control point(s) have NaN/empty image or "
                             f"ground coordinates: {', '.join(first)}")
    seen: dict[str, int] = {}
    for i, ident in enumerate(ids):
        if ident in seen:
            raise InputDataError(f"{name}: point id {ident!r} appears twice (rows {seen[ident] + 1} "
                                 f"and {i + 1}); ids must be unique")
        seen[ident] = i
    points = ControlPoints(ids, image, ground, z, role, units)
    keep = role != "ignore"
    return points if keep.all() else points.subset(keep)
