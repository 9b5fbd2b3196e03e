"""From the product's tables and project to a :class:`~toolbox.triangulation.block.Block`.

- image measurements (``point_id``, ``photo``, ``col_px``/``row_px`` or ``x_mm``/``y_mm``,
  optional ``sigma_px`` / ``sigma_mm``): pixels go to image mm through each photo's interior
  orientation (fiducial fit or pixel size), their sigma by the transform's pixel size;
- control (``id``, ``X``, ``Y``, ``Z``, optional ``role`` control/check, optional ``sigma_xy``,
  ``sigma_z`` in metres): an empty X and Y makes a height (Z-only) point, an empty Z a
  planimetric (XY-only) one; check points are not observations: they are adjusted as tie points
  and compared afterwards;
- GNSS projection centres (``photo``, ``X``, ``Y``, ``Z``, optional ``sigma_xy``, ``sigma_z``,
  ``strip`` (default: the project's strip of the photo) and ``time`` (default: the photo's place
  in its strip, centred), used by the per-strip shift and drift unknowns);
- IMU attitudes (``photo``, ``omega``, ``phi``, ``kappa`` in the photogrammetric convention,
  optional ``sigma``, all in one angle unit);
- self-calibration: ``c, k1`` or ``c:weighted:0.01, x0, y0`` (parameter[:mode[:sigma]]).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from toolbox.errors import InputDataError, ParameterError
from toolbox.triangulation.block import FIXED, MODE_NAMES, WEIGHTED, Block
from toolbox.triangulation.model import CALIBRATION_NAMES, KIND_BROWN, KIND_FILM, KIND_MODEL

#: a digital (Brown) camera's f, cx, cy take the film camera's c, x0, y0 places
BROWN_ALIASES = {"f": "c", "cx": "x0", "cy": "y0"}


@dataclass
class Measurements:
    """Image measurements as read: ids, photos, values (M, 2) in ``kind`` units, sigma (M,) or
    NaN where the table gives none."""

    point_ids: list[str]
    photo_ids: list[str]
    xy: np.ndarray
    kind: str  # "pixel" or "image"
    sigma: np.ndarray

    def concatenate(self, other: Measurements) -> Measurements:
        """Both tables' rows (same kind of coordinates)."""
        return Measurements(self.point_ids + other.point_ids, self.photo_ids + other.photo_ids,
                            np.vstack([self.xy, other.xy]), self.kind,
                            np.concatenate([self.sigma, other.sigma]))


@dataclass
class Control:
    """Surveyed points: ids, xyz (n, 3; NaN = component unknown), roles, sigmas (n, 3; NaN =
    default)."""

    ids: list[str]
    xyz: np.ndarray
    roles: list[str]
    sigma: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __post_init__(self) -> None:
        self.xyz = np.asarray(self.xyz, dtype=float).reshape(-1, 3)
        if len(self.sigma) != len(self.ids):
            self.sigma = np.full((len(self.ids), 3), np.nan)


@dataclass
class Centres:
    """GNSS projection centres: photo ids, xyz (n, 3), sigmas (n, 3; NaN = default)."""

    photos: list[str]
    xyz: np.ndarray
    sigma: np.ndarray
    strips: list[str] | None = None  # per row; None or "" = the project's strip of the photo
    times: np.ndarray | None = None  # per row; NaN = the photo's place in its strip


@dataclass
class Attitudes:
    """IMU attitudes: photo ids, angles (n, 3) rad, sigmas (n, 3) rad (NaN = default)."""

    photos: list[str]
    angles: np.ndarray
    sigma: np.ndarray


@dataclass
class BlockRequest:
    """Everything the bundle needs besides the approximations (sigmas: px, mm, m)."""

    project: object
    measurements: Measurements
    control: Control
    centres: Centres | None = None
    self_calibration: str = ""
    sigma_px: float = 0.5
    sigma_mm: float = 0.005
    control_sigma_xy: float = 0.02
    control_sigma_z: float = 0.03
    centre_sigma_xy: float = 0.10
    centre_sigma_z: float = 0.15
    lever_arm: tuple[float, float, float] = (0.0, 0.0, 0.0)  # GNSS antenna, camera frame, m
    gnss_shift: bool = False  # unknown GNSS shift per strip
    gnss_drift: bool = False  # unknown GNSS drift per strip (m per time unit)
    attitudes: Attitudes | None = None
    attitude_sigma: float = 8.7e-5  # rad (0.005°)
    boresight: bool = False


def read_measurements(path: Path, layer: str | None, coordinates: str,
                      name: str = "INPUT") -> Measurements:
    from toolbox.photogrammetry.tables import column, image_measurements, number, read_table

    ids, photos, xy, kind = image_measurements(path, layer, coordinates, name)
    header, rows = read_table(path, layer, name)
    c_sigma = column(header, "sigma_px" if kind == "pixel" else "sigma_mm", "sigma",
                     required=False)
    sigma = np.full(len(ids), np.nan)
    if c_sigma:
        for k, r in enumerate(rows):
            if r[c_sigma] != "":
                sigma[k] = number(r[c_sigma], f"row {k + 1} {c_sigma}", name)
                if not sigma[k] > 0:
                    raise InputDataError(f"{name}: {path} row {k + 1}: {c_sigma} must be > 0, "
                                         f"got {r[c_sigma]!r}")
    return Measurements(ids, photos, xy, kind, sigma)


def _optional(value: str, what: str, name: str) -> float:
    from toolbox.photogrammetry.tables import number

    return np.nan if value.strip() == "" else number(value, what, name)


def read_control(path: Path, layer: str | None = None, name: str = "CONTROL") -> Control:
    from toolbox.photogrammetry.tables import column, known_point_rows

    header, cols, rows = known_point_rows(path, layer, name)
    c_sxy = column(header, "sigma_xy", required=False)
    c_sz = column(header, "sigma_z", required=False)
    ids, xyz, roles, sig = [], [], [], []
    for k, r, pid, role in rows:
        vals = [_optional(r[c], f"row {k} {c}", name) for c in cols]
        if np.isnan(vals[0]) != np.isnan(vals[1]) or all(np.isnan(vals)):
            raise InputDataError(f"{name}: {path} row {k} (point {pid!r}): give X and Y "
                                 "together, Z, or all three")
        sxy = _optional(r[c_sxy], f"row {k} {c_sxy}", name) if c_sxy else np.nan
        sz = _optional(r[c_sz], f"row {k} {c_sz}", name) if c_sz else np.nan
        for s, what in ((sxy, c_sxy), (sz, c_sz)):
            if not np.isnan(s) and not s > 0:
                raise InputDataError(f"{name}: {path} row {k} (point {pid!r}): {what} must be "
                                     f"> 0, got {s!r}")
        ids.append(pid)
        roles.append(role)
        xyz.append(vals)
        sig.append([sxy, sxy, sz])
    return Control(ids, np.array(xyz), roles, np.array(sig))


def read_centres(path: Path, layer: str | None = None, name: str = "GNSS") -> Centres:
    from toolbox.photogrammetry.tables import column, number, read_table

    header, rows = read_table(path, layer, name)
    c_photo = column(header, "photo", "photo_id", "image", "filename", name=name, path=path)
    cols = [column(header, *a, name=name, path=path) for a in
            (("X0", "X", "E"), ("Y0", "Y", "N"), ("Z0", "Z", "H"))]
    c_sxy = column(header, "sigma_xy", required=False)
    c_sz = column(header, "sigma_z", required=False)
    c_strip = column(header, "strip", required=False)
    c_time = column(header, "time", "t", required=False)
    photos, xyz, sig, strips, times = [], [], [], [], []
    for k, r in enumerate(rows, start=1):
        strips.append(r[c_strip].strip() if c_strip else "")
        times.append(_optional(r[c_time], f"row {k} {c_time}", name) if c_time else np.nan)
        if r[c_photo] in photos:
            raise InputDataError(f"{name}: {path} lists photo {r[c_photo]!r} twice")
        photos.append(r[c_photo])
        xyz.append([number(r[c], f"row {k} {c}", name) for c in cols])
        sxy = _optional(r[c_sxy], f"row {k} {c_sxy}", name) if c_sxy else np.nan
        sz = _optional(r[c_sz], f"row {k} {c_sz}", name) if c_sz else np.nan
        for s, what in ((sxy, c_sxy), (sz, c_sz)):
            if not np.isnan(s) and not s > 0:
                raise InputDataError(f"{name}: {path} row {k}: {what} must be > 0, got {s!r}")
        sig.append([sxy, sxy, sz])
    return Centres(photos, np.array(xyz, dtype=float).reshape(-1, 3),
                   np.array(sig, dtype=float).reshape(-1, 3), strips, np.array(times, dtype=float))


def read_attitudes(path: Path, unit: str, layer: str | None = None, name: str = "IMU"
                   ) -> Attitudes:
    """IMU attitudes (``photo``, ``omega``, ``phi``, ``kappa``, optional ``sigma``) in
    ``unit`` (rad, deg, gon), returned in radians."""
    from toolbox.photogrammetry.rotation import to_radians
    from toolbox.photogrammetry.tables import column, number, read_table

    header, rows = read_table(path, layer, name)
    c_photo = column(header, "photo", "photo_id", "image", "filename", name=name, path=path)
    cols = [column(header, *a, name=name, path=path) for a in
            (("omega", "roll"), ("phi", "pitch"), ("kappa", "yaw", "heading"))]
    c_sig = column(header, "sigma", required=False)
    photos, angles, sig = [], [], []
    for k, r in enumerate(rows, start=1):
        if r[c_photo] in photos:
            raise InputDataError(f"{name}: {path} lists photo {r[c_photo]!r} twice")
        photos.append(r[c_photo])
        angles.append([number(r[c], f"row {k} {c}", name) for c in cols])
        s = _optional(r[c_sig], f"row {k} {c_sig}", name) if c_sig else np.nan
        if not np.isnan(s) and not s > 0:
            raise InputDataError(f"{name}: {path} row {k}: {c_sig} must be > 0, got {s!r}")
        sig.append([s] * 3)
    return Attitudes(photos, to_radians(np.array(angles, dtype=float).reshape(-1, 3), unit),
                     to_radians(np.array(sig, dtype=float).reshape(-1, 3), unit))


def parse_lever_arm(text: str | None, name: str = "LEVER_ARM") -> tuple[float, float, float]:
    """``"0.1, -0.2, 1.5"`` -> (0.1, -0.2, 1.5); empty -> zeros."""
    if not text or not str(text).strip():
        return (0.0, 0.0, 0.0)
    parts = [p for p in str(text).replace(";", ",").replace(" ", ",").split(",") if p]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(np.isfinite(values)):
        raise ParameterError(name, f"must be three numbers 'x, y, z' (metres, camera frame), got "
                             f"{text!r}")
    return values  # type: ignore[return-value]


def parse_self_calibration(text: str, name: str = "SELF_CALIBRATION"
                           ) -> dict[tuple[str | None, str], tuple[int, float]]:
    """``"c, k1:weighted:1e-6, x0@wild 303.55"`` -> ``{(None, "c"): (FREE, nan), (None, "k1"):
    (WEIGHTED, 1e-6), ("wild 303.55", "x0"): (FREE, nan)}``: ``PARAMETER[@CAMERA][:MODE[:SIGMA]]``,
    for every camera unless ``@CAMERA`` names one (which then overrides)."""
    result: dict[tuple[str | None, str], tuple[int, float]] = {}
    for item in (text or "").replace(";", ",").split(","):
        item = item.strip()
        if not item:
            continue
        parts = [p.strip() for p in item.split(":")]
        par, _, camera = parts[0].partition("@")
        par = par.strip().lower()
        par = BROWN_ALIASES.get(par, par)
        if par not in CALIBRATION_NAMES:
            raise ParameterError(name, f"unknown calibration parameter {par!r}; expected "
                                 f"one of {', '.join(CALIBRATION_NAMES)} (f, cx, cy for a "
                                 "digital Brown camera) (optionally @CAMERA)")
        mode = parts[1].lower() if len(parts) > 1 else "free"
        if mode not in MODE_NAMES or len(parts) > 3:
            raise ParameterError(name, f"{item!r}: mode must be fixed, free or "
                                 "weighted:SIGMA")
        sigma = np.nan
        if MODE_NAMES[mode] == WEIGHTED:
            try:
                sigma = float(parts[2])
            except (IndexError, ValueError):
                sigma = np.nan
            if not sigma > 0:
                raise ParameterError(name, f"{item!r}: a weighted parameter needs a sigma > 0 "
                                     "(e.g. c:weighted:0.01)")
        result[(camera.strip() or None, par)] = (MODE_NAMES[mode], sigma)
    return result


def calibration_settings(spec: dict[tuple[str | None, str], tuple[int, float]],
                         cameras: list[str], all_cameras, name: str = "SELF_CALIBRATION"
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Modes and sigmas (k, 8) of ``cameras`` from a parsed specification."""
    unknown = sorted({c for c, _ in spec if c is not None and c not in all_cameras})
    if unknown:
        raise ParameterError(name, f"names camera(s) {', '.join(map(repr, unknown))} that "
                             f"PROJECT does not have (cameras: {', '.join(all_cameras)})")
    modes = np.full((len(cameras), 8), FIXED)
    sig = np.full((len(cameras), 8), np.nan)
    for general in (True, False):  # camera-specific entries override the general ones
        for (camera, par), (mode, s) in spec.items():
            if (camera is None) != general:
                continue
            for k, cam in enumerate(cameras):
                if camera is None or camera == cam:
                    modes[k, CALIBRATION_NAMES.index(par)] = mode
                    sig[k, CALIBRATION_NAMES.index(par)] = s
    return modes, sig


def camera_calibration(camera, free: set[str]) -> np.ndarray:
    """Start values (8,) of a project camera; its distortion must be a polynomial (or none)
    when distortion terms are estimated, and a table is applied to the measurements instead.
    A model camera (pinhole or brown): ``(fx px, cx px, cy px, k1, k2, k3, p1, p2)``."""
    from toolbox.cameras import Intrinsics
    from toolbox.photogrammetry.camera import DISTORTION_POLYNOMIAL

    if isinstance(camera, Intrinsics):
        if camera.kind not in ("pinhole", "brown") and free:
            raise ParameterError("SELF_CALIBRATION", f"camera {camera.name!r} is a "
                                 f"{camera.kind} model: its interior is held fixed (only film, "
                                 "pinhole or brown cameras are self-calibrated); drop "
                                 f"{', '.join(sorted(free))}")
        if camera.kind not in ("pinhole", "brown"):
            return np.array([camera.focal_px[0], *camera.principal_point_px, 0, 0, 0, 0, 0])
        c = camera.coefficients
        return np.array([camera.focal_px[0], *camera.principal_point_px,
                         *(c.get(k, 0.0) for k in ("k1", "k2", "k3", "p1", "p2"))])
    values = np.zeros(8)
    values[0] = camera.c
    values[1:3] = camera.principal_point_mm
    dist = camera.distortion
    if dist is not None and dist.mode == DISTORTION_POLYNOMIAL:
        values[3:] = dist.k1, dist.k2, dist.k3, dist.p1, dist.p2
    elif dist is not None and any(k in free for k in ("k1", "k2", "k3", "p1", "p2")):
        raise ParameterError("SELF_CALIBRATION", f"camera {camera.name!r} has a distortion "
                             "table; k1-k3, p1, p2 can be estimated only for a polynomial "
                             "distortion or none")
    return values


def build_block(request: BlockRequest) -> tuple[Block, dict]:
    """The block and a dict of bookkeeping (check point ids, measurement kind, pixel sizes)."""
    project = request.project
    ms = request.measurements
    unknown = sorted({p for p in ms.photo_ids if p not in project.photos})
    if unknown:
        raise InputDataError(f"INPUT names photo(s) {', '.join(map(repr, unknown[:5]))} that "
                             f"PROJECT does not have (photos: {', '.join(project.photos)})")
    photo_ids = [p for p in project.photos if p in set(ms.photo_ids)]
    photo_index = {p: k for k, p in enumerate(photo_ids)}
    camera_names = list(dict.fromkeys(project.photos[p].camera.name for p in photo_ids))
    cam_index = {c: k for k, c in enumerate(camera_names)}
    photo_camera = np.array([cam_index[project.photos[p].camera.name] for p in photo_ids])
    point_ids = list(dict.fromkeys(ms.point_ids))
    point_index = {p: k for k, p in enumerate(point_ids)}
    spec = parse_self_calibration(request.self_calibration)
    modes, sig = calibration_settings(spec, camera_names, list(project.cameras))
    calibration = np.array([
        camera_calibration(project.cameras[c],
                           {CALIBRATION_NAMES[i] for i in np.flatnonzero(modes[k] != FIXED)})
        for k, c in enumerate(camera_names)])
    # image mm and sigmas
    xy = np.array(ms.xy, dtype=float)
    sigma = np.array(ms.sigma, dtype=float)
    pixel_mm = {}
    rows_of: dict[str, list[int]] = {}
    for k, p in enumerate(ms.photo_ids):
        rows_of.setdefault(p, []).append(k)
    for pid in photo_ids:
        rows = rows_of[pid]
        photo = project.photos[pid]
        if photo.is_model:  # Brown / pinhole: pixels observed as they are (forward model)
            if ms.kind != "pixel":
                raise InputDataError(f"photo {pid!r}: its camera {photo.camera.name!r} is a "
                                     f"{photo.camera.kind} model: give its measurements in "
                                     "pixels (col_px, row_px), not image mm")
            pixel_mm[pid] = 1.0  # its image units are pixels
            sigma[rows] = np.where(np.isnan(sigma[rows]), request.sigma_px, sigma[rows])
            continue
        if ms.kind == "pixel":
            transform = photo.require_pixel_transform()
            xy[rows] = transform.pixel_to_image(xy[rows])
            size = transform.pixel_size_mm
            pixel_mm[pid] = size
            sigma[rows] = np.where(np.isnan(sigma[rows]), request.sigma_px, sigma[rows]) * size
        else:
            sigma[rows] = np.where(np.isnan(sigma[rows]), request.sigma_mm, sigma[rows])
        dist = photo.camera.distortion
        if dist is not None and dist.mode != 2:  # a table: applied once, not estimated
            pp = np.asarray(photo.camera.principal_point_mm)
            xy[rows] = dist.correct(xy[rows] - pp) + pp
    # control (role control) as observations; check points compared afterwards
    ctrl = request.control
    where = {pid: k for k, pid in enumerate(ctrl.ids)}
    g_point, g_xyz, g_sig = [], [], []
    checks = []
    for pid in point_ids:
        if pid not in where:
            continue
        k = where[pid]
        if ctrl.roles[k] == "check":
            checks.append(pid)
            continue
        g_point.append(point_index[pid])
        g_xyz.append(ctrl.xyz[k])
        g_sig.append(_sigma_or(ctrl.sigma[k], request.control_sigma_xy, request.control_sigma_z))
    h_photo, h_xyz, h_sig, h_strip, h_time = [], [], [], [], []
    if request.centres is not None:
        cen = request.centres
        for k, p in enumerate(_require_photos(cen.photos, project, "GNSS")):
            if p not in photo_index:
                continue
            h_photo.append(photo_index[p])
            h_xyz.append(cen.xyz[k])
            h_strip.append((cen.strips[k] if cen.strips else "") or
                           str(getattr(project.photos[p], "strip", None) or ""))
            h_time.append(cen.times[k] if cen.times is not None else np.nan)
            h_sig.append(_sigma_or(cen.sigma[k], request.centre_sigma_xy, request.centre_sigma_z))
    groups, times = _strips_and_times(h_photo, h_strip, np.array(h_time, dtype=float),
                                      photo_ids)
    time_origin = np.zeros(int(groups.max()) + 1 if len(groups) else 0)
    if request.gnss_shift and request.gnss_drift:
        # s + d·t = (s + d·t0) + d·(t - t0): with a shift the time origin is free, and times
        # given as GPS seconds of week or POSIX seconds (1.7e9) make the shift and drift
        # columns parallel (a false "singular"): each strip is solved about its mean time, the
        # shift reported at that time
        for g in range(len(time_origin)):
            time_origin[g] = float(np.round(times[groups == g].mean()))
        times = times - time_origin[groups]
    a_photo, a_obs, a_sig = [], [], []
    if request.attitudes is not None:
        att = request.attitudes
        for k, p in enumerate(_require_photos(att.photos, project, "IMU")):
            if p in photo_index:
                a_photo.append(photo_index[p])
                a_obs.append(att.angles[k])
                a_sig.append(np.where(np.isnan(att.sigma[k]), request.attitude_sigma,
                                      att.sigma[k]))
    sigma2 = np.repeat(sigma[:, None], 2, axis=1)
    block = Block(photo_ids, photo_camera, camera_names, calibration, point_ids,
                  [photo_index[p] for p in ms.photo_ids], [point_index[p] for p in ms.point_ids],
                  xy, sigma2, modes, sig, g_point, np.array(g_xyz).reshape(-1, 3),
                  np.array(g_sig).reshape(-1, 3), h_photo, np.array(h_xyz).reshape(-1, 3),
                  np.array(h_sig).reshape(-1, 3), np.asarray(request.lever_arm, dtype=float),
                  groups, times, request.gnss_shift, request.gnss_drift, a_photo,
                  np.array(a_obs, dtype=float).reshape(-1, 3),
                  np.array(a_sig, dtype=float).reshape(-1, 3), request.boresight,
                  [_kind(project.cameras[c]) for c in camera_names],
                  [_aspect(project.cameras[c]) for c in camera_names],
                  [project.cameras[c] if _kind(project.cameras[c]) == KIND_MODEL else None
                   for c in camera_names])
    info_strips = sorted(set(h_strip), key=lambda v: (len(v), v))
    return block, {"checks": checks, "kind": ms.kind, "pixel_mm": pixel_mm,
                   "model_photos": {p for p in photo_ids if project.photos[p].is_model},
                   "gnss_strips": info_strips, "gnss_time_origin": time_origin.tolist(),
                   "free": [f"{block.calibration_label(k, i)}" for k, i in
                            np.argwhere(modes != FIXED)]}


def _strips_and_times(photos: list[int], strips: list[str], times: np.ndarray,
                      photo_ids: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Group index (0..G-1, in order of the strip names) of each GNSS row, and its time: the
    given one, or the photo's place in its strip (block order), centred on the strip."""
    names = sorted(set(strips), key=lambda v: (len(v), v))
    groups = np.array([names.index(s) for s in strips], dtype=np.int64)
    times = times.copy()
    for g in range(len(names)):
        rows = np.flatnonzero((groups == g) & np.isnan(times))
        if len(rows):
            order = np.argsort(np.argsort([photos[i] for i in rows]))
            times[rows] = order - (len(rows) - 1) / 2
    return groups, times


def _is_model(camera) -> bool:
    from toolbox.cameras import Intrinsics

    return isinstance(camera, Intrinsics)


def _kind(camera) -> int:
    """KIND_FILM, KIND_BROWN (pinhole, brown) or KIND_MODEL (opencv, fisheye) of a camera."""
    if not _is_model(camera):
        return KIND_FILM
    return KIND_BROWN if camera.kind in ("pinhole", "brown") else KIND_MODEL


def _aspect(camera) -> float:
    """fy/fx of a model camera (1 for film)."""
    return camera.focal_px[1] / camera.focal_px[0] if _is_model(camera) else 1.0


def _sigma_or(sigma: np.ndarray, sigma_xy: float, sigma_z: float) -> np.ndarray:
    """(sx, sy, sz) of a point with the defaults where the table left them blank (NaN)."""
    s = np.array(sigma, dtype=float)
    s[:2] = np.where(np.isnan(s[:2]), sigma_xy, s[:2])
    s[2] = sigma_z if np.isnan(s[2]) else s[2]
    return s


def _require_photos(photos: list[str], project: object, name: str) -> list[str]:
    """``photos`` as PROJECT's photo ids: an image file name (``id.tif``, as the ``filename``
    column of Orthority's CSV, or of orientation:convert's, may give it) stands for the photo
    its stem names. Names of no photo are an error."""
    from toolbox.exchange.project import IMAGE_SUFFIXES

    out = [p if p in project.photos or Path(p).suffix.lower() not in IMAGE_SUFFIXES
           else Path(p).stem for p in photos]
    bad = [p for p, q in zip(photos, out, strict=True) if q not in project.photos]
    if bad:
        raise InputDataError(f"{name} names photo(s) {', '.join(map(repr, bad[:5]))} that "
                             "PROJECT does not have")
    return out
