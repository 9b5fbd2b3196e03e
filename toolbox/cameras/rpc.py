"""RPC (rational polynomial coefficient) cameras of satellite images.

The coefficients are read through GDAL (:func:`read_rpc`: the GeoTIFF's RPC tags, an ``.RPB`` or
``_RPC.TXT`` beside the image, whatever GDAL finds) or given as Orthority's RPC schema. The
model (RPC00B, the order GDAL and the NITF standard use): with ``P``, ``L``, ``H`` the latitude,
longitude and height normalised by their offsets and scales,
``line = line_off + line_scale·Num_L(P, L, H)/Den_L(P, L, H)`` (samples likewise), each a cubic of
20 terms. Lines and samples count pixel *centres* from 0, so the product's pixel is
``(sample + 0.5, line + 0.5)``. Heights are those the RPCs are made for (ellipsoidal, in
practice): the DEM must give the same.

Ground -> pixel needs heights (an RPC camera is not a central projection): ortho needs a DEM.
Pixel -> ground is solved at given heights by Newton's method on (lon, lat), to
``tolerance_px`` in the image; pixels that do not converge come back NaN.

Bias refinement (:func:`refine_bias`; Grodecki and Dial 2003, "Block adjustment of
high-resolution satellite images described by rational polynomials", PE&RS 69(1)): the RPCs'
pixels are corrected by an image-space shift (1+ ground control points) or affinity (3+),
``pixel' = A·(col, row, 1)``, fitted by least squares to GCPs measured on the image.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from toolbox.errors import InputDataError

DEFAULT_TOLERANCE_PX = 1e-3
RPC_FIELDS = ("line_off", "samp_off", "lat_off", "long_off", "height_off", "line_scale",
              "samp_scale", "lat_scale", "long_scale", "height_scale")
RPC_TERMS = ("line_num_coeff", "line_den_coeff", "samp_num_coeff", "samp_den_coeff")


@dataclass(frozen=True, eq=False)
class RpcCoefficients:
    """The offsets and scales (``RPC_FIELDS``) and the four 20-term polynomials."""

    values: dict[str, float]
    terms: dict[str, np.ndarray]

    @classmethod
    def from_mapping(cls, spec: Any, where: str = "rpc") -> RpcCoefficients:
        """From a mapping with Orthority's / rasterio's keys (lowercase; ``.to_dict()`` of a
        :class:`rasterio.rpc.RPC` gives them)."""
        if hasattr(spec, "to_dict"):
            spec = spec.to_dict()
        spec = {str(k).lower(): v for k, v in dict(spec).items()}
        missing = [k for k in RPC_FIELDS + RPC_TERMS if k not in spec]
        if missing:
            raise InputDataError(f"{where}: RPCs lack {', '.join(missing)}")
        try:
            values = {k: float(spec[k]) for k in RPC_FIELDS}
            terms = {k: np.asarray(spec[k], dtype="float64").ravel() for k in RPC_TERMS}
        except (TypeError, ValueError):
            raise InputDataError(f"{where}: RPC values must be numbers") from None
        bad = [k for k, t in terms.items() if t.shape != (20,) or not np.isfinite(t).all()]
        if bad or not all(np.isfinite(list(values.values()))):
            raise InputDataError(f"{where}: RPC polynomials need 20 finite terms each "
                                 f"({', '.join(bad) or 'offsets/scales not finite'})")
        if min(abs(values[k]) for k in RPC_FIELDS[5:]) == 0:
            raise InputDataError(f"{where}: an RPC scale is 0")
        return cls(values, terms)


def _monomials(p: np.ndarray, lo: np.ndarray, h: np.ndarray) -> np.ndarray:
    """The 20 RPC00B terms (20, N) of normalised latitude ``p``, longitude ``lo``, height ``h``."""
    one = np.ones_like(p)
    return np.stack([one, lo, p, h, lo * p, lo * h, p * h, lo * lo, p * p, h * h,
                     p * lo * h, lo ** 3, lo * p * p, lo * h * h, lo * lo * p, p ** 3,
                     p * h * h, lo * lo * h, p * p * h, h ** 3])


@dataclass(frozen=True, eq=False)
class RpcCamera:
    """An RPC camera (the :class:`~toolbox.cameras.base.CameraModel` protocol, without a
    projection centre). Ground coordinates are in ``crs`` (default: longitude, latitude in
    degrees, EPSG:4326), heights as the RPCs expect."""

    rpc: RpcCoefficients
    image_size_px: tuple[int, int]
    crs: Any = None
    tolerance_px: float = DEFAULT_TOLERANCE_PX
    bias: Any = None  # (2, 3) image-space affinity applied to the RPCs' pixels (refine_bias)

    @property
    def image_size(self) -> tuple[int, int]:
        return tuple(self.image_size_px)

    @property
    def centre(self) -> np.ndarray:
        return np.full(3, np.nan)

    def _transformer(self, inverse: bool = False):
        if self.crs is None:
            return None
        from toolbox.io.crs import parse_crs

        return _lonlat_transformer(parse_crs(self.crs).to_wkt(), inverse)

    def lonlat_to_pixel(self, lon: np.ndarray, lat: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Longitude, latitude (degrees), height -> pixels (N, 2)."""
        v, t = self.rpc.values, self.rpc.terms
        m = _monomials((np.asarray(lat, dtype="float64") - v["lat_off"]) / v["lat_scale"],
                       (np.asarray(lon, dtype="float64") - v["long_off"]) / v["long_scale"],
                       (np.asarray(h, dtype="float64") - v["height_off"]) / v["height_scale"])
        with np.errstate(invalid="ignore", divide="ignore"):
            line = t["line_num_coeff"] @ m / (t["line_den_coeff"] @ m)
            samp = t["samp_num_coeff"] @ m / (t["samp_den_coeff"] @ m)
        col = samp * v["samp_scale"] + v["samp_off"] + 0.5
        row = line * v["line_scale"] + v["line_off"] + 0.5
        if self.bias is not None:
            a = self.bias
            col, row = (a[0, 0] * col + a[0, 1] * row + a[0, 2],
                        a[1, 0] * col + a[1, 1] * row + a[1, 2])
        return np.column_stack([col, row])

    def project(self, xyz: Any) -> np.ndarray:
        from toolbox.cameras.frame import ground_points

        pts = ground_points(xyz)
        x, y = pts[:, 0], pts[:, 1]
        transformer = self._transformer()
        if transformer is not None:
            x, y = transformer.transform(x, y)
        return self.lonlat_to_pixel(x, y, pts[:, 2])

    def pixel_to_lonlat(self, pixels: np.ndarray, h: Any) -> tuple[np.ndarray, np.ndarray, int]:
        """Pixels (N, 2) at heights ``h`` -> longitude, latitude (degrees; NaN where Newton's
        method did not reach ``tolerance_px``) and the number of such pixels."""
        px = np.asarray(pixels, dtype="float64").reshape(-1, 2)
        h = np.broadcast_to(np.asarray(h, dtype="float64"), (len(px),))
        v = self.rpc.values
        lon = np.full(len(px), v["long_off"])
        lat = np.full(len(px), v["lat_off"])
        dlon, dlat = 1e-6 * abs(v["long_scale"]), 1e-6 * abs(v["lat_scale"])
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            for _ in range(20):
                f = self.lonlat_to_pixel(lon, lat, h) - px
                if not np.nanmax(np.abs(f), initial=0.0) > 1e-4 * self.tolerance_px:
                    break
                ja = (self.lonlat_to_pixel(lon + dlon, lat, h) - f - px) / dlon
                jb = (self.lonlat_to_pixel(lon, lat + dlat, h) - f - px) / dlat
                det = ja[:, 0] * jb[:, 1] - jb[:, 0] * ja[:, 1]
                lon = lon - (jb[:, 1] * f[:, 0] - jb[:, 0] * f[:, 1]) / det
                lat = lat - (ja[:, 0] * f[:, 1] - ja[:, 1] * f[:, 0]) / det
            error = np.hypot(*(self.lonlat_to_pixel(lon, lat, h) - px).T)
        bad = ~(error <= self.tolerance_px)
        given = np.isfinite(px).all(axis=1) & np.isfinite(h)
        lon[bad], lat[bad] = np.nan, np.nan
        return lon, lat, int(np.count_nonzero(bad & given))

    def pixel_to_ground(self, pixels: np.ndarray, z: Any) -> np.ndarray:
        px = np.asarray(pixels, dtype="float64").reshape(-1, 2)
        z = np.broadcast_to(np.asarray(z, dtype="float64"), (len(px),))
        lon, lat, _ = self.pixel_to_lonlat(px, z)
        transformer = self._transformer(inverse=True)
        if transformer is not None:
            lon, lat = transformer.transform(lon, lat)
        return np.column_stack([lon, lat, z])

    def unproject(self, pixels: np.ndarray) -> np.ndarray:
        """Directions (ground axes, downwards) of the lines of sight: from the point at the top
        of the RPCs' height range to the one at its bottom (the line of sight of an RPC camera
        is nearly straight over its height range)."""
        v = self.rpc.values
        top = self.pixel_to_ground(pixels, v["height_off"] + v["height_scale"])
        bottom = self.pixel_to_ground(pixels, v["height_off"] - v["height_scale"])
        d = bottom - top
        return d / np.linalg.norm(d, axis=1)[:, None]


@functools.lru_cache(maxsize=8)
def _lonlat_transformer(wkt: str, inverse: bool) -> Any:
    """pyproj Transformer ``wkt`` -> WGS84 lon/lat (``inverse``: back), always_xy; cached
    (an ortho asks once per window)."""
    from pyproj import CRS, Transformer

    geo, crs = CRS.from_epsg(4326), CRS.from_wkt(wkt)
    return Transformer.from_crs(geo, crs, always_xy=True) if inverse else \
        Transformer.from_crs(crs, geo, always_xy=True)


def refine_bias(camera: RpcCamera, ground: np.ndarray, pixels: np.ndarray,
                model: str = "auto") -> tuple[RpcCamera, dict[str, Any]]:
    """The camera with its image-space bias fitted to GCPs (module docstring): ``ground``
    (n, 3) in the camera's CRS and heights, ``pixels`` (n, 2) measured (product pixels).
    ``model``: ``shift`` (n >= 1), ``affine`` (n >= 3; better conditioned with more), or
    ``auto`` (affine from 4 GCPs, else shift). Returns the camera and a report (model, the
    residuals' RMS before and after, pixels, per GCP after)."""
    ground = np.asarray(ground, dtype="float64").reshape(-1, 3)
    pixels = np.asarray(pixels, dtype="float64").reshape(-1, 2)
    plain = replace(camera, bias=None)
    predicted = plain.project(ground)
    ok = np.isfinite(predicted).all(axis=1) & np.isfinite(pixels).all(axis=1)
    n = int(ok.sum())
    if model == "auto":
        model = "affine" if n >= 4 else "shift"
    need = {"shift": 1, "affine": 3}.get(model)
    if need is None:
        raise InputDataError(f"RPC bias model must be shift, affine or auto, got {model!r}")
    if n < need:
        raise InputDataError(f"an RPC {model} bias needs at least {need} GCP(s) on the image; "
                             f"{n} of {len(ground)} project into it")
    p, m = predicted[ok], pixels[ok]
    if model == "shift":
        a = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        a[:, 2] = (m - p).mean(axis=0)
    else:
        design = np.column_stack([p, np.ones(n)])
        solution, *_ = np.linalg.lstsq(design, m, rcond=None)
        a = solution.T
    fitted = replace(camera, bias=a)
    after = fitted.project(ground[ok]) - m
    report = {"model": model, "gcps": n, "bias": a.tolist(),
              "rms_before_px": float(np.sqrt(np.mean(np.sum((p - m) ** 2, axis=1)))),
              "rms_after_px": float(np.sqrt(np.mean(np.sum(after ** 2, axis=1)))),
              "residuals_px": after.tolist()}
    return fitted, report


def read_rpc(path: Any, crs: Any = None) -> RpcCamera:
    """The RPC camera of an image file through GDAL (GeoTIFF tags, ``.RPB``, ``_RPC.TXT``)."""
    import rasterio

    try:
        with rasterio.open(path) as src:
            rpcs, size = src.rpcs, (src.width, src.height)
    except rasterio.errors.RasterioIOError as exc:
        raise InputDataError(f"cannot read '{path}': {exc}") from None
    if rpcs is None:
        raise InputDataError(f"'{path}' has no RPCs (no RPC tags, .RPB or _RPC.TXT file)")
    return RpcCamera(RpcCoefficients.from_mapping(rpcs, str(path)), size, crs)
