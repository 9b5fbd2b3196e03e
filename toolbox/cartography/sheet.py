"""Map sheet rendering with matplotlib: a map frame at an exact scale on an ISO paper sheet,
with a raster base (orthophoto or hillshade), styled vector layers, contours with labels along
them, the map grid with coordinates, a legend, a scale bar, a north arrow and a title block.

Page geometry is in millimetres from the sheet's lower-left corner; the map frame is
``ground size / scale`` exactly, so the printed sheet measures true (print at 100%, no "fit to
page"). PDF output is vector (lines, text as TrueType text); the base raster is embedded at
``BASE_DPI``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from toolbox.cartography.qml import CONTOUR_RGB, INDEX_WIDTH_MM, WIDTH_MM
from toolbox.cartography.sheet_layout import (
    MM_PER_INCH,
    PANEL_MAX,
    PT_PER_MM,
    SheetSpec,
    layout_page,
    nice_length,
)

BASE_DPI = 200
MIN_TEXT_PT = 6.0  # no text smaller at print size
SHADING_STRENGTH = 0.45  # a grey base (hillshade) keeps this share of its darkness
CORNER_CLEAR = 8.0  # mm along the frame edge kept free of grid labels at each corner
LABEL_PAD_MM = 0.3  # spot-height labels keep this far from other texts
HEIGHT_FIELDS = ("z", "quota", "elev", "height", "h")  # spot-height value fields, in this order


@dataclass
class LayerStyle:
    """How one vector layer is drawn and listed in the legend (the renderer-neutral style
    model's fields): geometry kind ``point``/``line``/``polygon``, RGB 0-255, line width and
    point size in mm, optional fill RGB or RGBA, optional label field. A layer categorised by
    code is several LayerStyles, one per code, each with its features and its legend name."""

    frame: Any  # GeoDataFrame
    name: str
    kind: str
    rgb: tuple[int, int, int] = (0, 0, 0)
    width_mm: float = 0.25
    fill: tuple[int, ...] | None = None
    label_field: str | None = None
    symbol: Any = None  # a toolbox.cartography.symbols.Symbol: the code file's symbology


def _hex(rgb) -> str:
    r, g, b = (int(v) for v in rgb[:3])
    return f"#{r:02x}{g:02x}{b:02x}"


class SheetRenderer:
    """Draws one sheet on a matplotlib figure sized to the paper."""

    def __init__(self, spec: SheetSpec):
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        self.plt = plt
        self.spec = spec
        self.page = layout_page(spec)
        w, h = self.page.width, self.page.height
        self.fig = plt.figure(figsize=(w / MM_PER_INCH, h / MM_PER_INCH))
        left, bottom, fw, fh = self.page.frame
        self.ax = self.fig.add_axes((left / w, bottom / h, fw / w, fh / h))
        xmin, ymin, xmax, ymax = spec.bounds
        self.ax.set_xlim(xmin, xmax)
        self.ax.set_ylim(ymin, ymax)
        self.ax.set_xticks([])
        self.ax.set_yticks([])
        for spine in self.ax.spines.values():
            spine.set_linewidth(0.5 * PT_PER_MM)
        self.legend: list[tuple[str, str, str, float, str | None]] = []  # kind, name, ...
        self.obstacles: list = []  # text artists already placed (texts, contour labels)
        self.pending: list[tuple[float, float, str, str]] = []  # spot heights: x, y, text, colour
        self.labels_left_out = 0

    # -- page coordinates (mm) -> figure fraction
    def _fx(self, x_mm: float) -> float:
        return x_mm / self.page.width

    def _fy(self, y_mm: float) -> float:
        return y_mm / self.page.height

    def _mm_to_ground(self, mm: float) -> float:
        return mm * self.spec.scale / 1000.0

    def base(self, image: np.ndarray, extent: tuple[float, float, float, float],
             name: str) -> None:
        """Raster base: ``image`` (rows, cols) grey or (rows, cols, 3) RGB, ``extent`` (xmin,
        xmax, ymin, ymax) of its outer cell edges."""
        cmap = "gray" if image.ndim == 2 else None
        if image.ndim == 2:  # relief shading is printed light under the linework
            image = 255 - SHADING_STRENGTH * (255 - image.astype("float32"))
        self.ax.imshow(image, extent=extent, cmap=cmap, interpolation="bilinear",
                       origin="upper", zorder=0, vmin=0, vmax=255)
        self.ax.set_xlim(self.spec.bounds[0], self.spec.bounds[2])
        self.ax.set_ylim(self.spec.bounds[1], self.spec.bounds[3])
        what = "relief shading" if image.ndim == 2 else "orthophoto"
        self.legend.append(("raster", f"{what} ({name})", "#bbbbbb" if image.ndim == 2
                            else "#7d8c6a", 0.0, None))

    def vector(self, style: LayerStyle) -> None:
        frame = style.frame
        colour = _hex(style.rgb)
        lw = style.width_mm * PT_PER_MM
        if "text" in frame.columns:  # the restitution's texts (toponyms), as plotted
            from toolbox.cartography.symbols_draw import draw_texts

            placed = draw_texts(self.ax, frame, style.rgb, self.spec.scale)
            self.obstacles += placed
            if placed:
                entry = ("text", style.name, colour, 0.0, None)
                if entry not in self.legend:
                    self.legend.append(entry)
            self._restore_limits()
            return
        if style.symbol is not None:  # the code file's symbology (toolbox.cartography.symbols)
            from toolbox.cartography.symbols_draw import draw_symbol

            draw_symbol(self.ax, frame.geometry.values, style.kind, style.rgb, style.symbol,
                        self.spec.scale, zorder={"polygon": 2, "line": 3}.get(style.kind, 4))
        elif style.kind == "polygon":
            face = tuple(v / 255 for v in style.fill) if style.fill is not None else "none"
            frame.plot(ax=self.ax, facecolor=face, edgecolor=colour, linewidth=lw, zorder=2)
        elif style.kind == "line":
            frame.plot(ax=self.ax, color=colour, linewidth=lw, zorder=3)
        else:
            frame.plot(ax=self.ax, color=colour, markersize=(style.width_mm * 4 * PT_PER_MM),
                       zorder=4)
        if style.label_field and style.label_field in frame.columns:
            for geom, text in zip(frame.geometry, frame[style.label_field]):
                p = geom.representative_point()
                self.ax.text(p.x, p.y, str(text), fontsize=MIN_TEXT_PT, color=colour,
                             ha="center", va="center", zorder=6, clip_on=True)
        elif style.kind == "point" and (style.symbol is None or style.symbol.symbol == "dot"):
            self.spot_heights(frame, colour)  # a dot is a spot height: its value beside it
        if style.symbol is not None:
            from dataclasses import replace

            # one legend entry per delivered code and look, whichever working code drew it
            entry = ("symbol", style.name, colour, style.width_mm,
                     (style.kind, replace(style.symbol, code=style.symbol.delivered)))
        else:
            entry = (style.kind, style.name, colour, style.width_mm,
                     tuple(v / 255 for v in style.fill) if style.fill is not None else None)
        if entry not in self.legend:  # one code drawn from two layers: listed once
            self.legend.append(entry)
        self._restore_limits()

    def spot_heights(self, frame, colour: str) -> None:
        """Each point's height beside it (the Z of the geometry, else a height field), one
        decimal: spot heights carry their value on a map."""
        import shapely

        lower = {c.lower(): c for c in frame.columns}
        field = next((lower[f] for f in HEIGHT_FIELDS if f in lower), None)
        coords, owner = shapely.get_coordinates(frame.geometry.values, include_z=True,
                                                return_index=True)
        use_z = len(coords) > 0 and bool(np.isfinite(coords[:, 2]).all())
        if not use_z and field is None:
            return
        first = np.unique(owner, return_index=True)  # each geometry's first point
        for k, i in zip(*first, strict=True):
            p = coords[i]
            value = p[2] if use_z else frame[field].iloc[k]
            if value is None or not np.isfinite(float(value)):
                continue
            self.pending.append((float(p[0]), float(p[1]), f"{float(value):.1f}", colour))

    def place_labels(self) -> int:
        """Spot-height labels where they come no nearer than 0.3 mm to a text already on the
        map: right of the point, else left, above, below (1 mm off); a label with no free
        place is left out (counted, never printed over another). Returns the number left out."""
        renderer = self.fig.canvas.get_renderer()
        pad = LABEL_PAD_MM / MM_PER_INCH * self.fig.dpi  # display units
        boxes = _BoxIndex(20.0 / MM_PER_INCH * self.fig.dpi)
        for a in self.obstacles:
            boxes.add(a.get_window_extent(renderer).padded(pad))
        off = self._mm_to_ground(1.0)
        xmin, ymin, xmax, ymax = self.spec.bounds
        for x, y, text, colour in self.pending:
            if not (xmin <= x <= xmax and ymin <= y <= ymax):
                continue
            for dx, dy, ha, va in ((off, 0, "left", "center"), (-off, 0, "right", "center"),
                                   (0, off, "center", "bottom"), (0, -off, "center", "top")):
                artist = self.ax.text(x + dx, y + dy, text, fontsize=MIN_TEXT_PT, color=colour,
                                      ha=ha, va=va, zorder=6, clip_on=True)
                box = artist.get_window_extent(renderer).padded(pad)
                if not boxes.hits(box):
                    boxes.add(box)
                    break
                artist.remove()
            else:
                self.labels_left_out += 1
        self.pending = []
        return self.labels_left_out

    def _restore_limits(self) -> None:
        self.ax.set_xlim(self.spec.bounds[0], self.spec.bounds[2])
        self.ax.set_ylim(self.spec.bounds[1], self.spec.bounds[3])
        self.ax.set_aspect("auto")
        self.ax.set_xlabel("")
        self.ax.set_ylabel("")

    def contours(self, frame, rgb=CONTOUR_RGB, width_mm=WIDTH_MM, index_width_mm=INDEX_WIDTH_MM,
                 label_every_mm: float = 120.0) -> None:
        """Contours (LineString with ``elev`` and ``index``); index contours heavier and
        labelled along the line every ``label_every_mm`` of paper, text upright. Colour and
        widths default to those of the contour layer's QGIS/SLD style (:mod:`.qml`)."""
        import matplotlib.patheffects as pe
        import shapely
        from matplotlib.collections import LineCollection

        colour = _hex(rgb)
        index = np.asarray(frame["index"] == 1) if "index" in frame else np.zeros(len(frame),
                                                                                  bool)
        clip = shapely.box(*self.spec.bounds)
        for flag, lw in ((False, width_mm), (True, index_width_mm)):
            segs = [shapely.get_coordinates(p) for g in frame.geometry.values[index == flag]
                    for p in shapely.get_parts(g)]
            self.ax.add_collection(LineCollection(segs, colors=colour,
                                                  linewidths=lw * PT_PER_MM, zorder=2.5))
        spacing = self._mm_to_ground(label_every_mm)
        halo = [pe.withStroke(linewidth=2.0, foreground="white")]
        for geom, elev in zip(frame.geometry.values[index], frame["elev"].values[index]):
            geom = shapely.intersection(shapely.force_2d(geom), clip)
            for part in shapely.get_parts(geom):
                if part.geom_type != "LineString" or part.length < spacing / 3:
                    continue
                for d in np.arange(min(spacing / 2, part.length / 2), part.length, spacing):
                    a = part.interpolate(max(d - 1.0, 0.0))
                    b = part.interpolate(min(d + 1.0, part.length))
                    angle = np.degrees(np.arctan2(b.y - a.y, b.x - a.x))
                    angle = (angle + 90.0) % 180.0 - 90.0  # upright text
                    p = part.interpolate(d)
                    self.obstacles.append(self.ax.text(
                        p.x, p.y, f"{elev:.0f}", fontsize=MIN_TEXT_PT, color=colour,
                        rotation=angle, rotation_mode="anchor", ha="center", va="center",
                        zorder=5, path_effects=halo, clip_on=True))
        levels = np.unique(np.round(np.asarray(frame["elev"], dtype="float64"), 6))
        steps = np.diff(levels)
        interval = float(steps[steps > 0].min()) if (steps > 0).any() else None
        if interval is not None and self.spec.contour_interval is None:
            self.spec.contour_interval = interval
        every = ""
        if interval is not None and index.any():
            index_levels = np.unique(np.asarray(frame["elev"])[index])
            gaps = np.diff(index_levels)
            every = f", every {gaps.min():g} m" if len(gaps) else ""
        self.legend.append(("line", "contour" + (f", interval {interval:g} m"
                                                  if interval else ""), colour, width_mm, None))
        self.legend.append(("line", "index contour" + every, colour, index_width_mm, None))
        self._restore_limits()

    def grid(self, grid) -> None:
        """The map grid (:class:`~toolbox.cartography.grid.MapGrid`) and its labels outside
        the frame."""
        import shapely
        from matplotlib.collections import LineCollection

        segs = [shapely.get_coordinates(p) for g in grid.geometries for p in shapely.get_parts(g)
                if not p.is_empty]
        self.ax.add_collection(LineCollection(segs, colors="#000000",
                                              linewidths=0.25 * PT_PER_MM, zorder=7))
        xmin, ymin, xmax, ymax = self.spec.bounds
        off = self._mm_to_ground(1.5)
        clear = self._mm_to_ground(CORNER_CLEAR)
        for label in grid.labels:
            x, y, edge = label["x"], label["y"], label["edge"]
            along = x if edge in ("bottom", "top") else y
            lo, hi = (xmin, xmax) if edge in ("bottom", "top") else (ymin, ymax)
            if min(along - lo, hi - along) < clear:  # two edges' labels would collide here
                continue
            kw = dict(fontsize=MIN_TEXT_PT, clip_on=False, zorder=8)
            if edge == "bottom":
                self.ax.text(x, ymin - off, label["text"], ha="center", va="top", **kw)
            elif edge == "top":
                self.ax.text(x, ymax + off, label["text"], ha="center", va="bottom", **kw)
            elif edge == "left":
                self.ax.text(xmin - off, y, label["text"], ha="right", va="center",
                             rotation=90, rotation_mode="anchor", **kw)
            else:
                self.ax.text(xmax + off, y, label["text"], ha="left", va="center",
                             rotation=90, rotation_mode="anchor", **kw)
        self.legend.append(("cross", f"map grid, {grid.step:g} m", "#000000", 0.25, None))
        self._restore_limits()

    def second_grid(self, transformer, label: str, step: float, colour: str = "#1f4fbf"
                    ) -> int:
        """Ticks and labels of a second CRS's grid every ``step`` (its units) along the frame,
        outside the first CRS's labels (``transformer``: sheet CRS -> second CRS, pyproj,
        always_xy). A tick marks where the second CRS's line x = k * step (bottom, top edges)
        or y = k * step (left, right edges) crosses the frame. Returns the ticks drawn."""
        from matplotlib.collections import LineCollection

        xmin, ymin, xmax, ymax = self.spec.bounds
        clear = self._mm_to_ground(CORNER_CLEAR)
        tick, off = self._mm_to_ground(3.9), self._mm_to_ground(4.2)
        t = np.linspace(0.0, 1.0, 2001)
        edges = {"bottom": (xmin + t * (xmax - xmin), np.full_like(t, ymin), 0),
                 "top": (xmin + t * (xmax - xmin), np.full_like(t, ymax), 0),
                 "left": (np.full_like(t, xmin), ymin + t * (ymax - ymin), 1),
                 "right": (np.full_like(t, xmax), ymin + t * (ymax - ymin), 1)}
        segs = []
        kw = dict(fontsize=MIN_TEXT_PT, clip_on=False, zorder=8, color=colour)
        for edge, (ex, ey, axis) in edges.items():
            values = np.asarray(transformer.transform(ex, ey)[axis])
            along = ex if axis == 0 else ey
            for v in np.arange(np.ceil(values.min() / step), np.floor(values.max() / step) + 1):
                if not (np.all(np.diff(values) > 0) or np.all(np.diff(values) < 0)):
                    break  # not monotonic along the edge: no single crossing
                order = np.argsort(values)
                a = float(np.interp(v * step, values[order], along[order]))
                if min(a - along[0], along[-1] - a) < clear:
                    continue
                text = f"{v * step:.0f}"
                if edge == "bottom":
                    segs.append([(a, ymin), (a, ymin - tick)])
                    self.ax.text(a, ymin - off, text, ha="center", va="top", **kw)
                elif edge == "top":
                    segs.append([(a, ymax), (a, ymax + tick)])
                    self.ax.text(a, ymax + off, text, ha="center", va="bottom", **kw)
                elif edge == "left":
                    segs.append([(xmin, a), (xmin - tick, a)])
                    self.ax.text(xmin - off, a, text, ha="right", va="center", rotation=90,
                                 rotation_mode="anchor", **kw)
                else:
                    segs.append([(xmax, a), (xmax + tick, a)])
                    self.ax.text(xmax + off, a, text, ha="left", va="center", rotation=90,
                                 rotation_mode="anchor", **kw)
        self.ax.add_collection(LineCollection(segs, colors=colour, clip_on=False, zorder=8,
                                              linewidths=0.2 * PT_PER_MM))
        self.legend.append(("tick", f"{label} grid ticks, {step:g} m (outer labels)", colour,
                            0.2, None))
        self._restore_limits()
        return len(segs)

    # -- side panel ------------------------------------------------------------------------------
    def title_rows(self) -> list[tuple[str, str]]:
        """The title block: (key, value) rows; an empty key is the title."""
        spec = self.spec
        rows = [("", spec.title), ("sheet", spec.sheet_id), ("scale", f"1:{spec.scale:g}"),
                ("CRS", spec.crs_label)]
        if spec.index_number and spec.index_number != spec.sheet_id:
            rows.insert(2, ("in sheet index", spec.index_number))
        if spec.datum:
            rows.append(("datum", spec.datum))
        if spec.second_crs:
            rows.append(("outer ticks", spec.second_crs))
        if spec.contour_interval:
            rows.append(("contour interval", f"{spec.contour_interval:g} m"))
        rows += [("date", spec.date), ("sources", "; ".join(spec.sources))]
        if spec.producer:
            rows.append(("producer", spec.producer))
        if spec.credits:
            rows.append(("", spec.credits))
        return rows

    def panel(self) -> dict:
        """North arrow, scale bar and legend from the top of the panel, the title block at its
        foot; the panel spans the map's band. Returns the scale bar's geometry (ground length,
        paper length in mm, left end in mm)."""
        import textwrap

        from matplotlib.lines import Line2D
        from matplotlib.patches import Polygon, Rectangle

        fig = self.fig
        x0 = self.page.panel_left
        width = self.page.panel_width
        bottom = self.page.band_bottom
        top = bottom + self.page.band_height
        text = dict(transform=fig.transFigure, fontsize=7, va="center")
        # north arrow (grid north: projected CRSs are drawn north-up)
        cx, cy = x0 + 10.0, top - 12.0
        fig.patches.append(Polygon([(self._fx(cx), self._fy(cy + 9)),
                                    (self._fx(cx - 4), self._fy(cy - 6)),
                                    (self._fx(cx), self._fy(cy - 2)),
                                    (self._fx(cx + 4), self._fy(cy - 6))], closed=True,
                                   transform=fig.transFigure, facecolor="black"))
        fig.text(self._fx(cx), self._fy(cy + 12), "N", ha="center", transform=fig.transFigure,
                 fontsize=10, fontweight="bold", va="center")
        # scale bar: a nice ground length no longer than the panel
        ground = nice_length(self._mm_to_ground(min(width, PANEL_MAX) - 20.0))
        bar_mm = ground / self.spec.scale * 1000.0
        bx, by = x0 + 4.0, top - 34.0
        parts = 4 if ground / 4 >= 1 else 2
        for k in range(parts):
            fig.patches.append(Rectangle(
                (self._fx(bx + k * bar_mm / parts), self._fy(by)),
                (bar_mm / parts) / self.page.width, 2.0 / self.page.height,
                transform=fig.transFigure, facecolor="black" if k % 2 == 0 else "white",
                edgecolor="black", linewidth=0.3 * PT_PER_MM))
        for k in (0, parts):
            value = ground * k / parts
            # labels start at their tick, so the file's text positions measure the bar
            fig.text(self._fx(bx + k * bar_mm / parts), self._fy(by - 2.5),
                     f"{value:.0f} m" if k else "0", ha="left", va="top",
                     transform=fig.transFigure, fontsize=MIN_TEXT_PT)
        fig.text(self._fx(bx), self._fy(by + 6.0), f"Scale 1:{self.spec.scale:,.0f}"
                 .replace(",", " "), transform=fig.transFigure, fontsize=8, va="center")
        # title block, wrapped to the panel (never cut), then the legend above it
        chars = int((width - 4.0) / (0.55 * 6.5 / PT_PER_MM))
        lines: list[tuple[str, bool]] = []
        for key, value in self.title_rows():
            if not key:
                lines += [(t, True) for t in textwrap.wrap(str(value), int(chars * 0.8),
                                                            break_on_hyphens=False) or [""]]
            else:
                lines += [(t, False) for t in textwrap.wrap(f"{key}: {value}", chars,
                                                             subsequent_indent="  ",
                                                             break_on_hyphens=False)]
        h = 5.0 * len(lines) + 3
        fig.patches.append(Rectangle((self._fx(x0), self._fy(bottom)), width / self.page.width,
                                     h / self.page.height, transform=fig.transFigure,
                                     facecolor="none", edgecolor="black",
                                     linewidth=0.4 * PT_PER_MM))
        y = bottom + h - 4.0
        for line, bold in lines:
            fig.text(self._fx(x0 + 2), self._fy(y), line, transform=fig.transFigure,
                     fontsize=8 if bold else 6.5, fontweight="bold" if bold else "normal",
                     va="center")
            y -= 5.0
        y = top - 52.0
        fig.text(self._fx(x0), self._fy(y), "Legend", fontweight="bold", **text)
        left_out = 0
        for kind, name, colour, lw, fill in self.legend:
            if y - 5.5 < bottom + h + 11.5:  # one line kept for "... more entries"
                left_out += 1
                continue
            y -= 5.5
            sx = (self._fx(x0 + 1), self._fx(x0 + 9))
            if kind in ("polygon", "raster"):  # the swatch as the map draws it: fill and edge
                fig.patches.append(Rectangle((self._fx(x0 + 1), self._fy(y - 1.5)),
                                             8.0 / self.page.width, 3.0 / self.page.height,
                                             transform=fig.transFigure,
                                             facecolor=fill if fill is not None else (
                                                 colour if kind == "raster" else "none"),
                                             edgecolor=colour, linewidth=lw * PT_PER_MM))
            elif kind == "cross":
                fig.lines.append(Line2D(sx, (self._fy(y),) * 2, transform=fig.transFigure,
                                        color=colour, linewidth=lw * PT_PER_MM))
                fig.lines.append(Line2D((self._fx(x0 + 5),) * 2,
                                        (self._fy(y - 2), self._fy(y + 2)),
                                        transform=fig.transFigure, color=colour,
                                        linewidth=lw * PT_PER_MM))
            elif kind == "symbol":  # drawn by the map's own routine, at the map's scale
                self._symbol_swatch(x0 + 1.0, y - 2.0, colour, *fill)
            elif kind == "tick":
                fig.lines.append(Line2D((self._fx(x0 + 5),) * 2, (self._fy(y - 2),
                                                                   self._fy(y + 2)),
                                        transform=fig.transFigure, color=colour,
                                        linewidth=lw * PT_PER_MM))
            elif kind == "text":
                fig.text(self._fx(x0 + 1), self._fy(y), "Aa", transform=fig.transFigure,
                         fontsize=7, fontstyle="italic", color=colour, va="center")
            elif kind == "point":
                fig.lines.append(Line2D((self._fx(x0 + 5),), (self._fy(y),), marker="o",
                                        markersize=np.sqrt(lw * 4 * PT_PER_MM),  # as drawn
                                        color=colour, markeredgewidth=0,
                                        transform=fig.transFigure))
            else:
                fig.lines.append(Line2D(sx, (self._fy(y),) * 2, transform=fig.transFigure,
                                        color=colour, linewidth=max(lw, 0.1) * PT_PER_MM))
            fig.text(self._fx(x0 + 12), self._fy(y), _fit(name, int(chars * 1.1)), **text)
        if left_out:  # said, not hidden
            fig.text(self._fx(x0 + 12), self._fy(y - 5.5), f"... and {left_out} more entries",
                     **text)
        return {"ground_length": ground, "paper_mm": bar_mm, "left_mm": bx}

    def _symbol_swatch(self, left_mm: float, bottom_mm: float, colour: str, kind: str,
                       symbol) -> None:
        """A legend swatch 8 x 4 mm drawn by the map's routine at the map's scale."""
        from toolbox.cartography.symbols_draw import draw_symbol, swatch_geometry

        w_mm, h_mm = 8.0, 4.0
        ax = self.fig.add_axes((self._fx(left_mm), self._fy(bottom_mm), w_mm / self.page.width,
                                h_mm / self.page.height))
        g = self.spec.scale / 1000.0
        ax.set_xlim(0, w_mm * g)
        ax.set_ylim(0, h_mm * g)
        ax.set_axis_off()
        rgb = tuple(int(colour[i:i + 2], 16) for i in (1, 3, 5))
        draw_symbol(ax, [swatch_geometry(kind, w_mm, h_mm, self.spec.scale)], kind, rgb, symbol,
                    self.spec.scale)

    def save(self, pdfs=(), pngs=(), dpi: int = 150, metadata: dict | None = None,
             pdf_pages=None) -> None:
        import matplotlib

        with matplotlib.rc_context({"pdf.fonttype": 42}):  # TrueType: real, searchable text
            for pdf in pdfs:
                self.fig.savefig(pdf, format="pdf", metadata=metadata or {})
            for png in pngs:
                self.fig.savefig(png, format="png", dpi=dpi, pil_kwargs={"compress_level": 3})
            if pdf_pages is not None:
                pdf_pages.savefig(self.fig)

    def close(self) -> None:
        self.plt.close(self.fig)


class _BoxIndex:
    """Boxes (matplotlib Bbox, display units) bucketed on a square grid of ``size``: overlap
    queries look at the buckets a box covers only."""

    def __init__(self, size: float):
        self.size = size
        self.cells: dict[tuple[int, int], list] = {}

    def _keys(self, box):
        s = self.size
        for i in range(int(box.x0 // s), int(box.x1 // s) + 1):
            for j in range(int(box.y0 // s), int(box.y1 // s) + 1):
                yield i, j

    def add(self, box) -> None:
        for key in self._keys(box):
            self.cells.setdefault(key, []).append(box)

    def hits(self, box) -> bool:
        return any(box.overlaps(b) for key in self._keys(box) for b in self.cells.get(key, ()))


def _fit(text: str, n: int) -> str:
    return text if len(text) <= n else text[: n - 1] + "…"
