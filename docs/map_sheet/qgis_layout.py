"""The demo's map sheet laid out by QGIS's print layout (PyQGIS), for a side-by-side comparison
with ``carto:sheet`` (docs/map_sheet.md).

Run with the Python that has QGIS (not the toolbox's venv), from a folder made by
``toolbox demo --out demo_out``:

    QT_QPA_PLATFORM=offscreen /usr/bin/python3 docs/map_sheet/qgis_layout.py demo_out qgis_sheet

It writes ``qgis_sheet.pdf`` and ``qgis_sheet.png``: the same extent, scale (1:5000), data
(relief shading, contours in the toolbox's own ``contours.qml``, the landscape's and the
restitution's coded layers, the DXF's text) and symbology (colours, widths, line types and
hatching of the demo's code and colour files, read here with a few lines rather than the
toolbox, which this Python does not have),
with QGIS's own map grid (EPSG:3003, plus EPSG:6707 ticks), legend, scale bar, north arrow
and a title label. Nothing here is tuned to look like the toolbox's sheet beyond that.
"""

from __future__ import annotations

import sys
from pathlib import Path

from qgis.core import (
    QgsApplication,
    QgsCoordinateReferenceSystem,
    QgsFillSymbol,
    QgsLayoutExporter,
    QgsLayoutItemLabel,
    QgsLayoutItemLegend,
    QgsLayoutItemMap,
    QgsLayoutItemMapGrid,
    QgsLayoutItemPicture,
    QgsLayoutItemScaleBar,
    QgsLayoutPoint,
    QgsLayoutSize,
    QgsLinePatternFillSymbolLayer,
    QgsLineSymbol,
    QgsMarkerSymbol,
    QgsPalLayerSettings,
    QgsPrintLayout,
    QgsProject,
    QgsRasterLayer,
    QgsRectangle,
    QgsRenderContext,
    QgsSingleSymbolRenderer,
    QgsTextFormat,
    QgsUnitTypes,
    QgsVectorLayer,
    QgsVectorLayerSimpleLabeling,
)
from qgis.PyQt.QtCore import Qt
from qgis.PyQt.QtGui import QColor, QFont

EXTENT = (1687500.0, 4798974.0, 1689112.0, 4800350.0)  # the demo sheet's (EPSG:3003)
SCALE = 5000.0
PAPER = (594.0, 420.0)  # A2 landscape, as carto:sheet chose for this extent
MM = QgsUnitTypes.LayoutMillimeters


def code_colours(folder: Path) -> dict[str, tuple[QColor, list[str]]]:
    """code -> (colour, the row's fields) from the demo's code file (';' with a header) and
    colour file (INDEX %R %G %B)."""
    colours = {}
    for line in (folder / "data/siena_colori.txt").read_text().splitlines()[1:]:
        i, r, g, b = line.split()
        colours[i] = QColor(*(round(float(p) * 255 / 100) for p in (r, g, b)))
    out = {}
    rows = [line.split(";") for line in
            (folder / "data/siena_codici.txt").read_text(encoding="latin-1").splitlines()
            if line.strip() and not line.startswith("#")]
    for row in rows[1:]:
        out[row[0]] = (colours.get(row[3], QColor(128, 128, 128)), row)
    return out


def vector(project, path: str, name: str) -> QgsVectorLayer:
    layer = QgsVectorLayer(path, name, "ogr")
    assert layer.isValid(), path
    project.addMapLayer(layer, False)
    return layer


def main(folder: Path, out: Path) -> None:
    QgsApplication.setPrefixPath("/usr", True)
    app = QgsApplication([], False)
    app.initQgis()
    project = QgsProject.instance()
    project.setCrs(QgsCoordinateReferenceSystem("EPSG:3003"))
    codes = code_colours(folder)
    land = str(folder / "data/siena_landscape.gpkg")
    coded = str(folder / "attribution/siena_coded.gpkg")
    dxf = str(folder / "attribution/siena_dxf_coded.gpkg")

    def col(code):
        return codes[code][0]

    shade = QgsRasterLayer(str(folder / "hillshade.tif"), "relief shading")
    shade.renderer().setOpacity(0.45)  # printed light under the linework, as carto:sheet
    project.addMapLayer(shade, False)

    green = [vector(project, f"{p}|layername={n}", "AREA_VERDE area a verde")
             for p, n in ((land, "green"),)]
    for layer in green:
        c = col("VEG01001")
        fill = QColor(c)
        fill.setAlpha(96)
        layer.setRenderer(QgsSingleSymbolRenderer(QgsFillSymbol.createSimple({
            "color": fill.name(QColor.HexArgb), "outline_color": c.name(),
            "outline_width": "0.13", "outline_width_unit": "MM", "outline_style": "dash"})))

    buildings = [vector(project, f"{land}|layername=buildings",
                        "EDIFICIO muro perimetrale di fabbricato civile"),
                 vector(project, f"{coded}|layername=FAB01002", "EDIFICIO (restitution)")]
    for layer in buildings:  # outline 0.25 mm, hatching 45 degrees every 1 mm, 0.1 mm lines
        symbol = QgsFillSymbol.createSimple({"color": "0,0,0,0", "outline_color":
                                             col("FAB01002").name(), "outline_width": "0.25",
                                             "outline_width_unit": "MM"})
        hatch = QgsLinePatternFillSymbolLayer()
        hatch.setLineAngle(45)
        hatch.setDistance(1.0)
        hatch.setDistanceUnit(QgsUnitTypes.RenderMillimeters)
        hatch.setColor(col("FAB01002"))
        hatch.setLineWidth(0.1)
        hatch.setLineWidthUnit(QgsUnitTypes.RenderMillimeters)
        symbol.appendSymbolLayer(hatch)
        layer.setRenderer(QgsSingleSymbolRenderer(symbol))

    roads = [vector(project, f"{land}|layername=road_edges", "BORDO_STRADA limite di strada"),
             vector(project, f"{coded}|layername=STR02001", "BORDO_STRADA (restitution)")]
    for layer in roads:
        layer.setRenderer(QgsSingleSymbolRenderer(QgsLineSymbol.createSimple({
            "line_color": col("STR02001").name(), "line_width": "0.18",
            "line_width_unit": "MM"})))

    spots = [vector(project, f"{land}|layername=spot_heights", "PUNTO_QUOTATO punto quotato"),
             vector(project, f"{coded}|layername=QUO01001", "PUNTO_QUOTATO (restitution)")]
    for layer, expr in zip(spots, ("format_number(\"quota\", 1)", "format_number(z($geometry), 1)")):
        layer.setRenderer(QgsSingleSymbolRenderer(QgsMarkerSymbol.createSimple({
            "name": "circle", "color": col("QUO01001").name(), "size": "0.7",
            "size_unit": "MM", "outline_style": "no"})))
        label(layer, expr, col("QUO01001"), placement=QgsPalLayerSettings.OrderedPositionsAroundPoint)

    contours = vector(project, str(folder / "carto/contours.gpkg"), "contours")
    contours.loadNamedStyle(str(folder / "carto/contours.qml"))  # the toolbox's QGIS style
    brown = contours.renderer().symbols(QgsRenderContext())[0].color()
    label(contours, 'if("index" = 1, format_number("elev", 0), \'\')', brown,
          placement=QgsPalLayerSettings.Line, buffer=True)

    texts = vector(project, f"{dxf}|layername=labels", "TOPONIMO toponimo (località)")
    texts.setRenderer(QgsSingleSymbolRenderer(QgsMarkerSymbol.createSimple(
        {"size": "0", "outline_style": "no", "color": "0,0,0,0"})))
    label(texts, '"text"', col("TOP01001"), italic=True,
          placement=QgsPalLayerSettings.OverPoint)

    layers = [texts, *spots, contours, *roads, *buildings, *green, shade]

    layout = QgsPrintLayout(project)
    layout.initializeDefaults()
    page = layout.pageCollection().page(0)
    page.setPageSize(QgsLayoutSize(*PAPER, MM))
    map_w = (EXTENT[2] - EXTENT[0]) / SCALE * 1000
    map_h = (EXTENT[3] - EXTENT[1]) / SCALE * 1000
    left, top = 28.0, (PAPER[1] - map_h) / 2
    item = QgsLayoutItemMap(layout)
    item.attemptMove(QgsLayoutPoint(left, top, MM))
    item.attemptResize(QgsLayoutSize(map_w, map_h, MM))
    item.setLayers(layers)
    item.setExtent(QgsRectangle(*EXTENT))
    item.setScale(SCALE)
    item.setFrameEnabled(True)
    layout.addLayoutItem(item)

    for crs, style, offset, colour in (("EPSG:3003", QgsLayoutItemMapGrid.Cross, 1.5, "black"),
                                       ("EPSG:6707", QgsLayoutItemMapGrid.FrameAnnotationsOnly,
                                        5.0, "#1f4fbf")):
        grid = QgsLayoutItemMapGrid(crs, item)
        grid.setCrs(QgsCoordinateReferenceSystem(crs))
        grid.setIntervalX(500)
        grid.setIntervalY(500)
        grid.setStyle(style)
        grid.setCrossLength(10)
        grid.setAnnotationEnabled(True)
        grid.setAnnotationPrecision(0)
        grid.setAnnotationFrameDistance(offset)
        fmt = QgsTextFormat()
        fmt.setFont(QFont("DejaVu Sans"))
        fmt.setSize(6)
        fmt.setColor(QColor(colour))
        grid.setAnnotationTextFormat(fmt)
        for border in (QgsLayoutItemMapGrid.Left, QgsLayoutItemMapGrid.Right):
            grid.setAnnotationDirection(QgsLayoutItemMapGrid.Vertical, border)
        if crs == "EPSG:6707":
            grid.setFrameStyle(QgsLayoutItemMapGrid.ExteriorTicks)
            grid.setFrameWidth(3.9)
            grid.setFramePenColor(QColor(colour))
        item.grids().addGrid(grid)

    x0 = left + map_w + 14
    legend = QgsLayoutItemLegend(layout)
    legend.setTitle("Legend")
    legend.setLinkedMap(item)
    legend.setAutoUpdateModel(False)
    group = legend.model().rootGroup()
    group.removeAllChildren()
    for layer in (shade, green[0], buildings[0], roads[0], spots[0], texts, contours):
        group.addLayer(layer)
    legend.attemptMove(QgsLayoutPoint(x0, top + 50, MM))
    layout.addLayoutItem(legend)

    bar = QgsLayoutItemScaleBar(layout)
    bar.setStyle("Single Box")
    bar.setLinkedMap(item)
    bar.setUnits(QgsUnitTypes.DistanceMeters)
    bar.setNumberOfSegments(4)
    bar.setNumberOfSegmentsLeft(0)
    bar.setUnitsPerSegment(125)
    bar.setUnitLabel("m")
    bar.attemptMove(QgsLayoutPoint(x0, top + 30, MM))
    layout.addLayoutItem(bar)

    arrow = QgsLayoutItemPicture(layout)
    arrow.setPicturePath("/usr/share/qgis/svg/arrows/NorthArrow_02.svg")
    arrow.attemptMove(QgsLayoutPoint(x0, top, MM))
    arrow.attemptResize(QgsLayoutSize(12, 20, MM))
    layout.addLayoutItem(arrow)

    title = QgsLayoutItemLabel(layout)
    title.setText("Siena block - demo sheet\nsheet: 1\nscale: 1:5000\nCRS: EPSG:3003 "
                  "(Monte Mario / Italy zone 2), ticks EPSG:6707\ncontour interval: 5 m\n"
                  "producer: QGIS 3.22 print layout")
    title.setFont(QFont("DejaVu Sans", 7))
    title.attemptMove(QgsLayoutPoint(x0, top + map_h - 40, MM))
    title.attemptResize(QgsLayoutSize(110, 40, MM))
    title.setFrameEnabled(True)
    layout.addLayoutItem(title)

    exporter = QgsLayoutExporter(layout)
    pdf = QgsLayoutExporter.PdfExportSettings()
    pdf.rasterizeWholeImage = False
    assert exporter.exportToPdf(str(out.with_suffix(".pdf")), pdf) == QgsLayoutExporter.Success
    png = QgsLayoutExporter.ImageExportSettings()
    png.dpi = 60
    assert exporter.exportToImage(str(out.with_suffix(".png")), png) == QgsLayoutExporter.Success
    app.exitQgis()


def label(layer, expression: str, colour: QColor, placement, italic: bool = False,
          buffer: bool = False) -> None:
    """6 pt labels of ``expression`` in ``colour``."""
    settings = QgsPalLayerSettings()
    settings.fieldName = expression
    settings.isExpression = True
    settings.placement = placement
    fmt = QgsTextFormat()
    font = QFont("DejaVu Sans")
    font.setItalic(italic)
    fmt.setFont(font)
    fmt.setSize(6)
    fmt.setColor(colour)
    if buffer:
        fmt.buffer().setEnabled(True)
        fmt.buffer().setSize(0.5)
        fmt.buffer().setColor(Qt.white)
    settings.setFormat(fmt)
    layer.setLabeling(QgsVectorLayerSimpleLabeling(settings))
    layer.setLabelsEnabled(True)


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
