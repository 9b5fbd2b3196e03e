"""carto:sheet - a map sheet (PDF and PNG) at an exact scale, or one per sheet of a sheet grid."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import (
    Crs,
    Enum,
    Field,
    File,
    Integer,
    MultipleLayers,
    Number,
    RasterLayer,
    String,
    VectorLayer,
)
from toolbox.parameters.outputs import Output, OutputFile, OutputFolder
from toolbox.registry import register
from toolbox.ui.cartography import sheet_parameters, sheet_source
from toolbox.ui.execution import executor_of, scheduler_parameter


@register
class Sheet(Algorithm):
    """A map sheet of ``EXTENT`` at 1:``SCALE``, or one per feature of ``SHEETS``.

    The map frame measures exactly ground size / scale on paper (print at 100%), on the smallest
    ISO sheet (A4...A0, portrait or landscape) that holds it and the side panel, unless
    ``PAPER`` names one. Drawn: the ``BASE`` raster (orthophoto or hillshade), the ``LAYERS``,
    the ``CONTOURS`` (index contours heavier, labelled along the line), the map grid every
    ``MAP_STEP`` mm with its coordinates at the frame (none at the corners), ticks and outer
    labels of a second CRS's grid (``GRID_CRS``, e.g. ETRS89 / UTM 32N beside Gauss-Boaga),
    a legend drawn as
    the map is, a scale bar, a north arrow (grid north), and a title block with the title,
    sheet id, scale, CRS and datum, contour interval, date, sources with their dates and the
    producer. Point layers are spot heights, labelled with their height (Z, else a
    z/quota/elev/height/h field). The map and panel are centred on the paper; no text is under
    6 pt. The PDF is vector (text as TrueType text, lines as paths), the base
    raster is embedded at 200 dpi; its metadata keep the scale, CRS and bounds.

    With symbology columns in ``CODES`` (``spessore``/width mm, ``tipo linea``/linetype:
    continuous, dashed, dotted, dashdot, scarp; ``simbolo``/symbol: dot (a spot height,
    labelled), circle, cross, triangle, square, tree; ``campitura``/hatch: solid or
    ANGLE/SPACING in degrees/mm; ``codice consegna``/delivered code) each code is drawn so, the
    legend lists the delivered codes once each with swatches drawn by the map's own routine,
    and texts of the restitution (a layer with a ``text`` field, as ``attribution:apply`` writes
    DXF texts) are placed at their size (at least 6 pt) and rotation.

    ``LAYERS`` take their symbology from the code file ``CODES`` (and ``COLOURS``) through the
    shared style model, the one ``attribution:apply`` embeds in its GeoPackage for QGIS: a
    layer with a ``code`` field is drawn by code, a layer named after a code (one layer per
    code) in that code's colour, and the legend lists each code with its description. Layers
    with neither, and every layer without ``CODES``, get default colours by geometry kind.

    ``INDEX``, a sheet index layer (``carto:sheet_index``: CTR elements or sections with their
    ``number``; another field with ``INDEX_ID``), adds a small index map to the panel's top
    right: the sheet (shaded) and its neighbours with their numbers; the title block names its
    number in the index when the sheet's id is another. Give the same layer as
    ``SHEETS`` (``SHEET_ID number``) for one sheet per element of the index.

    With ``SHEETS``, ``OUTPUT`` holds one page per sheet, and ``FOLDER`` (if given) receives one
    ``<sheet id>.pdf`` and ``.png`` per sheet; a sheet is the bounds of its polygon (a null,
    empty or flat one is refused, one that crosses itself repaired). Features of ``LAYERS``
    without geometry are not drawn (a warning names them). On a Dask cluster (SCHEDULER or
    DASK_SCHEDULER_ADDRESS) each sheet is drawn on a worker, which writes its FOLDER files and
    PNG (on storage the workers share) and sends its page back for OUTPUT; locally the sheets
    are drawn one after the other in this process.
    """

    id = "carto:sheet"
    display_name = "Map sheet"
    group = "Cartography"
    short_help = "Map sheet PDF/PNG at an exact scale: base, layers, contours, grid, legend."
    parameters = [
        *sheet_parameters("sheet area: 'xmin,ymin,xmax,ymax EPSG:3003' (CRS optional)",
                               "sheet grid polygons instead of EXTENT (one sheet each)"),
        RasterLayer("BASE", "base raster: orthophoto (RGB) or hillshade (grey)", optional=True),
        MultipleLayers("LAYERS", "vector layers to draw", layer_type="vector", min_count=0,
                       optional=True),
        File("CODES", "code file ('file dei codici'): LAYERS drawn with its symbology",
             optional=True),
        File("COLOURS", "colour file ('file dei colori') of the CODES", optional=True),
        VectorLayer("CONTOURS", "contour lines (carto:contours output)", geometry_types=["line"],
                    optional=True),
        Enum("GRID_STYLE", "map grid drawing", options=["crosses", "lines"], default="crosses"),
        Number("MAP_STEP", "map grid step on paper, mm", default=100.0, min_value=0,
               min_exclusive=True),
        Enum("PAPER", "paper size", options=["auto", "A4", "A3", "A2", "A1", "A0"],
             default="auto"),
        String("TITLE", "title in the title block", default="Map sheet"),
        String("SOURCES", "sources line (default: the input files)", optional=True),
        String("DATE", "date in the title block (default: today, ISO; SOURCE_DATE_EPOCH's day "
               "when that is set)", optional=True),
        Crs("CRS", "CRS of EXTENT or SHEETS when they name none (one naming another CRS "
            "is refused)", optional=True),
        Crs("GRID_CRS", "second CRS ticked along the frame (e.g. EPSG:6707 beside EPSG:3003)",
            optional=True),
        VectorLayer("INDEX", "sheet index (carto:sheet_index) drawn as a small index map",
                    geometry_types=["polygon"], optional=True),
        Field("INDEX_ID", "sheet number field of INDEX (default: number)", parent="INDEX",
              optional=True),
        scheduler_parameter("the sheets"),
        OutputFile("OUTPUT", "sheet PDF (one page per sheet)", extensions=[".pdf"],
                   optional=True),
        OutputFile("PNG", "PNG of the (first) sheet", extensions=[".png"], optional=True),
        Integer("PNG_DPI", "PNG resolution, dots per inch", default=120, min_value=30,
                max_value=600),
        OutputFolder("FOLDER", "folder for one <sheet id>.pdf/.png per sheet", optional=True),
    ]
    outputs = [Output("SHEETS_WRITTEN", "per sheet: paper, frame and scale bar (mm), files",
                      "list")]

    def check(self, params):
        if params.get("COLOURS") is not None and params.get("CODES") is None:
            raise self.fail("COLOURS", "needs CODES (the colour file gives the RGB of the code "
                            "file's colour indices)")
        sheet_source(params)
        contours = params.get("CONTOURS")
        if contours is not None and not ("elev" in contours.fields
                                         and contours.is_numeric("elev")):
            raise self.fail("CONTOURS", f"{contours} has no numeric 'elev' field (the contour "
                            "heights, as carto:contours writes them)")
        if not (params.get("OUTPUT") or params.get("PNG") or params.get("FOLDER")):
            raise self.fail("OUTPUT", "or PNG or FOLDER: give at least one")
        from toolbox.cartography.sheet_job import guard_sheets

        guard_sheets(sheet_job(params))

    def planned_files(self, params):
        if params.get("FOLDER") is None:
            return {"FOLDER": []}
        from toolbox.cartography.sheet_job import sheet_file_names

        return {"FOLDER": [f"{name}{ext}" for name in sheet_file_names(sheet_job(params))
                           for ext in (".pdf", ".png")]}

    def process(self, params, feedback: Feedback):
        from toolbox.cartography.sheet_job import run_sheets

        return run_sheets(sheet_job(params), feedback)


def sheet_job(params: dict):
    """The typed request of a run (:class:`toolbox.cartography.sheet_job.SheetJob`)."""
    from toolbox.cartography.sheet_job import SheetJob

    return SheetJob(
        sheets=sheet_source(params),
        scale=params["SCALE"], title=params["TITLE"], paper=params["PAPER"],
        grid_style=params["GRID_STYLE"], map_step=params["MAP_STEP"],
        png_dpi=params["PNG_DPI"], base=params.get("BASE"), layers=params.get("LAYERS") or [],
        contours=params.get("CONTOURS"), codes=params.get("CODES"),
        colours=params.get("COLOURS"), sources=params.get("SOURCES"), date=params.get("DATE"),
        grid_crs=params.get("GRID_CRS"), index=params.get("INDEX"),
        index_field=params.get("INDEX_ID"), output=params.get("OUTPUT"), png=params.get("PNG"),
        folder=params.get("FOLDER"), executor=executor_of(params))
