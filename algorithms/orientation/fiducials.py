"""orientation:fiducials - automatic measurement of fiducial marks on scanned frames."""

from __future__ import annotations

from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Enum, File, Number, Output, OutputFile, OutputFolder, String
from toolbox.registry import register

ORIENTATION_CHOICES = ("auto", "0", "90", "180", "270", "0m", "90m", "180m", "270m")
FAMILIES = ("cross", "dot", "cross_in_circle", "wild_rc8", "wild_rc10", "zeiss_rmk_top",
            "zeiss_rmk_a")


@register
class FiducialMarks(Algorithm):
    """Measure the fiducial marks of scanned photos and fit their interior orientation.

    PROJECT gives the photos (their ``image``: the scans, 8 or 16 bit, read window by window)
    and their cameras' calibrated marks (``fiducials_mm``, fiducial system, y up) and scan pixel
    size (``pixel_size_mm``, or PIXEL_SIZE). Each mark is first placed from the certificate:
    near ``scan centre + G·(x, -y)/pixel``, ``G`` one of the eight scan orientations (0, 90,
    180, 270 degrees, mirrored or not; ORIENTATION=auto tries all and keeps the best, a tie
    between different assignments keeps the scan as it is, with a note). It is then searched
    within SEARCH_MM by normalised cross-correlation (OpenCV TM_CCOEFF_NORMED; coarse on a
    decimated window, then at full resolution with a quadratic sub-pixel peak) with TEMPLATE
    (an image of one mark as an upright scan shows it) or a built-in FAMILY, bright or dark
    (POLARITY): cross, dot, cross_in_circle of MARK_SIZE mm with LINE_WIDTH mm lines (1 and
    0.06 mm unless given), or the marks of a camera, drawn from their published geometry
    (toolbox.matching.camera_marks names the sources), a corner mark (near a diagonal of the
    certificate) and a side mark differing where the camera's do: wild_rc8 (a bright disc with
    a dark x, 3.2 / 0.06 mm), wild_rc10 (a cross in a ring, x in the corners and + at the
    sides; its size is not published: give MARK_SIZE = ring diameter and LINE_WIDTH),
    zeiss_rmk_top (ring, central dot and four spokes, 1.85 / 0.3 mm), zeiss_rmk_a (a disc of
    MARK_SIZE mm, to be given). The scan is read only in windows around the predicted marks,
    each once: STATISTICS counts the pixels read.

    A mark whose peak is below MIN_SCORE (covered), whose runner-up (best score farther than
    the mark's size) is within MARGIN of the peak (ambiguous), that leaves the scan (cropped,
    outside) or that the fitted transform leaves a residual above MAX_RESIDUAL mm (inconsistent)
    is reported missing with its scores, never placed. The pixel -> fiducial transform
    (TRANSFORMATION) is fitted as orientation:interior does on the marks found.

    OUTPUT: the JSON orientation:interior writes (per photo: matrices, residuals in mm,
    sigma0), with per photo the scan orientation, the marks found with their correlation and
    runner-up, and the missing ones with their status. MEASUREMENTS: the marks found as a CSV
    (photo, mark_id, col_px, row_px, score, runner_up) that orientation:interior reads with
    PROJECT. THUMBNAILS: a PNG per mark (found centre in green, missing marks in red).
    """

    id = "orientation:fiducials"
    display_name = "Fiducial marks (automatic)"
    group = "Orientation"
    short_help = "Find fiducial marks on scans (NCC, sub-pixel) and fit the interior orientation."
    parameters = [
        File("PROJECT", "orientation project (YAML): photos with scans, cameras with "
             "fiducials_mm", extensions=[".yaml", ".yml"]),
        String("PHOTOS", "comma-separated photo ids (default: every photo with an image)",
               optional=True),
        File("TEMPLATE", "image of one mark (as an upright scan shows it)",
             extensions=[".tif", ".tiff", ".png", ".jpg"], optional=True),
        Enum("FAMILY", "built-in mark shape when no TEMPLATE", options=FAMILIES,
             default="cross"),
        Number("MARK_SIZE", "built-in mark: size (cross length, dot/ring diameter), mm "
               "(default: the family's published size; 1 for cross, dot, cross_in_circle)",
               optional=True, min_value=0.0, min_exclusive=True),
        Number("LINE_WIDTH", "built-in mark: line width, mm (default: the family's; 0.06)",
               optional=True, min_value=0.0, min_exclusive=True),
        Enum("POLARITY", "marks brighter or darker than their background", options=(
             "auto", "bright", "dark"), default="auto"),
        Number("PIXEL_SIZE", "scan pixel size, mm (default: the camera's pixel_size_mm)",
               optional=True, min_value=0.0, min_exclusive=True),
        Number("SEARCH_MM", "half size of the search window around the predicted mark, mm",
               default=8.0, min_value=0.0, min_exclusive=True),
        Number("MIN_SCORE", "smallest correlation of a mark", default=0.6, min_value=0.0,
               max_value=1.0),
        Number("MARGIN", "runner-up closer than this to the peak: ambiguous", default=0.1,
               min_value=0.0, max_value=1.0),
        Enum("ORIENTATION", "scan orientation (degrees clockwise, m = mirrored)",
             options=ORIENTATION_CHOICES, default="auto"),
        Enum("TRANSFORMATION", "pixel -> fiducial transform", options=("affine", "homography",
             "similarity"), default="affine"),
        Number("MAX_RESIDUAL", "largest mark residual kept, mm", default=0.05, min_value=0.0,
               min_exclusive=True),
        OutputFile("OUTPUT", "interior orientation (JSON, as orientation:interior)",
                   extensions=[".json"]),
        OutputFile("MEASUREMENTS", "marks found (CSV: photo, mark_id, col_px, row_px, score)",
                   extensions=[".csv"], optional=True),
        OutputFolder("THUMBNAILS", "folder of per-mark PNG thumbnails", optional=True),
    ]
    outputs = [Output("STATISTICS", "photos fitted and failed, marks missing, largest residual",
                      "json")]

    def planned_files(self, params):
        """THUMBNAILS: PNG files whose names come from the data (checked as a pattern)."""
        return {"THUMBNAILS": ["*.png"]} if params.get("THUMBNAILS") is not None else {}

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from toolbox.errors import InputDataError
        from toolbox.matching import marks
        from toolbox.matching.fiducial_search import (
            MarkSearch,
            ScanReader,
            fit_marks,
            interior_entry,
            search_photo,
            turned,
        )
        from toolbox.matching.fiducial_thumbs import write_thumbnails
        from toolbox.photogrammetry.tables import load_project_parameter, write_csv, write_json

        project = load_project_parameter(params["PROJECT"])
        photos = [p for p in project.photos.values() if p.image is not None]
        if params["PHOTOS"]:
            wanted = [s.strip() for s in params["PHOTOS"].split(",") if s.strip()]
            unknown = [w for w in wanted if w not in project.photos]
            if unknown:
                raise self.fail("PHOTOS", f"names photo(s) {', '.join(unknown)} that PROJECT "
                                "does not have")
            photos = [p for p in photos if p.id in wanted]
        if not photos:
            raise self.fail("PROJECT", "has no photo with an image to measure")
        template_file = None
        if params["TEMPLATE"] is not None:
            template_file = marks.read_template(params["TEMPLATE"])
        size_mm, line_mm = self._mark_size(params, marks)
        entries, failed, rows, missing_total = [], [], [], 0
        pixels_read = pixels_total = 0
        for photo in feedback.iterate(photos):
            cam = photo.camera
            if len(cam.fiducials_mm) < 2:
                raise InputDataError(f"PROJECT: camera {cam.name!r} of photo {photo.id!r} has "
                                     "no calibrated fiducials_mm (at least 2 marks)")
            pixel = params["PIXEL_SIZE"] or cam.pixel_size_mm
            if pixel is None:
                raise self.fail("PIXEL_SIZE", f"is needed: camera {cam.name!r} gives no "
                                "pixel_size_mm")
            if not photo.image.exists():
                raise InputDataError(f"PROJECT: the scan {photo.image} of photo {photo.id!r} "
                                     "does not exist")
            reader = ScanReader(photo.image, f"photo {photo.id!r}")
            side = max(reader.width, reader.height)
            if template_file is None and not size_mm / pixel < side:  # NaN too
                raise self.fail("MARK_SIZE", f"{size_mm:g} mm is "
                                f"{size_mm / pixel:.3g} pixels of {pixel:g} mm, "
                                f"more than the whole scan of photo {photo.id!r} ({side} px): "
                                "give the mark's size in mm")
            if template_file is not None:
                grey, dtype = template_file
                if marks.bit_depth(dtype) > marks.bit_depth(reader.dtype):
                    raise InputDataError(
                        f"TEMPLATE is {dtype} but the scan of photo {photo.id!r} is "
                        f"{reader.dtype}: give a template cut from a scan of the same depth")

                def template_for(g, mark, grey=grey):
                    return turned(grey, g)
            else:
                template_for = self._drawn_templates(params["FAMILY"], size_mm, line_mm, pixel,
                                                     dict(cam.fiducials_mm))
            opts = MarkSearch(pixel, params["SEARCH_MM"], params["MIN_SCORE"], params["MARGIN"],
                              params["POLARITY"], max_residual_mm=params["MAX_RESIDUAL"])
            try:
                found = search_photo(reader, photo.id, dict(cam.fiducials_mm), template_for,
                                     opts, params["ORIENTATION"])
            except InputDataError as exc:
                raise InputDataError(f"photo {photo.id!r}: {exc}") from None
            if all(r.status == "outside" for r in found.marks):
                reach = max(max(abs(x), abs(y)) for x, y in cam.fiducials_mm.values())
                raise InputDataError(
                    f"PROJECT: every calibrated mark of camera {cam.name!r} falls outside the "
                    f"scan of photo {photo.id!r} ({reader.width} x {reader.height} px of "
                    f"{pixel:g} mm = {reader.width * pixel:.1f} x {reader.height * pixel:.1f} "
                    f"mm; marks up to {reach:g} mm from the centre): check fiducials_mm and "
                    "PIXEL_SIZE / pixel_size_mm")
            pixels_read += reader.pixels_read
            pixels_total += reader.width * reader.height
            io = fit_marks(dict(cam.fiducials_mm), found, params["TRANSFORMATION"],
                           params["MAX_RESIDUAL"])
            missing = [r for r in found.marks if not r.ok]
            missing_total += len(missing)
            for note in found.notes:
                feedback.push_warning(f"photo {photo.id}: {note}")
            if missing:
                feedback.push_warning(f"photo {photo.id}: mark(s) not measured: " + ", ".join(
                    f"{r.mark} ({r.status}, score {_fmt(r.score)}, runner-up "
                    f"{_fmt(r.runner_up)})" for r in missing))
            if params["THUMBNAILS"] is not None:
                half = int(max(1.5 * size_mm / pixel, 16))
                if template_file is not None:
                    half = max(half, max(template_file[0].shape))
                write_thumbnails(params["THUMBNAILS"], reader, found, half)
            if io is None:
                failed.append({"photo": photo.id, "scan_orientation": found.orientation,
                               "reason": f"too few marks found for a {params['TRANSFORMATION']}"
                                         " transform",
                               "marks": [r.__dict__ for r in found.marks]})
                feedback.push_warning(f"photo {photo.id}: too few marks for the transform")
                continue
            entries.append({"photo": photo.id, "source": "orientation:fiducials"}
                           | interior_entry(io, dict(cam.fiducials_mm), found))
            rows += [[photo.id, r.mark, r.col_px, r.row_px, r.score, r.runner_up]
                     for r in found.marks if r.ok and r.mark in io.marks]
        if not entries:
            raise InputDataError(f"no photo could be fitted: {len(failed)} photo(s) with too few "
                                 f"marks found (first: {failed[0]['photo']}); see the "
                                 "THUMBNAILS or lower MIN_SCORE")
        stats = {"photos": len(entries), "photos_failed": [f["photo"] for f in failed],
                 "marks_missing": missing_total,
                 "max_residual_mm": max(e["max_residual_mm"] for e in entries),
                 "max_sigma0_mm": max((e["sigma0_mm"] for e in entries
                                       if e["sigma0_mm"] is not None), default=None),
                 "pixels_read": pixels_read, "pixels_in_scans": pixels_total}
        write_json(params["OUTPUT"], {"algorithm": self.id, "input": str(params["PROJECT"]),
                                      "residual_convention": "fitted - calibrated, mm",
                                      "statistics": stats, "photos": entries,
                                      "failed": failed})
        if params["MEASUREMENTS"] is not None:
            write_csv(params["MEASUREMENTS"], ["photo", "mark_id", "col_px", "row_px", "score",
                                               "runner_up"], rows)
        return {"OUTPUT": params["OUTPUT"], "MEASUREMENTS": params["MEASUREMENTS"],
                "THUMBNAILS": params["THUMBNAILS"], "STATISTICS": stats}

    def _mark_size(self, params, marks) -> tuple[float, float]:
        """MARK_SIZE and LINE_WIDTH, or the family's published ones; refused when neither."""
        size, line = marks.default_size(params["FAMILY"])
        size = params["MARK_SIZE"] if params["MARK_SIZE"] is not None else size
        line = params["LINE_WIDTH"] if params["LINE_WIDTH"] is not None else line
        if params["TEMPLATE"] is None:
            for name, value in (("MARK_SIZE", size), ("LINE_WIDTH", line)):
                if value is None:
                    raise self.fail(name, f"is needed with FAMILY={params['FAMILY']}: no "
                                    "published size for its marks (measure one on a scan, mm)")
        return size or 1.0, line or 0.06

    @staticmethod
    def _drawn_templates(family, size_mm, line_mm, pixel, marks_mm):
        """``template_for(g, mark)``: the family's corner or side mark as a scan of orientation
        ``g`` shows it (drawn once per orientation and kind)."""
        import numpy as np

        from toolbox.matching import marks
        from toolbox.matching.camera_marks import mark_kind

        drawn = {}

        def template_for(g, mark):
            kind = mark_kind(*marks_mm[mark])
            key = (g.tobytes(), kind)
            if key not in drawn:
                # pixel offset p = G·(x, -y)/s  =>  (x, y) = s·D·G⁻¹·p, D = diag(1, -1)
                affine = pixel * np.diag([1.0, -1.0]) @ np.linalg.inv(g)
                drawn[key] = marks.draw(family, size_mm, line_mm, pixel, affine, kind=kind)
            return drawn[key]

        return template_for


def _fmt(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"
