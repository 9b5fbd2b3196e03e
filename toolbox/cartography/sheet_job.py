"""The carto:sheet job: sheets from an extent or a sheet layer, written as PDF pages, PNG and
per-sheet files."""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from toolbox.cartography.grid_io import SheetSource, sheet_polygons
from toolbox.cartography.sheet_io import coded_styles, default_styles, render_sheet
from toolbox.cartography.sheet_layout import SheetSpec
from toolbox.io.source_date import today as source_today
from toolbox.version import __version__


def _name(ref) -> str:
    text = str(ref).strip("'")
    return Path(text.split("|")[0]).name


def _dated(ref) -> str:
    """A source by file name with its file's date: ``contours.gpkg (2026-12-03)``."""
    path = Path(str(ref).strip("'").split("|")[0])
    try:
        day = _dt.date.fromtimestamp(path.stat().st_mtime).isoformat()
    except OSError:
        return path.name
    return f"{path.name} ({day})"


def _datum(crs) -> str:
    try:
        return crs.datum.name if crs is not None and crs.datum is not None else ""
    except Exception:  # a CRS without a datum (engineering CRS)
        return ""


def _layer_name(ref) -> str:
    """The layer a reference names (``file.gpkg|layername=X`` -> X), else the file's stem."""
    text = str(ref).strip("'")
    for option in text.split("|")[1:]:
        key, _, value = option.partition("=")
        if key.strip().lower() == "layername":
            return value.strip()
    return Path(text.split("|")[0]).stem


@dataclass(frozen=True)
class SheetJob:
    """One carto:sheet run: the ``sheets``, drawn at 1:``scale`` with a map grid every
    ``map_step`` mm (``grid_style`` crosses or lines) on ``paper`` (auto, A4...A0); the
    ``base`` raster, vector ``layers`` (symbology from the ``codes``/``colours`` files),
    ``contours``; the title block's ``title``, ``sources`` (None: the input files, dated) and
    ``date`` (None: today); ``grid_crs``: a second projected CRS ticked along the frame;
    written to the PDF ``output`` (one page per sheet), the ``png`` of the first sheet at
    ``png_dpi``, and/or one PDF + PNG per sheet in ``folder``."""

    sheets: SheetSource
    scale: float = 5000.0
    title: str = "Map sheet"
    paper: str = "auto"
    grid_style: str = "crosses"
    map_step: float = 100.0
    png_dpi: int = 120
    base: Any = None
    layers: list = field(default_factory=list)
    contours: Any = None
    codes: Any = None
    colours: Any = None
    sources: str | None = None
    date: str | None = None
    grid_crs: Any = None
    index: Any = None
    index_field: str | None = None
    output: Path | None = None
    png: Path | None = None
    folder: Path | None = None
    executor: Any = None  # toolbox.executor.Executor; None or local: drawn in this process


def layer_styles(job: SheetJob, warn=None) -> tuple[list[tuple[str, object]], list]:
    """The LAYERS as (name, frame) and their sheet styles: from CODES/COLOURS through the
    shared style model when CODES is given, else default colours by geometry kind. Features
    without geometry (null or empty: nothing to draw) are left out, with a warning through
    ``warn``."""
    from toolbox.io.vector import read_vector

    refs = job.layers or []
    layers = [_drawable(_layer_name(ref), read_vector(ref, name="LAYERS"), warn)
              for ref in refs]
    if job.codes is None:
        return layers, default_styles(layers)
    from toolbox.io.code_file import read_code_file, read_colour_file

    table = read_code_file(job.codes, "CODES")
    colours = read_colour_file(job.colours, "COLOURS") \
        if job.colours is not None else None
    return layers, coded_styles(layers, table, colours)


def _drawable(name: str, frame, warn) -> tuple[str, object]:
    """``(name, frame)`` without the features that have no geometry (null or empty)."""
    import numpy as np

    from toolbox.io.vector import feature_rows, no_geometry

    missing = no_geometry(frame.geometry.values)
    if not missing.any():
        return name, frame
    if warn is not None:
        warn(f"LAYERS {name}: {int(missing.sum())} feature(s) without geometry (null or "
             f"empty) not drawn: {feature_rows(np.flatnonzero(missing))}")
    return name, frame[~missing]


def guard_sheets(job: SheetJob) -> None:
    """Refuse before drawing: too many sheets, a page too large to render at PNG_DPI (a tiny
    SCALE denominator), or too many map grid crosses."""
    from toolbox.cartography.grid import ground_step
    from toolbox.cartography.grid_io import guard_grid
    from toolbox.cartography.sheet_layout import GAP, LABEL_BAND, MARGIN, PANEL
    from toolbox.limits import check_size

    sheets, crs = sheet_polygons(job.sheets)  # null, empty or flat sheets refused
    if not sheets:
        return  # the job says so
    if job.sheets.sheets is not None:
        check_size("sheets", len(sheets), "SHEETS", f"has {len(sheets):,} features, which",
                   "draw fewer sheets")
    scale, dpi = job.scale, job.png_dpi
    widest = max(sheets, key=lambda s: (s[1].bounds[2] - s[1].bounds[0])
                 * (s[1].bounds[3] - s[1].bounds[1]))[1].bounds
    w = (widest[2] - widest[0]) / scale * 1000.0 + 2 * (MARGIN + LABEL_BAND) + GAP + PANEL
    h = (widest[3] - widest[1]) / scale * 1000.0 + 2 * (MARGIN + LABEL_BAND)
    check_size("cells", (w / 25.4 * dpi) * (h / 25.4 * dpi), "SCALE",
               f"1:{scale:g} puts the {widest[2] - widest[0]:,.0f} x "
               f"{widest[3] - widest[1]:,.0f} sheet on {w / 1000:,.1f} x {h / 1000:,.1f} m of "
               f"paper, which at PNG_DPI {dpi}", "check SCALE (the denominator: 5000 for "
               "1:5000) or use smaller sheets", "pixels")
    guard_grid(sheets, ground_step(scale, job.map_step), job.grid_style, scale,
               job.map_step)
    _refuse_empty_sheets(job, sheets, crs)


def _refuse_empty_sheets(job: SheetJob, sheets: list, crs=None) -> None:
    """Refuse BASE, LAYERS, CONTOURS in another CRS than the sheets' ``crs`` (naming both),
    then sheets that none of them meets (data of another area: the sheets would be empty
    frames)."""
    import shapely

    from toolbox.errors import InputDataError
    from toolbox.io.crs import common_crs, input_crs_and_bounds

    named = {"BASE": input_crs_and_bounds(job.base), "CONTOURS": input_crs_and_bounds(
        job.contours)} | {f"LAYERS[{k + 1}]": input_crs_and_bounds(ref)
                          for k, ref in enumerate(job.layers or [])}
    sheets_name = "SHEETS" if job.sheets.sheets is not None else "EXTENT"
    common_crs({sheets_name: crs} | {name: found[0][0] for name, found in named.items()
                                     if found},
               bounds={name: found[0][1] for name, found in named.items() if found})

    # envelopes, not boxes: one point, or points in a row, have a flat extent (an empty box)
    boxes = [shapely.envelope(shapely.MultiPoint([b[:2], b[2:]]))
             for value in (job.base, job.layers, job.contours)
             for _, b in input_crs_and_bounds(value) if b is not None]
    if not boxes:
        return  # nothing to draw, or extents unknown: the job draws what it has
    data = shapely.union_all(boxes)
    if not any(data.intersects(polygon) for _, polygon in sheets):
        d = data.bounds
        s = shapely.union_all([polygon for _, polygon in sheets]).bounds
        raise InputDataError(f"no input (BASE, LAYERS, CONTOURS: {d[0]:.0f}..{d[2]:.0f}, "
                             f"{d[1]:.0f}..{d[3]:.0f}) meets the sheets ({s[0]:.0f}..{s[2]:.0f}, "
                             f"{s[1]:.0f}..{s[3]:.0f}): the sheets would be empty; are they of "
                             "the same area and CRS?")


def _second_grid_accuracy(crs, job: SheetJob, sheets, feedback) -> None:
    """Warn when the datum transformation that places the second grid (GRID_CRS: Gauss-Boaga
    ticks on an RDN2008 sheet) is coarser than the map's planimetric tolerance at its scale
    (0.5 mm at 1:5000 = 2.5 m; the 4 m Monte Mario Helmert is not), of unknown accuracy, or
    when a better one needs a missing PROJ grid."""
    if job.grid_crs is None or crs is None or not sheets:
        return
    from toolbox.io.crs import note_transformation
    from toolbox.photogrammetry.accuracy import planimetric_tolerance_m

    boxes = [polygon.bounds for _, polygon in sheets]
    bounds = (min(b[0] for b in boxes), min(b[1] for b in boxes), max(b[2] for b in boxes),
              max(b[3] for b in boxes))
    note_transformation(feedback, crs, job.grid_crs, bounds,
                        planimetric_tolerance_m(job.scale), "the second grid (GRID_CRS)",
                        f"the map's planimetric tolerance at 1:{job.scale:g}")


def _second_grid(crs, second):
    """(transformer sheet CRS -> ``second``, label) for the frame's second grid, or None."""
    if second is None:
        return None
    from pyproj import Transformer

    from toolbox.errors import ParameterError
    from toolbox.io.crs import crs_label

    if crs is None:
        raise ParameterError("GRID_CRS: the sheet's data have no CRS to transform from")
    if not second.is_projected:
        raise ParameterError(f"GRID_CRS: {crs_label(second)} is not a projected CRS (grid "
                             "ticks are in metres)")
    return Transformer.from_crs(crs, second, always_xy=True), f"{crs_label(second)} " \
        f"({second.name})"


def sheet_file_names(job: SheetJob) -> list[str]:
    """The file name (without extension) of each sheet in FOLDER: its id made file-safe and
    unique."""
    from toolbox.mosaic.sheets import sheet_ids_unique

    return sheet_ids_unique([sheet_id for sheet_id, _ in sheet_polygons(job.sheets)[0]])


def _index_layer(ref, crs, feedback):
    """The INDEX layer in the sheets' CRS (one without a CRS is taken to be in it; one in
    another CRS is reprojected, with a warning naming both)."""
    from toolbox.io.crs import crs_label, note_transformation, one_crs
    from toolbox.io.vector import read_vector

    frame = read_vector(ref, name="INDEX")
    if frame.crs is None or crs is None or one_crs(frame.crs, crs, frame.total_bounds):
        # (another definition of the sheets' CRS, an ESRI WKT, is it: nothing moves)
        return frame.set_crs(crs, allow_override=True) if crs is not None else frame
    feedback.push_warning(f"INDEX is in {crs_label(frame.crs)}: reprojected to the sheets' "
                          f"{crs_label(crs)}")
    note_transformation(feedback, frame.crs, crs, frame.total_bounds, what="INDEX")
    return frame.to_crs(crs)


def run_sheets(job: SheetJob, feedback) -> dict:
    import matplotlib
    from matplotlib.backends.backend_pdf import PdfPages

    from toolbox.io.crs import crs_label
    from toolbox.io.staging import final_path
    from toolbox.io.vector import read_vector

    sheets, crs = sheet_polygons(job.sheets, feedback.push_warning)
    layers, styles = layer_styles(job, feedback.push_warning)
    contours = read_vector(job.contours, name="CONTOURS") \
        if job.contours is not None else None
    from toolbox.io.crs import common_crs, input_crs_and_bounds

    named = {"BASE": job.base.crs if job.base is not None else None,
             "CONTOURS": None if contours is None else contours.crs}
    named |= {f"LAYERS[{k + 1}]": f.crs for k, (_, f) in enumerate(layers)}
    extents = {"BASE": next((b for _, b in input_crs_and_bounds(job.base)), None),
               "CONTOURS": None if contours is None else contours.total_bounds}
    extents |= {f"LAYERS[{k + 1}]": f.total_bounds for k, (_, f) in enumerate(layers)}
    # the sheet's CRS: every layer in it (or in another definition of it), or refused
    crs = common_crs(named, crs, extents)
    sources = job.sources or "; ".join(dict.fromkeys(
        [_dated(job.base)] * (job.base is not None)
        + [_dated(ref) for ref in job.layers or []]
        + [_dated(job.contours)] * (job.contours is not None)))
    date = job.date or source_today().isoformat()  # SOURCE_DATE_EPOCH's when set
    index = _index_layer(job.index, crs, feedback) if job.index is not None else None
    _second_grid_accuracy(crs, job, sheets, feedback)
    folder = Path(job.folder) if job.folder else None  # staged by the runner
    names = sheet_file_names(job)
    written = []
    scale = job.scale
    meta = {"Title": job.title, "Subject": f"{len(sheets)} map sheet(s) at 1:{scale:g}",
            "Keywords": f"scale=1:{scale:g}; crs={crs_label(crs)}; "
                        f"sheets={','.join(s for s, _ in sheets)}",
            "Creator": "photogrammetry-toolbox carto:sheet"}
    pages = PdfPages(job.output, metadata=meta) if job.output else None
    if job.executor is not None and job.executor.kind == "dask":
        return _run_sheets_on_cluster(job, sheets, crs, styles, contours, index, sources, date,
                                      names, pages, feedback)
    try:
        for i, (sheet_id, polygon) in enumerate(feedback.iterate(sheets, start=0, end=100)):
            feedback.check_canceled()
            spec = SheetSpec(polygon.bounds, job.scale, job.title, sheet_id,
                             crs_label(crs), date, [sources], job.paper,
                             datum=_datum(crs), producer=f"photogrammetry-toolbox {__version__}")
            common = dict(base=job.base, base_name=_name(job.base)
                          if job.base is not None else "", styles=styles,
                          contours=contours, grid_style=job.grid_style,
                          map_step_mm=job.map_step, png_dpi=job.png_dpi)
            common["second_grid"] = _second_grid(crs, job.grid_crs)
            if index is not None:
                common["index"] = (index, job.index_field or "number", polygon)
            if common["second_grid"] is not None:
                spec.second_crs = common["second_grid"][1]
            pngs = [job.png] if job.png and i == 0 else []
            files = []
            if folder is not None:
                files = [folder / f"{names[i]}.pdf", folder / f"{names[i]}.png"]
                info = render_sheet(spec, pdfs=[files[0]], pngs=pngs + [files[1]],
                                    pdf_pages=pages, **common)
            else:
                info = render_sheet(spec, pngs=pngs, pdf_pages=pages, **common)
            if info["labels_left_out"]:
                feedback.push_warning(f"sheet {sheet_id}: {info['labels_left_out']} spot-height "
                                      "label(s) left out: no free place beside the point at "
                                      f"1:{scale:g}")
            files = [str(final_path(f)) for f in files]
            written.append(info | {"files": files})
    finally:
        if pages is not None:
            with matplotlib.rc_context({"pdf.fonttype": 42}):
                pages.close()
    return {"OUTPUT": job.output, "PNG": job.png,
            "SHEETS_WRITTEN": written}


@dataclass(frozen=True)
class SheetTask:
    """One sheet drawn on a Dask worker: what :func:`render_sheet` takes (layers and contours
    cut to the sheet's bounds, as it cuts them), and whether to send back the figure for the
    client's multi-page PDF."""

    spec: SheetSpec
    common: dict
    pdfs: list
    pngs: list
    page: bool


class _PickledPage:
    """Stands for ``PdfPages`` on a worker: keeps the figure, pickled, for the client's page."""

    def __init__(self):
        self.blob: bytes | None = None

    def savefig(self, fig) -> None:
        import pickle

        self.blob = pickle.dumps(fig)


_PYPLOT = __import__("threading").Lock()  # pyplot is not thread-safe: one sheet per process


def render_sheet_task(task: SheetTask) -> tuple[dict, bytes | None]:
    """``(render_sheet's page geometry, the pickled figure or None)`` of one sheet."""
    page = _PickledPage() if task.page else None
    with _PYPLOT:
        info = render_sheet(task.spec, pdfs=task.pdfs, pngs=task.pngs, pdf_pages=page,
                            **task.common)
    return info, None if page is None else page.blob


def _run_sheets_on_cluster(job: SheetJob, sheets, crs, styles, contours, index, sources, date,
                           names, pages, feedback) -> dict:
    """Each sheet drawn on a worker (the FOLDER and PNG files written there); the multi-page
    OUTPUT PDF gathered here from the workers' figures, in sheet order."""
    import pickle
    from dataclasses import replace

    import matplotlib
    import matplotlib.pyplot as plt

    from toolbox.executor import map_tiles
    from toolbox.io.crs import crs_label
    from toolbox.io.staging import final_path

    folder = Path(job.folder) if job.folder else None
    second = _second_grid(crs, job.grid_crs)

    def tasks():
        for i, (sheet_id, polygon) in enumerate(sheets):
            spec = SheetSpec(polygon.bounds, job.scale, job.title, sheet_id, crs_label(crs),
                             date, [sources], job.paper, datum=_datum(crs),
                             producer=f"photogrammetry-toolbox {__version__}")
            x0, y0, x1, y1 = polygon.bounds
            common = dict(base=job.base, base_name=_name(job.base) if job.base is not None
                          else "", grid_style=job.grid_style, map_step_mm=job.map_step,
                          png_dpi=job.png_dpi, second_grid=second,
                          styles=[replace(st, frame=st.frame.cx[x0:x1, y0:y1])
                                  for st in styles],
                          contours=None if contours is None else contours.cx[x0:x1, y0:y1])
            if index is not None:
                common["index"] = (index, job.index_field or "number", polygon)
            if second is not None:
                spec.second_crs = second[1]
            files = [folder / f"{names[i]}.pdf", folder / f"{names[i]}.png"] if folder else []
            pngs = ([job.png] if job.png and i == 0 else []) + files[1:]
            yield SheetTask(spec, common, [str(f) for f in files[:1]], [str(f) for f in pngs],
                            pages is not None)

    written = []
    try:
        for (sheet_id, _), (info, blob) in zip(sheets, map_tiles(
                render_sheet_task, tasks(), executor=job.executor, feedback=feedback,
                total=len(sheets)), strict=True):
            if blob is not None:
                fig = pickle.loads(blob)
                try:
                    with matplotlib.rc_context({"pdf.fonttype": 42}):
                        pages.savefig(fig)
                finally:
                    plt.close(fig)
            if info["labels_left_out"]:
                feedback.push_warning(f"sheet {sheet_id}: {info['labels_left_out']} spot-height "
                                      "label(s) left out: no free place beside the point at "
                                      f"1:{job.scale:g}")
            files = [folder / f"{n}" for n in (f"{names[len(written)]}.pdf",
                                                f"{names[len(written)]}.png")] if folder else []
            written.append(info | {"files": [str(final_path(f)) for f in files]})
    finally:
        if pages is not None:
            with matplotlib.rc_context({"pdf.fonttype": 42}):
                pages.close()
    return {"OUTPUT": job.output, "PNG": job.png, "SHEETS_WRITTEN": written}
