"""Map sheets from files: the base raster read at print resolution, vector layers styled from
the code file (the shared style model) or with default styles, one sheet per extent or per
feature of a sheet layer."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from toolbox.cartography.grid import ground_step, map_grid
from toolbox.cartography.sheet import BASE_DPI, LayerStyle, SheetRenderer
from toolbox.cartography.sheet_layout import MM_PER_INCH, SheetSpec

# default styles by geometry kind, until the shared style model provides the code file's
PALETTE = {"polygon": [((120, 120, 120), (230, 220, 200)), ((40, 110, 40), (200, 230, 190)),
                       ((60, 90, 160), (200, 215, 240))],
           "line": [((200, 30, 30), None), ((40, 80, 200), None), ((30, 30, 30), None)],
           "point": [((200, 0, 120), None), ((0, 0, 0), None)]}
WIDTHS = {"polygon": 0.2, "line": 0.35, "point": 0.6}


def geometry_kind(frame) -> str:
    """"polygon", "line" or "point": the dominant geometry kind of a GeoDataFrame."""
    kinds = {t.replace("Multi", "").replace(" Z", "").lower() for t in frame.geom_type if t}
    return "polygon" if "polygon" in kinds else "line" if "linestring" in kinds else "point"


def default_styles(layers: list[tuple[str, Any]]) -> list[LayerStyle]:
    """A :class:`LayerStyle` per ``(name, GeoDataFrame)``, colours cycling by geometry kind."""
    used: dict[str, int] = {}
    out = []
    for name, frame in layers:
        kind = geometry_kind(frame)
        k = used.get(kind, 0)
        used[kind] = k + 1
        rgb, fill = PALETTE[kind][k % len(PALETTE[kind])]
        out.append(LayerStyle(frame, name.replace("_", " "), kind, rgb, WIDTHS[kind], fill))
    return out


def read_base(info, bounds: tuple[float, float, float, float], scale: float,
              dpi: int = BASE_DPI) -> tuple[np.ndarray, tuple[float, float, float, float]] | None:
    """The base raster over ``bounds`` resampled to ``dpi`` on paper (at most its own cell):
    (grey or RGB uint8 image, north up, extent xmin, xmax, ymin, ymax), or None when it does
    not overlap. A paletted raster is read as its colours (RGB). Non-byte grey rasters are
    stretched between the 2nd and 98th percentiles of their valid values (NaN is no value,
    with or without a nodata tag). A north-up raster is
    read by a decimated window read (GDAL's overviews); one stored south-up, east to west or
    rotated is warped onto a north-up grid (GDAL's warper)."""
    import math

    import rasterio
    from affine import Affine
    from rasterio.enums import Resampling
    from rasterio.windows import from_bounds

    from toolbox.io.raster import dataset_transform, read_dataset_masked
    from toolbox.raster.warp import photo_path

    with rasterio.open(photo_path(info.path)) as src:  # a paletted base: its colours
        t = dataset_transform(src)
        corners = [t * (c, r) for c in (0, src.width) for r in (0, src.height)]
        xs, ys = [x for x, _ in corners], [y for _, y in corners]
        xmin, ymin = max(bounds[0], min(xs)), max(bounds[1], min(ys))
        xmax, ymax = min(bounds[2], max(xs)), min(bounds[3], max(ys))
        if xmin >= xmax or ymin >= ymax:
            return None
        cell = math.sqrt(abs(t.a * t.e - t.b * t.d))
        px_w = max(min(int((xmax - xmin) / scale * 1000 / MM_PER_INCH * dpi),
                       math.ceil((xmax - xmin) / cell)), 1)
        px_h = max(min(int((ymax - ymin) / scale * 1000 / MM_PER_INCH * dpi),
                       math.ceil((ymax - ymin) / cell)), 1)
        bands = [1, 2, 3] if src.count >= 3 else [1]
        byte = src.dtypes[0] == "uint8"
        if t.b == 0 and t.d == 0 and t.a > 0 and t.e < 0:  # north-up: a decimated read
            win = from_bounds(xmin, ymin, xmax, ymax, t).round_offsets().round_lengths()
            win = win.intersection(rasterio.windows.Window(0, 0, src.width, src.height))
            px_w, px_h = min(px_w, int(win.width)), min(px_h, int(win.height))
            data = read_dataset_masked(src, bands, win, (px_h, px_w), Resampling.bilinear)
            wl, wb, wr, wt = rasterio.windows.bounds(win, t)
        else:
            from toolbox.raster.reproject import read_onto

            grid = Affine((xmax - xmin) / px_w, 0, xmin, 0, -(ymax - ymin) / px_h, ymax)
            data = read_onto(src, grid, px_w, px_h, None, indexes=bands,
                             resampling="bilinear", dtype="float64")
            wl, wb, wr, wt = xmin, ymin, xmax, ymax
        data = np.ma.masked_invalid(data)  # NaN without a nodata tag is no value either
        if byte:
            data = np.ma.clip(np.ma.round(data), 0, 255)
        else:
            valid = data.compressed()
            lo, hi = np.percentile(valid, [2, 98]) if valid.size else (0, 1)
            data = np.clip((data.astype("float64") - lo) / max(hi - lo, 1e-12) * 255, 0, 255)
        image = np.ma.filled(data, 255).astype("uint8")
    image = image[0] if len(bands) == 1 else np.moveaxis(image, 0, -1)
    return image, (wl, wr, wb, wt)


def render_sheet(spec: SheetSpec, base=None, base_name: str = "", styles=(), contours=None,
                 grid_style: str = "crosses", map_step_mm: float = 100.0,
                 pdfs: list[str | Path] = (), pngs: list[str | Path] = (), png_dpi: int = 150,
                 pdf_pages=None, second_grid=None, index=None) -> dict:
    """Draw one sheet and save it (PDF files, PNG files, and/or a page of an open
    ``PdfPages``). ``second_grid``: (pyproj Transformer sheet CRS -> second CRS, its label)
    whose grid is ticked along the frame; ``index``: (sheet index GeoDataFrame, number field,
    this sheet's polygon) drawn as the panel's small index map. Returns the page geometry."""
    if index is not None:  # the title block names the sheet's number in the index
        from toolbox.cartography.index_map import index_number

        spec.index_number = index_number(*index)
    renderer = SheetRenderer(spec)
    try:
        if base is not None:
            image = read_base(base, spec.bounds, spec.scale)
            if image is not None:
                renderer.base(*image, base_name or "base")
        for style in styles:
            clipped = style.frame.cx[spec.bounds[0]:spec.bounds[2], spec.bounds[1]:spec.bounds[3]]
            if len(clipped):
                renderer.vector(LayerStyle(clipped, style.name, style.kind, style.rgb,
                                           style.width_mm, style.fill, style.label_field,
                                           style.symbol))
        if contours is not None and len(contours):
            renderer.contours(contours.cx[spec.bounds[0]:spec.bounds[2],
                                          spec.bounds[1]:spec.bounds[3]])
        left_out = renderer.place_labels()
        step = ground_step(spec.scale, map_step_mm)
        renderer.grid(map_grid(spec.bounds, step, grid_style, ground_step(spec.scale, 10) / 2))
        if second_grid is not None:
            renderer.second_grid(second_grid[0], second_grid[1], step)
        bar = renderer.panel()
        shown = None
        if index is not None:
            from toolbox.cartography.index_map import draw_index_map

            shown = draw_index_map(renderer, *index)
        metadata = {"Title": f"{spec.title} {spec.sheet_id}".strip(),
                    "Subject": f"map sheet {spec.sheet_id} at 1:{spec.scale:g}, {spec.crs_label}",
                    "Keywords": f"scale=1:{spec.scale:g}; crs={spec.crs_label}; "
                                f"bounds={','.join(f'{v:.3f}' for v in spec.bounds)}",
                    "Creator": "photogrammetry-toolbox carto:sheet"}
        renderer.save(pdfs, pngs, png_dpi, metadata, pdf_pages)
        page = renderer.page
        return {"sheet": spec.sheet_id, "paper": page.paper, "paper_mm": [page.width, page.height],
                "frame_mm": list(page.frame), "scale_bar": bar, "labels_left_out": left_out,
                "index_map": shown,
                "panel_mm": [page.panel_left, page.band_bottom, page.panel_width,
                             page.band_height]}
    finally:
        renderer.close()


def styles_from_model(frame, layer_style, with_code: bool = False) -> list[LayerStyle]:
    """Sheet styles of a layer from the shared style model (a ``toolbox.styles.LayerStyle``:
    ``name``, ``kind``, ``styles`` (per code: ``code``, ``rgb``, ``line_width`` mm, ``fill``
    RGBA, ``label``), ``field``, ``label_field``); duck-typed, so this module does not depend
    on it. One :class:`LayerStyle` per code, with that code's features and its label as the
    legend name (``"<code> <label>"`` with ``with_code``); a single-symbol layer gives one."""
    out = []
    many = len(layer_style.styles) > 1 and layer_style.field in frame.columns
    for code in layer_style.styles:
        part = frame[frame[layer_style.field].astype(str) == str(code.code)] if many else frame
        name = code.label or code.code
        if with_code and name != code.code:
            name = f"{code.code} {name}"
        out.append(LayerStyle(part, name, code.kind, tuple(code.rgb),
                              code.line_width, code.fill, layer_style.label_field))
    return out


def coded_styles(layers: list[tuple[str, Any]], table, colours) -> list[LayerStyle]:
    """Sheet styles of ``(layer name, GeoDataFrame)`` pairs from the code file ``table`` (a
    :class:`toolbox.io.code_file.CodeTable`) and ``colours``, through the shared style
    model: a layer with a ``code`` field is categorised by the codes it holds (in the code
    file's order; unknown codes grey, features without a code in a default style), a layer
    named after a code (one layer per code, as ``attribution:apply`` writes) gets that code's
    style, any other layer a default style.
    Legend entries read ``<code> <description>``; features are not labelled (the legend
    explains the codes)."""
    from toolbox.styles.model import layer_style

    order = {code: i for i, code in enumerate(table.entries)}
    out: list[LayerStyle] = []
    for name, frame in layers:
        kind = geometry_kind(frame)
        if "code" in frame.columns:
            coded = frame["code"].notna() & (frame["code"].astype(str).str.strip() != "")
            codes = sorted({str(c) for c in frame["code"][coded]},
                           key=lambda c: (order.get(c, len(order)), c))
            if not coded.all():  # features without a code keep a default style
                out += default_styles([(f"{name}: no code", frame[~coded])])
            frame = frame[coded]
        elif name in table:
            codes = [name]
        else:
            out += default_styles([(name, frame)])
            continue
        model = layer_style(name, kind, codes, table, colours, label_field=None)
        out += _with_symbology(styles_from_model(frame, model, with_code=True), codes, table,
                               colours)
    return out


def _with_symbology(styles: list[LayerStyle], codes: list[str], table, colours
                    ) -> list[LayerStyle]:
    """The code file's symbology (line type, width, point symbol, hatching; see
    :mod:`.symbols`) on each code's style, and its legend name under the delivered code, when
    the code file has symbology columns; else the styles as they are."""
    from dataclasses import replace

    from toolbox.styles.symbology import code_symbol, has_symbology

    if not has_symbology(table):
        return styles
    out = []
    for style, code in zip(styles, codes, strict=True):
        if code not in table:
            out.append(style)
            continue
        symbol, name, lead = code_symbol(code, style.kind, table)
        out.append(replace(style, symbol=symbol, width_mm=symbol.width, name=name,
                           rgb=_code_rgb(lead, table, colours) or style.rgb))
    return out


def _code_rgb(code: str, table, colours):
    from toolbox.io.code_file import code_colour

    return code_colour(code, table, colours)[0]
