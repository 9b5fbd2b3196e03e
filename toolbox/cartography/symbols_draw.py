"""Drawing a code's :class:`~toolbox.cartography.symbols.Symbol` with matplotlib, on any axes
whose data units are ground metres at 1:``scale`` (the map frame, or a legend swatch laid out
at the same scale, so the legend shows exactly what the map draws)."""

from __future__ import annotations

import numpy as np

from toolbox.cartography.symbols import DASHES, SCARP_TICK_MM, Symbol, hatch_lines, scarp_ticks
from toolbox.styles.symbology import HATCH_WIDTH_MM

PT_PER_MM = 72.0 / 25.4
SOLID_ALPHA = 96 / 255  # as the QGIS styles fill areas (toolbox.styles.model.FILL_ALPHA)
TEXT_MIN_PT = 6.0


def _parts(geoms, kind: str) -> list:
    import shapely

    out = []
    for g in geoms:
        if g is None or g.is_empty:
            continue
        for p in shapely.get_parts(shapely.force_2d(g)):
            if kind == "line" and p.geom_type == "Polygon":
                out += [p.exterior, *p.interiors]
            else:
                out.append(p)
    return out


def _linestyle(symbol: Symbol):
    if symbol.linetype not in DASHES:
        return "solid"
    # matplotlib scales dash lengths by the line width: divide it out (pattern in paper mm)
    return (0, tuple(v / symbol.width for v in DASHES[symbol.linetype]))


def _tree_marker():
    from matplotlib.path import Path

    crown = Path.circle((0.0, 0.25), 0.5)
    stem = Path([(0.0, -0.25), (0.0, -0.75)], [Path.MOVETO, Path.LINETO])
    return Path.make_compound_path(crown, stem)


MARKERS = {"dot": ("o", True), "circle": ("o", False), "cross": ("+", False),
           "triangle": ("^", False), "square": ("s", False)}


def draw_symbol(ax, geoms, kind: str, rgb: tuple[int, int, int], symbol: Symbol, scale: float,
                zorder: float = 3.0) -> None:
    """Draw ``geoms`` (shapely geometries, ground units) of ``kind`` point/line/polygon in
    colour ``rgb`` (0-255) with ``symbol`` at 1:``scale``."""
    import shapely
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path

    colour = tuple(v / 255 for v in rgb)
    ground_per_mm = scale / 1000.0
    lw = symbol.width * PT_PER_MM
    if kind == "point":
        pts = [p for p in _parts(geoms, "point") if p.geom_type == "Point"]
        if not pts:
            return
        xy = np.array([(p.x, p.y) for p in pts])
        size = symbol.size * PT_PER_MM
        if symbol.symbol == "tree":
            ax.plot(xy[:, 0], xy[:, 1], linestyle="none", marker=_tree_marker(), markersize=size,
                    markerfacecolor="none", markeredgecolor=colour,
                    markeredgewidth=symbol.width * PT_PER_MM, zorder=zorder)
            return
        marker, filled = MARKERS[symbol.symbol]
        ax.plot(xy[:, 0], xy[:, 1], linestyle="none", marker=marker, markersize=size,
                markerfacecolor=colour if filled else "none", markeredgecolor=colour,
                markeredgewidth=0 if filled else symbol.width * PT_PER_MM, zorder=zorder)
        return
    if kind == "polygon":
        polys = [p for p in _parts(geoms, "polygon") if p.geom_type == "Polygon"]
        if symbol.hatch == "solid":
            patches = [PathPatch(Path.make_compound_path(
                *[Path(np.asarray(r.coords)[:, :2]) for r in (p.exterior, *p.interiors)]))
                for p in polys]
            ax.add_collection(PatchCollection(patches, facecolor=(*colour, SOLID_ALPHA),
                                              edgecolor="none", zorder=zorder - 0.2))
        elif isinstance(symbol.hatch, tuple):
            angle, spacing = symbol.hatch
            segs = [np.asarray(line.coords)[:, :2] for p in polys
                    for line in shapely.get_parts(hatch_lines(p, angle, spacing * ground_per_mm))
                    if line.geom_type == "LineString" and not line.is_empty]
            ax.add_collection(LineCollection(segs, colors=[colour], zorder=zorder - 0.1,
                                             linewidths=HATCH_WIDTH_MM * PT_PER_MM,
                                             gid="hatch"))
        lines = [r for p in polys for r in (p.exterior, *p.interiors)]
    else:
        lines = [p for p in _parts(geoms, "line") if p.geom_type in ("LineString", "LinearRing")]
    segs = [np.asarray(line.coords)[:, :2] for line in lines]
    if segs:
        ax.add_collection(LineCollection(segs, colors=[colour], linewidths=lw,
                                         linestyles=[_linestyle(symbol)], zorder=zorder))
    if symbol.linetype == "scarp":
        spacing, length = (v * ground_per_mm for v in SCARP_TICK_MM)
        ticks = [t for line in lines for t in scarp_ticks(shapely.LineString(line.coords),
                                                          spacing, length)]
        if ticks:
            ax.add_collection(LineCollection(ticks, colors=[colour], linewidths=lw * 0.7,
                                             zorder=zorder, gid="scarp"))


def draw_texts(ax, frame, rgb: tuple[int, int, int], scale: float, clip: bool = True) -> list:
    """The restitution's texts (a ``text`` field; ``text_height`` in ground metres and
    ``rotation`` in degrees if given) at their points, never under 6 pt; returns the text
    artists."""
    colour = tuple(v / 255 for v in rgb)
    placed = []
    for k, (geom, text) in enumerate(zip(frame.geometry, frame["text"])):
        if geom is None or geom.is_empty or text is None or not str(text).strip():
            continue
        height = frame["text_height"].iloc[k] if "text_height" in frame else None
        size = TEXT_MIN_PT
        if height is not None and np.isfinite(float(height)) and float(height) > 0:
            size = max(TEXT_MIN_PT, float(height) / scale * 1000.0 * PT_PER_MM)
        rotation = frame["rotation"].iloc[k] if "rotation" in frame else 0.0
        rotation = float(rotation) if rotation is not None and np.isfinite(float(rotation)) \
            else 0.0
        p = geom.representative_point()
        placed.append(ax.text(p.x, p.y, str(text), fontsize=size, color=colour,
                              rotation=rotation, rotation_mode="anchor", ha="left",
                              va="baseline", fontstyle="italic", zorder=6, clip_on=clip))
    return placed


def swatch_geometry(kind: str, width_mm: float, height_mm: float, scale: float):
    """A sample geometry filling a legend swatch of ``width_mm`` x ``height_mm`` (ground units
    at 1:``scale``, origin at the swatch's lower left)."""
    import shapely

    g = scale / 1000.0
    if kind == "point":
        return shapely.Point(width_mm / 2 * g, height_mm / 2 * g)
    if kind == "polygon":
        return shapely.box(0.5 * g, 0.3 * g, (width_mm - 0.5) * g, (height_mm - 0.3) * g)
    # a scarp's ticks fall on the left: the line runs right to left near the swatch's top
    return shapely.LineString([(0.5 * g, height_mm / 2 * g), ((width_mm - 0.5) * g,
                                                              height_mm / 2 * g)])
