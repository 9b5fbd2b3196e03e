"""LAS/LAZ/COPC point clouds: a validated reference, a chunked reader with class and return
filters, and a chunked writer (laspy; LAZ through the lazrs backend).

Reading never holds the whole file's records: chunks of :data:`CHUNK_POINTS` points are
decoded, filtered and copied into one preallocated ``(N, 3)`` float64 array (N = the header's
point count), so the peak is that array plus one chunk. COPC files (``.copc.laz``, told by
their ``copc`` info VLR: ``info["copc"]``) are LAZ 1.4 files and are read the same way, all
their points in file order (no spatial query of the octree).

Return filter (``RETURNS``): ``all``; ``first`` = return number <= 1; ``last`` = return number
>= number of returns. Points with return number 0 (photogrammetric clouds often leave 0/0)
count as both first and last. Points flagged *withheld* (the LAS specification: "should not
be included in processing", synonymous with deleted) are never read. Class filter
(``CLASSES``): ASPRS classification codes, e.g.
``2`` ground, ``9`` water; a requested class absent from the file is an error.

CRS: from the file's OGC WKT VLR, else its GeoTIFF keys read by GDAL (:func:`geotiff_keys_crs`:
user-defined projections, their units and a vertical CRS included).
"""

from __future__ import annotations

import logging
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError, ParameterError

SUFFIXES = (".las", ".laz")  # COPC is ".copc.laz"
CHUNK_POINTS = 1_000_000
RETURN_RULES = ("all", "first", "last")


def is_point_cloud_path(value: Any) -> bool:
    """True for a path (str or Path) ending in .las or .laz (any case)."""
    return isinstance(value, (str, Path)) and "|" not in str(value) \
        and Path(str(value)).suffix.lower() in SUFFIXES


@dataclass
class PointCloudRef:
    """A validated LAS/LAZ file: its header facts, read once (not the points)."""

    path: Path
    point_count: int
    compressed: bool
    version: str
    point_format: int
    dimensions: list[str]
    bounds: tuple[float, float, float, float]  # xmin, ymin, xmax, ymax
    z_range: tuple[float, float]
    crs_wkt: str | None
    info: dict[str, Any] = field(default_factory=dict)

    def __str__(self) -> str:
        return f"'{self.path}'"

    @property
    def crs(self):
        from pyproj import CRS

        return None if self.crs_wkt is None else CRS.from_wkt(self.crs_wkt)

    # the Field parameter's interface: the point dimensions are the "fields"
    @property
    def fields(self) -> list[str]:
        return list(self.dimensions)

    @property
    def field_types(self) -> dict[str, str]:
        return {name: "number" for name in self.dimensions}

    def is_numeric(self, name: str) -> bool:
        return name in self.dimensions


def lazrs_available() -> bool:
    """True when laspy has a LAZ backend (lazrs or laszip)."""
    import laspy

    return bool(laspy.LazBackend.detect_available())


def _open_reader(path: Path):
    """``laspy.open`` for reading, with the point count a LAS 1.4 file states only in the legacy
    field (the 64-bit count left 0 by some writers) taken from there, as LASlib does; laspy read
    such a file as empty."""
    import laspy

    reader = laspy.open(path)
    header = reader.header
    if header.version.minor >= 4 and header.point_count == 0:
        with open(path, "rb") as stream:
            stream.seek(107)
            legacy = int.from_bytes(stream.read(4), "little")
        if legacy:
            header.point_count = legacy
    return reader


def open_point_cloud(value: Any, name: str = "INPUT") -> PointCloudRef:
    """Read the header of a LAS/LAZ file; :class:`ParameterError` naming ``name`` if unreadable."""
    if isinstance(value, PointCloudRef):
        return value

    path = Path(str(value)).expanduser()
    if not path.exists():
        raise ParameterError(name, f"file '{value}' does not exist")
    try:
        with _open_reader(path) as reader:
            header = reader.header
            compressed = bool(header.are_points_compressed)
            try:
                crs = header.parse_crs() if _has_wkt(header) else geotiff_keys_crs(header)
            except Exception as exc:  # a malformed VLR: say so, do not guess
                raise ParameterError(name, f"'{value}': its CRS VLR cannot be parsed: "
                                     f"{str(exc).splitlines()[0]}") from None
            mins, maxs = header.mins, header.maxs
            ref = PointCloudRef(
                path=path, point_count=int(header.point_count), compressed=compressed,
                version=str(header.version), point_format=int(header.point_format.id),
                dimensions=list(header.point_format.dimension_names),
                bounds=(float(mins[0]), float(mins[1]), float(maxs[0]), float(maxs[1])),
                z_range=(float(mins[2]), float(maxs[2])),
                crs_wkt=None if crs is None else crs.to_wkt())
            copc = any(getattr(v, "user_id", "") == "copc" for v in header.vlrs)
    except ParameterError:
        raise
    except Exception as exc:
        raise ParameterError(name, f"cannot read '{value}' as a LAS/LAZ point cloud: "
                             f"{str(exc).splitlines()[0]}") from None
    if ref.point_count == 0:
        raise ParameterError(name, f"point cloud '{value}' has no points")
    ref.info = {"total_bounds": ref.bounds, "point_count": ref.point_count,
                "compressed": compressed, "version": ref.version,
                "point_format": ref.point_format, "copc": copc}
    return ref


def _has_wkt(header) -> bool:
    """True when the header carries a non-empty OGC WKT CRS VLR (or EVLR)."""
    from laspy.vlrs.known import WktCoordinateSystemVlr

    records = list(header.vlrs) + list(header.evlrs or [])
    return any(isinstance(v, WktCoordinateSystemVlr) and (v.string or "").strip("\0 ")
               for v in records)


def geotiff_keys_crs(header):
    """The pyproj CRS of a LAS header's GeoTIFF keys as GDAL (libgeotiff) reads them, or None.

    laspy reads only an EPSG ProjectedCSTypeGeoKey / GeographicTypeGeoKey: a user-defined
    projection (ProjectedCSTypeGeoKey 32767, its parameters in the keys, common in LAS 1.0-1.3
    files) came back as its geographic base CRS (or none), the vertical CRS was dropped. The keys
    are put in a 1x1 GeoTIFF in memory and GDAL reads its CRS, as it would for a raster.
    """
    from pyproj import CRS

    directories = header.vlrs.get("GeoKeyDirectoryVlr")
    if not directories:
        return None
    keys = [k for k in directories[0].geo_keys if k.id != 0]  # writers pad with a zero key
    directory = struct.pack("<4H", 1, 1, 0, len(keys)) + b"".join(
        struct.pack("<4H", k.id, k.tiff_tag_location, k.count, k.value_offset) for k in keys)

    def record(name: str) -> bytes:
        found = header.vlrs.get(name)
        return found[0].record_data_bytes() if found else b""

    tiff = _geokeys_tiff(directory, record("GeoDoubleParamsVlr"), record("GeoAsciiParamsVlr"))
    import rasterio
    from rasterio.io import MemoryFile

    with rasterio.Env(GTIFF_REPORT_COMPD_CS=True, CPL_LOG="/dev/null"), \
            MemoryFile(tiff) as memory, memory.open() as dataset:
        crs = None if dataset.crs is None else CRS.from_wkt(dataset.crs.to_wkt())
    # keys naming no projection or datum (a unit alone, an incomplete user-defined projection)
    # come back as GDAL's LOCAL_CS "unnamed": no CRS, as laspy said (the CRS parameter gives it)
    return None if crs is None or crs.type_name.startswith("Engineering") else crs


def _geokeys_tiff(directory: bytes, doubles: bytes, ascii_: bytes) -> bytes:
    """A 1x1 uint8 little-endian GeoTIFF whose GeoKeyDirectory, GeoDoubleParams and
    GeoAsciiParams tags are the given LAS GeoTIFF VLR records."""
    short, long_, double, ascii_type = 3, 4, 12, 2
    plain = [(256, short, 1), (257, short, 1), (258, short, 8), (259, short, 1),
             (262, short, 1), (273, long_, None), (277, short, 1), (278, short, 1),
             (279, long_, 1)]
    blobs = [(33550, double, struct.pack("<3d", 1.0, 1.0, 0.0)),
             (33922, double, bytes(48)), (34735, short, directory)]
    if len(doubles) >= 8:
        blobs.append((34736, double, doubles[:len(doubles) // 8 * 8]))
    if ascii_.strip(b"\0"):
        blobs.append((34737, ascii_type, ascii_.rstrip(b"\0") + b"\0"))
    width = {short: 2, long_: 4, double: 8, ascii_type: 1}
    count = len(plain) + len(blobs)
    data_at = 8 + 2 + 12 * count + 4
    entries, data = [], b""
    for tag, kind, blob in blobs:
        entries.append(struct.pack("<HHII", tag, kind, len(blob) // width[kind],
                                   data_at + len(data)))
        data += blob + b"\0" * (len(blob) % 2)
    pixel_at = data_at + len(data)
    head = [struct.pack("<HHIHH", tag, kind, 1, value, 0) if kind == short
            else struct.pack("<HHII", tag, kind, 1, pixel_at if value is None else value)
            for tag, kind, value in plain]
    return (b"II*\0" + struct.pack("<IH", 8, count) + b"".join(head + entries)
            + struct.pack("<I", 0) + data + b"\0")


@dataclass(frozen=True)
class PointFilter:
    """Which points of a cloud are read: ASPRS classes (None = all) and returns."""

    classes: tuple[int, ...] | None = None
    returns: str = "all"

    def describe(self) -> str:
        classes = "all" if self.classes is None else ",".join(map(str, self.classes))
        return f"classes {classes}, returns {self.returns}"


def parse_classes(text: Any, name: str = "CLASSES") -> tuple[int, ...] | None:
    """``"2,9"`` -> ``(2, 9)``; None or "" -> None. Codes 0..255, else :class:`ParameterError`."""
    if text is None or str(text).strip() == "":
        return None
    items = text if isinstance(text, (list, tuple)) else str(text).replace(";", ",").split(",")
    codes = []
    for item in items:
        item = str(item).strip()
        if not item:
            continue
        try:
            code = int(item)
        except ValueError:
            raise ParameterError(name, f"must be ASPRS class codes separated by commas (e.g. "
                                 f"'2,9'), got {text!r}") from None
        if not 0 <= code <= 255:
            raise ParameterError(name, f"class codes are 0..255, got {code}")
        codes.append(code)
    return tuple(sorted(set(codes))) or None


@dataclass
class ReadReport:
    """What :func:`read_xyz` read: totals and the class histogram of the whole file."""

    read: int
    kept: int
    classes: dict[int, int]
    filter: str
    withheld: int = 0  # points flagged withheld (deleted), never kept

    def as_dict(self) -> dict:
        return {"points_in_file": self.read, "points_kept": self.kept,
                "points_withheld": self.withheld,
                "classes_in_file": {str(k): v for k, v in self.classes.items()},
                "filter": self.filter}


def _require_backend(ref: PointCloudRef, name: str) -> None:
    if ref.compressed and not lazrs_available():
        raise InputDataError(f"{name} {ref} is compressed (LAZ) but no LAZ backend is "
                             "installed: pip install lazrs")


def _keep(points, flt: PointFilter) -> np.ndarray | None:
    """Boolean mask of the chunk's points that pass ``flt`` and are not withheld (None = all)."""
    withheld = np.asarray(points.withheld).astype(bool)
    keep = ~withheld if withheld.any() else None
    if flt.classes is not None:
        cls = np.isin(np.asarray(points.classification), flt.classes)
        keep = cls if keep is None else keep & cls
    if flt.returns != "all":
        rn = np.asarray(points.return_number).astype(np.int16)
        if flt.returns == "first":
            ret = rn <= 1
        else:
            ret = rn >= np.asarray(points.number_of_returns).astype(np.int16)
        keep = ret if keep is None else keep & ret
    return keep


def iter_xyz(ref: PointCloudRef, flt: PointFilter = PointFilter(), z_field: str | None = None,
             name: str = "INPUT", chunk_points: int = CHUNK_POINTS,
             report: ReadReport | None = None) -> Iterator[np.ndarray]:
    """The (k, 3) float64 X, Y, Z of the points passing ``flt``, chunk by chunk (file order).

    Never holds more than one chunk of ``chunk_points`` records. ``report`` (optional) is
    filled as the chunks go (points read and kept, the class histogram of the whole file).
    After the last chunk it raises :class:`InputDataError` naming ``name`` when a requested
    class is not in the file or no point passed the filter; a NaN or infinite height is
    refused at its chunk; LAZ without a backend is refused before the first.
    """

    _require_backend(ref, name)
    report = report if report is not None else ReadReport(0, 0, {}, flt.describe())
    report.filter = flt.describe()
    hist = np.zeros(256, dtype=np.int64)
    try:
        with _open_reader(ref.path) as reader:
            for points in reader.chunk_iterator(chunk_points):
                n = len(points)
                if n == 0:
                    continue
                hist += np.bincount(np.asarray(points.classification, dtype=np.int64),
                                    minlength=256)[:256]
                keep = _keep(points, flt)
                report.withheld += int(np.count_nonzero(np.asarray(points.withheld)))
                z = points.z if z_field in (None, "z", "Z") else points[z_field]
                cols = [np.asarray(col, dtype=np.float64) for col in (points.x, points.y, z)]
                xyz = np.column_stack(cols if keep is None else [c[keep] for c in cols])
                del cols, points
                report.read += n
                report.kept += len(xyz)
                report.classes = {int(c): int(hist[c]) for c in np.flatnonzero(hist)}
                if not np.isfinite(xyz[:, 2]).all():
                    raise InputDataError(f"{name} {ref}: the height {z_field or 'z'} is NaN or "
                                         "infinite for some points")
                yield xyz
    except InputDataError:
        raise
    except Exception as exc:
        raise InputDataError(f"{name} {ref}: cannot read the points: "
                             f"{str(exc).splitlines()[0]}") from None
    classes = report.classes
    if flt.classes is not None:
        missing = [c for c in flt.classes if c not in classes]
        if missing:
            present = ", ".join(f"{c} ({n} points)" for c, n in classes.items())
            raise InputDataError(f"CLASSES {','.join(map(str, missing))} not in {name} {ref}; "
                                 f"the classes present are: {present}")
    if report.kept == 0:
        withheld = f" ({report.withheld} flagged withheld, never read)" if report.withheld \
            else ""
        raise InputDataError(f"no point of {name} {ref} passes the filter ({flt.describe()}) "
                             f"of its {report.read} points{withheld}")


def read_xyz(ref: PointCloudRef, flt: PointFilter = PointFilter(), z_field: str | None = None,
             name: str = "INPUT", chunk_points: int = CHUNK_POINTS
             ) -> tuple[np.ndarray, ReadReport]:
    """(K, 3) float64 X, Y, Z (map units) of the points passing ``flt``, read by chunks
    (:func:`iter_xyz`) into one array allocated for the header's count (pages past the kept
    points are never touched): 24 bytes a kept point plus one chunk.

    Z is the point's z, or the dimension ``z_field`` (e.g. a height above ground). Raises
    :class:`InputDataError` naming ``name`` when LAZ cannot be decoded, a requested class is
    not in the file, or no point passes the filter.
    """
    report = ReadReport(0, 0, {}, flt.describe())
    out = np.empty((ref.point_count, 3), dtype=np.float64)
    n_kept = 0
    for xyz in iter_xyz(ref, flt, z_field, name, chunk_points, report):
        end = n_kept + len(xyz)
        if end > len(out):  # the header under-counted: grow (rare, broken files)
            out = np.resize(out, (end + chunk_points, 3))
        out[n_kept:end] = xyz
        n_kept = end
    warn_noise_classes(report, flt, ref, name)
    return out[:n_kept], report


NOISE_CLASSES = {7: "low noise", 18: "high noise"}  # ASPRS LAS 1.4, table 17


def warn_noise_classes(report: ReadReport, flt: PointFilter, ref: Any, name: str) -> None:
    """Log a warning when points of the noise classes (7, 18) were kept because no class
    filter was given: a noise point in a surface is a spike or a pit (PDAL and LAStools keep
    them too unless told; the user may not know the file has them)."""
    if flt.classes is not None:
        return
    kept = [f"{report.classes[c]} of class {c} ({label})" for c, label in NOISE_CLASSES.items()
            if report.classes.get(c)]
    if kept:
        logging.getLogger("toolbox").warning(
            f"{name} {ref}: {' and '.join(kept)} points are used, CLASSES not being given; "
            "give CLASSES to leave them out (e.g. 2 for the ground)")


def check_cloud_crs(ref: Any, crs: Any, name: str = "INPUT") -> None:
    """:class:`ParameterError` when a point cloud has no CRS and the CRS parameter is not given."""
    if isinstance(ref, PointCloudRef) and ref.crs_wkt is None and crs is None:
        raise ParameterError(name, f"point cloud {ref} has no CRS (no WKT VLR, no GeoTIFF "
                             "keys GDAL can read): give its CRS in the CRS parameter (e.g. --CRS EPSG:3003)")


# -- writing -----------------------------------------------------------------------------------
def add_crs_vlr(header, crs: Any) -> None:
    """Put ``crs`` in the LAS ``header`` as the LAS 1.4 specification wants it: an OGC WKT VLR
    in the WKT of OGC 01-009 (WKT1, not ESRI's) with the WKT global-encoding bit, for point
    formats 6-10 (and what laspy chooses for the others: GeoTIFF keys for formats 0-5).

    laspy's ``add_crs`` writes pyproj's default WKT2 (``PROJCRS[...``), another language than
    the one the specification names, which readers that parse the WKT of LAS files as WKT1 do
    not read. A CRS whose WKT1 reads back as another CRS (WKT1 drops the north-first axes of
    EPSG:6707) keeps its WKT2."""
    from laspy.vlrs.known import WktCoordinateSystemVlr
    from pyproj import CRS

    crs = CRS.from_user_input(crs)
    header.add_crs(crs)
    if header.global_encoding.wkt:
        wkt1 = crs.to_wkt("WKT1_GDAL")
        if wkt1 and CRS.from_wkt(wkt1) == crs:
            header.vlrs.extract("WktCoordinateSystemVlr")
            header.vlrs.append(WktCoordinateSystemVlr(wkt1))


class PointCloudWriter:
    """Write points to LAS 1.4 (``.las``) or LAZ (``.laz``, needs lazrs) in appended chunks.

    ``origin`` (3,) is the coordinate offset (a point near the data; rounded to 1 km), ``scale``
    the coordinate resolution (CRS units, default 1 mm), ``rgb`` whether colour is written
    (point format 7, else 6). The CRS goes in an OGC WKT VLR. Use as a context manager;
    :meth:`write` takes ``xyz`` (N, 3), optional ``classification`` (N,) ASPRS codes and ``rgb``
    (N, 3) colour (uint8 values are scaled by 257 to 16 bits).
    """

    def __init__(self, path: str | Path, origin: np.ndarray, crs: Any = None,
                 rgb: bool = False, scale: float = 0.001):
        import laspy

        self.path = Path(path)
        self.compress = self.path.suffix.lower() == ".laz"
        if self.compress and not lazrs_available():
            raise InputDataError(f"cannot write '{self.path}' as LAZ: no LAZ backend is "
                                 "installed (pip install lazrs), or write .las")
        header = laspy.LasHeader(point_format=7 if rgb else 6, version="1.4")
        header.offsets = np.floor(np.asarray(origin, dtype=np.float64) / 1000.0) * 1000.0
        header.scales = np.array([scale, scale, scale])
        if crs is not None:
            add_crs_vlr(header, crs)
        self.header, self.rgb, self.count = header, rgb, 0
        self._writer = None

    def __enter__(self) -> PointCloudWriter:
        import laspy

        self._writer = laspy.open(self.path, mode="w", header=self.header,
                                  do_compress=self.compress)
        return self

    def write(self, xyz: np.ndarray, classification: np.ndarray | None = None,
              rgb: np.ndarray | None = None) -> None:
        import laspy

        xyz = np.asarray(xyz, dtype=np.float64)
        if len(xyz) == 0:
            return
        record = laspy.ScaleAwarePointRecord.zeros(len(xyz), header=self.header)
        record.x, record.y, record.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        if classification is not None:
            record.classification = np.asarray(classification, dtype=np.uint8)
        if self.rgb and rgb is not None:
            rgb = np.asarray(rgb)
            if rgb.dtype == np.uint8:
                rgb = rgb.astype(np.uint16) * 257
            record.red, record.green, record.blue = rgb[:, 0], rgb[:, 1], rgb[:, 2]
        record.return_number[:] = 1
        record.number_of_returns[:] = 1
        self._writer.write_points(record)
        self.count += len(xyz)

    def __exit__(self, *exc) -> None:
        self._writer.close()


def write_point_cloud(path: str | Path, xyz: np.ndarray, crs: Any = None,
                      classification: np.ndarray | None = None, rgb: np.ndarray | None = None,
                      scale: float = 0.001, chunk_points: int = CHUNK_POINTS) -> int:
    """Write points to LAS 1.4 / LAZ in chunks (see :class:`PointCloudWriter`); returns the
    points written."""
    xyz = np.asarray(xyz, dtype=np.float64)
    origin = xyz.min(axis=0) if len(xyz) else np.zeros(3)
    with PointCloudWriter(path, origin, crs, rgb is not None, scale) as writer:
        for start in range(0, len(xyz), chunk_points):
            part = slice(start, start + chunk_points)
            writer.write(xyz[part], None if classification is None else classification[part],
                         None if rgb is None else rgb[part])
    return len(xyz)


def write_classified_copy(ref: PointCloudRef, flt: PointFilter, path: str | Path,
                          classification: np.ndarray, crs: Any = None,
                          chunk_points: int = CHUNK_POINTS) -> int:
    """Write the points of ``ref`` that pass ``flt`` (the order :func:`iter_xyz` reads them),
    every dimension as read (X, Y, Z, intensity, returns, GPS time, colour, extra bytes), with
    ``classification`` (one code per kept point) set. Point format, version, scales, offsets
    and the CRS VLRs are the input's (the CRS ``crs`` is added when the input has none); the
    COPC VLRs are dropped (the copy is not ordered as an octree). Returns the points written.
    """
    import copy

    import laspy

    _require_backend(ref, "INPUT")
    path = Path(path)
    compress = path.suffix.lower() == ".laz"
    if compress and not lazrs_available():
        raise InputDataError(f"cannot write '{path}' as LAZ: no LAZ backend is installed "
                             "(pip install lazrs), or write .las")
    classification = np.asarray(classification)
    written = 0
    with _open_reader(ref.path) as reader:
        header = copy.deepcopy(reader.header)
        header.vlrs = type(header.vlrs)([v for v in header.vlrs
                                         if getattr(v, "user_id", "") != "copc"])
        if header.evlrs is not None:
            header.evlrs = [v for v in header.evlrs if getattr(v, "user_id", "") != "copc"]
        if ref.crs_wkt is None and crs is not None:
            add_crs_vlr(header, crs)
        with laspy.open(path, mode="w", header=header, do_compress=compress) as writer:
            for points in reader.chunk_iterator(chunk_points):
                if len(points) == 0:
                    continue
                keep = _keep(points, flt)
                if keep is not None:
                    points = points[keep]
                n = len(points)
                if n == 0:
                    continue
                if written + n > len(classification):
                    raise InputDataError(f"INPUT {ref} changed while it was read")
                points.classification = classification[written:written + n].astype(np.uint8)
                writer.write_points(points)
                written += n
    if header.version.minor >= 4 and header.point_format.id <= 5 and written < 2 ** 32:
        _write_legacy_counts(path)
    return written


def _write_legacy_counts(path: Path) -> None:
    """Fill the legacy point counts of a LAS 1.4 file of point format 0-5 (the specification:
    they 'must' hold the count when it fits 32 bits, for readers of LAS 1.0-1.3); laspy writes
    0 there."""
    with open(path, "r+b") as stream:
        stream.seek(247)
        total = int.from_bytes(stream.read(8), "little")
        by_return = [int.from_bytes(stream.read(8), "little") for _ in range(15)]
        stream.seek(107)
        stream.write(struct.pack("<6I", total, *(min(c, 2 ** 32 - 1) for c in by_return[:5])))


def cloud_filter(source: Any, classes: Any = None, returns: str | None = "all",
                 crs: Any = None, name: str = "INPUT") -> PointFilter | None:
    """The :class:`PointFilter` of a point-layer parameter, checked before any work.

    Returns None for a vector ``source``; raises :class:`ParameterError` when CLASSES or
    RETURNS are given for a vector layer, CLASSES is malformed, or the cloud has no CRS and
    ``crs`` is None.
    """
    returns = returns or "all"
    if not isinstance(source, PointCloudRef):
        if classes not in (None, "") or returns != "all":
            which = "CLASSES" if classes not in (None, "") else "RETURNS"
            raise ParameterError(which, f"applies only to a LAS/LAZ point cloud {name}, but "
                                 f"{name} {source} is a vector layer")
        return None
    if returns not in RETURN_RULES:
        raise ParameterError("RETURNS", f"must be one of {', '.join(RETURN_RULES)}, "
                             f"got {returns!r}")
    check_cloud_crs(source, crs, name)
    return PointFilter(parse_classes(classes), returns)
