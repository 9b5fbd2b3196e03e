"""Finding fiducial marks on a scanned frame: coarse positions from the camera certificate and
the scan size, normalised cross-correlation (coarse on a decimated window, then full
resolution, quadratic sub-pixel peak), the pixel -> fiducial transform with residuals.

Scan orientation: the certificate's marks ``(x, y)`` mm (fiducial system, y up) fall near
``(W/2, H/2) + G·(x/s, -y/s)`` pixels, ``s`` the scan pixel size and ``G`` one of the eight
rotations by 0/90/180/270 degrees, mirrored or not (a film scanned emulsion up or down). Every
``G`` is tried (the template turned with it) and the one whose marks correlate best is kept; a
tie between different mark assignments (a symmetric layout and a symmetric mark) keeps the scan
as it is and says so.

A mark is reported missing, never placed wrongly, when its peak is below ``min_score``
(covered, damaged), when a second peak farther than the mark's size scores within ``margin``
of it (ambiguous), when its window or its peak leaves the scan (cropped, outside), or when the
transform fitted on the other marks leaves it a residual above ``max_residual_mm``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from toolbox.errors import InputDataError
from toolbox.matching.ncc import peak, scores
from toolbox.matching.refine import sample
from toolbox.raster.photo_grid import open_photo_grid, warn_orientation_tag

#: the eight scan orientations: name -> G (2 x 2, pixel frame: col right, row down)
ORIENTATIONS: dict[str, np.ndarray] = {}
for _k in range(4):
    _c, _s = round(math.cos(_k * math.pi / 2)), round(math.sin(_k * math.pi / 2))
    _r = np.array([[_c, -_s], [_s, _c]], dtype=float)
    ORIENTATIONS[f"{_k * 90}"] = _r
    ORIENTATIONS[f"{_k * 90}m"] = np.array([[-1.0, 0.0], [0.0, 1.0]]) @ _r


@dataclass
class MarkSearch:
    """Settings (pixels of the scan unless said)."""

    pixel_mm: float  # scan pixel size
    search_mm: float = 8.0  # half size of the search window around the predicted position
    min_score: float = 0.6
    margin: float = 0.1  # runner-up within this of the peak: ambiguous
    polarity: str = "auto"  # bright, dark, auto
    coarse_size: int = 400  # longer side of the decimated search window
    max_residual_mm: float = 0.05  # marks farther from the fitted affine: inconsistent


@dataclass
class MarkResult:
    mark: str
    status: str  # ok, covered, ambiguous, cropped, outside, inconsistent
    col_px: float | None
    row_px: float | None
    score: float | None
    runner_up: float | None
    predicted: tuple[float, float] = (0.0, 0.0)

    @property
    def ok(self) -> bool:
        return self.status == "ok"


@dataclass
class PhotoMarks:
    photo: str
    orientation: str
    marks: list[MarkResult]
    notes: list[str] = field(default_factory=list)


def predicted_positions(marks_mm: dict[str, tuple[float, float]], width: int, height: int,
                        pixel_mm: float, g: np.ndarray) -> dict[str, np.ndarray]:
    """Coarse pixel position of every mark under scan orientation ``g``."""
    centre = np.array([width / 2.0, height / 2.0])
    return {m: centre + g @ np.array([x / pixel_mm, -y / pixel_mm])
            for m, (x, y) in marks_mm.items()}


def turned(template: np.ndarray, g: np.ndarray) -> np.ndarray:
    """The template as a scan of orientation ``g`` shows it (exact: integer matrices about
    the central pixel; the template is cropped to an odd size first)."""
    h, w = template.shape
    t = template[:h - (1 - h % 2), :w - (1 - w % 2)]
    half_r, half_c = t.shape[0] // 2, t.shape[1] // 2
    if half_r != half_c:  # pad to a square so that 90-degree turns keep the size
        size = max(half_r, half_c)
        t = np.pad(t, ((size - half_r,) * 2, (size - half_c,) * 2), mode="edge")
    half = t.shape[0] // 2
    return sample(t, (0, 0), np.array([half + 0.5, half + 0.5]), np.linalg.inv(g), half)


def _score_map(window: np.ndarray, template: np.ndarray, polarity: str) -> np.ndarray:
    s = scores(window, template)
    if polarity == "dark":
        return -s
    if polarity == "auto":
        return np.maximum(s, -s)
    return s


def locate(window: np.ndarray, origin: tuple[int, int], template: np.ndarray,
           opts: MarkSearch, scan_size: tuple[int, int], mark: str,
           predicted: np.ndarray) -> MarkResult:
    """Find one mark in ``window`` (float grey, full resolution, top-left pixel = ``origin``,
    already clipped to the scan)."""
    import cv2

    th, tw = template.shape
    if window.shape[0] < th or window.shape[1] < tw:
        return MarkResult(mark, "cropped", None, None, None, None, tuple(predicted))
    f = max(1, int(math.ceil(max(window.shape) / opts.coarse_size)))
    f = min(f, max(1, min(th, tw) // 7))  # keep the decimated template >= 7 px
    if f > 1:
        small = cv2.resize(window, (window.shape[1] // f, window.shape[0] // f),
                           interpolation=cv2.INTER_AREA)
        small_t = cv2.resize(template, (max(3, tw // f), max(3, th // f)),
                             interpolation=cv2.INTER_AREA)
    else:
        small, small_t = window, template
    coarse = _score_map(small, small_t, opts.polarity)
    cp = peak(coarse, exclusion=0.6 * max(small_t.shape))
    # full resolution around the coarse peak
    c0 = int(round(cp.x * f)) - 2 * f - 2
    r0 = int(round(cp.y * f)) - 2 * f - 2
    c0, r0 = max(0, c0), max(0, r0)
    c1 = min(window.shape[1], c0 + tw + 4 * f + 4)
    r1 = min(window.shape[0], r0 + th + 4 * f + 4)
    fine = _score_map(window[r0:r1, c0:c1], template, opts.polarity)
    fp = peak(fine)
    score = fp.score
    runner = cp.runner_up
    col = origin[0] + c0 + fp.x + (tw - 1) / 2.0 + 0.5
    row = origin[1] + r0 + fp.y + (th - 1) / 2.0 + 0.5
    touches = (cp.on_border or fp.on_border)
    at_edge = (origin[0] + c0 + fp.x <= 0.5 or origin[1] + r0 + fp.y <= 0.5
               or origin[0] + c0 + fp.x + tw >= scan_size[0] - 0.5
               or origin[1] + r0 + fp.y + th >= scan_size[1] - 0.5)
    if score < opts.min_score:
        status = "covered"
    elif touches or at_edge:
        status = "cropped"
    elif np.isfinite(runner) and runner >= score - opts.margin:
        status = "ambiguous"
    else:
        status = "ok"
    if status != "ok":
        return MarkResult(mark, status, None, None, float(score), _finite(runner),
                          tuple(predicted))
    return MarkResult(mark, "ok", float(col), float(row), float(score), _finite(runner),
                      tuple(predicted))


def _finite(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


class ScanReader:
    """Windows of a scan as float32 grey (mean of the first three bands), clipped to the scan,
    read from the file one window at a time (nothing else of the scan is ever in memory);
    ``pixels_read`` counts the scan pixels read so far."""

    def __init__(self, path: Path, name: str = "photo") -> None:
        import rasterio

        self.path = Path(path)
        self.pixels_read = 0
        try:
            with open_photo_grid(self.path) as src:  # (no warning for its missing georeference)
                self.width, self.height = src.width, src.height
                self.bands, self.dtype = src.count, src.dtypes[0]
                warn_orientation_tag(src, self.path, name)
        except rasterio.errors.RasterioError as exc:
            raise InputDataError(f"{name}: cannot read scan {path}: "
                                 f"{str(exc).splitlines()[0]}") from None

    def window(self, col0: int, row0: int, col1: int, row1: int
               ) -> tuple[np.ndarray, tuple[int, int]]:
        from rasterio.windows import Window

        c0, r0 = max(0, col0), max(0, row0)
        c1, r1 = min(self.width, col1), min(self.height, row1)
        if c1 <= c0 or r1 <= r0:
            return np.zeros((0, 0), np.float32), (c0, r0)
        with open_photo_grid(self.path) as src:  # grey, or the mean of R, G, B
            data = src.read(indexes=[1, 2, 3] if self.bands >= 3 else [1],
                            window=Window(c0, r0, c1 - c0, r1 - r0))
        self.pixels_read += (c1 - c0) * (r1 - r0)
        grey = data[0].astype(np.float32) if len(data) == 1 else \
            data.astype(np.float32).mean(axis=0)
        return grey, (c0, r0)


def search_photo(reader: ScanReader, photo: str, marks_mm: dict[str, tuple[float, float]],
                 template_for: Any, opts: MarkSearch, orientation: str = "auto") -> PhotoMarks:
    """Every mark of one scan. ``template_for(g, mark)`` gives the template of ``mark`` for
    orientation ``g``. Each distinct search window (the eight orientations share most of them)
    is read once, searched for every (orientation, mark) that needs it, then dropped."""
    names = list(ORIENTATIONS) if orientation == "auto" else [orientation]
    search_px = int(math.ceil(opts.search_mm / opts.pixel_mm))
    found: dict[tuple[str, str], MarkResult] = {}
    wanted: dict[tuple[int, int, int, int], list] = {}
    for name in names:
        g = ORIENTATIONS[name]
        for mark, p in predicted_positions(marks_mm, reader.width, reader.height, opts.pixel_mm,
                                           g).items():
            template = template_for(g, mark)
            if 2 * search_px < max(template.shape):
                raise InputDataError(
                    f"the template ({template.shape[1]} x {template.shape[0]} px) is larger than "
                    f"the search window ({2 * search_px} px, SEARCH_MM={opts.search_mm:g} at "
                    f"{opts.pixel_mm:g} mm/px): raise SEARCH_MM or use a smaller template")
            if not (0 <= p[0] < reader.width and 0 <= p[1] < reader.height):
                found[name, mark] = MarkResult(mark, "outside", None, None, None, None, tuple(p))
                continue
            reach = search_px + max(template.shape) // 2
            key = (int(p[0]) - reach, int(p[1]) - reach, int(p[0]) + reach + 1,
                   int(p[1]) + reach + 1)
            wanted.setdefault(key, []).append((name, mark, p, template))
    for key, jobs in wanted.items():
        window, origin = reader.window(*key)
        for name, mark, p, template in jobs:
            found[name, mark] = locate(window, origin, template, opts,
                                       (reader.width, reader.height), mark, p)
    tried = {name: [found[name, mark] for mark in marks_mm] for name in names}
    notes = []
    # an orientation is judged by the marks it finds that one affine transform explains
    # (a near-symmetric layout puts every orientation's windows on marks; only the geometry
    # tells them apart), then by their correlation
    rank = {n: _consistent(rs, marks_mm, opts.max_residual_mm) for n, rs in tried.items()}
    best = max(rank, key=lambda n: (rank[n], n == names[0]))
    if len(names) > 1:
        tol = 0.02 * len(marks_mm)
        tied = [n for n in names if n != best and rank[n][0] == rank[best][0]
                and rank[n][1] >= rank[best][1] - tol
                and _assignment(tried[n]) != _assignment(tried[best])]
        if tied:
            choice = "0" if "0" in [best, *tied] else best
            notes.append(f"scan orientation ambiguous between {', '.join(sorted([best, *tied]))}"
                         f" (symmetric marks and layout): {choice} assumed")
            best = choice
    return PhotoMarks(photo, best, tried[best], notes)


def _consistent(results: list[MarkResult], marks_mm: dict[str, tuple[float, float]],
                tolerance_mm: float) -> tuple[int, float]:
    """(marks an affine pixel -> mm transform explains within ``tolerance_mm``, the sum of their
    correlations), dropping the worst mark while any is farther."""
    ok = [r for r in results if r.ok]
    while len(ok) >= 3:
        px = np.array([[r.col_px, r.row_px, 1.0] for r in ok])
        mm = np.array([marks_mm[r.mark] for r in ok])
        coef, *_ = np.linalg.lstsq(px, mm, rcond=None)
        res = np.hypot(*(px @ coef - mm).T)
        worst = int(np.argmax(res))
        if len(ok) == 3 or res[worst] <= tolerance_mm:
            break
        ok.pop(worst)
    return len(ok), float(sum(r.score or 0.0 for r in ok))


def _assignment(results: list[MarkResult]) -> dict[str, tuple[int, int]]:
    return {r.mark: (round(r.col_px), round(r.row_px)) for r in results if r.ok}


def fit_marks(calibrated: dict[str, tuple[float, float]], found: PhotoMarks,
              transformation: str, max_residual_mm: float) -> Any:
    """Fit the pixel -> fiducial transform on the marks found, dropping the worst mark while its
    residual exceeds ``max_residual_mm`` and redundancy remains; returns the
    :class:`~toolbox.photogrammetry.fiducials.InteriorOrientation` (None if too few marks)."""
    from toolbox.photogrammetry.fiducials import InteriorOrientation

    needed = {"similarity": 2, "affine": 3, "homography": 4}[transformation]
    while True:
        ok = [r for r in found.marks if r.ok]
        if len(ok) < needed:
            return None
        measured = {r.mark: (r.col_px, r.row_px) for r in ok}
        io = InteriorOrientation.fit({m: calibrated[m] for m in measured}, measured,
                                     transformation, found.photo)
        if io.redundancy <= 0 or io.residuals_mm is None:
            return io
        res = np.hypot(io.residuals_mm[:, 0], io.residuals_mm[:, 1])
        worst = int(np.argmax(res))
        if res[worst] <= max_residual_mm or len(ok) - 1 < needed:
            return io
        bad = io.marks[worst]
        for r in found.marks:
            if r.mark == bad:
                r.status = "inconsistent"
                found.notes.append(f"mark {bad}: residual {res[worst]:.4f} mm > "
                                   f"{max_residual_mm:g} mm, dropped")


def interior_entry(io: Any, calibrated: dict[str, tuple[float, float]],
                   found: PhotoMarks) -> dict[str, Any]:
    """The per-photo entry orientation:interior writes (transform, residuals, sigma), plus the
    marks not used with their status, scores and the scan orientation."""
    measured = {r.mark: (r.col_px, r.row_px) for r in found.marks if r.ok and r.mark in io.marks}
    fitted = io.pixel_to_image(np.array([measured[m] for m in io.marks]))
    residuals = []
    for k, mark in enumerate(io.marks):
        vx, vy = (float(v) for v in io.residuals_mm[k])
        residuals.append({"mark": mark, "col_px": measured[mark][0],
                          "row_px": measured[mark][1], "x_mm": calibrated[mark][0],
                          "y_mm": calibrated[mark][1], "fitted_x_mm": float(fitted[k, 0]),
                          "fitted_y_mm": float(fitted[k, 1]), "res_x_mm": vx, "res_y_mm": vy,
                          "res_mm": math.hypot(vx, vy)})
    sigma = io.sigma0_mm if io.sigma0_mm is not None and np.isfinite(io.sigma0_mm) else None
    variance = io.variance_mm2 if sigma is not None else None
    return {"transformation": io.transformation, "marks": len(io.marks),
            "redundancy": io.redundancy, "sigma0_mm": sigma, "variance_mm2": variance,
            "max_residual_mm": max(m["res_mm"] for m in residuals),
            "pixel_size_mm": io.pixel_size_mm,
            "pixel_to_fiducial": io.pixel_to_fiducial.tolist(),
            "fiducial_to_pixel": io.fiducial_to_pixel.tolist(), "residuals": residuals,
            "scan_orientation": found.orientation,
            "found": [{"mark": r.mark, "score": r.score, "runner_up": r.runner_up}
                      for r in found.marks if r.ok],
            "missing": [{"mark": r.mark, "status": r.status, "score": r.score,
                         "runner_up": r.runner_up,
                         "predicted_px": [float(v) for v in r.predicted]}
                        for r in found.marks if not r.ok],
            "notes": found.notes}
