"""carto:sheet_index - the CTR sheet index (1:5000 elements or 1:10000 sections) of an area."""

from __future__ import annotations

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Crs, Enum, ExtentParameter, Integer, String
from toolbox.parameters.outputs import Layer, Output, OutputVector
from toolbox.registry import register


@register
class SheetIndex(Algorithm):
    """The sheets of an Italian regional technical map (CTR) covering ``EXTENT``, numbered as
    the CTRs are: the IGM 1:50000 sheet ``SHEET_50K`` (20' x 12' on ED50) is cut 4 x 4 into
    1:10000 sections (5' x 3', numbered 01-16 by rows from the north-west) and each section
    2 x 2 into 1:5000 elements (2'30" x 1'30", numbered 1-4 clockwise from the north-east):
    ``296061`` is element 1 of section 06 of sheet 296, ``296060`` the whole section.

    ``ORIGIN`` is the north-west corner of the 1:50000 sheet, ``lon,lat`` in ED50 degrees
    east of Greenwich, as printed on the IGM sheet (the toolbox holds no table of the 652
    sheets' corners). With ``NEIGHBOURS`` one more ring of sheets is written (the index map's neighbours);
    sheets outside the 1:50000 sheet have no number (their sheet's number is not derived).

    The layer ``sheets`` holds one polygon per sheet in the extent's CRS (edges are ED50
    meridians and parallels, densified), with ``name``, ``number``, ``scale``, ``sheet_50k``,
    ``section``, ``element``, ``west``/``south``/``east``/``north`` (ED50 degrees) and
    ``in_extent`` (1: the sheet meets ``EXTENT``). Give it to ``carto:sheet`` as ``SHEETS`` (with
    ``SHEET_ID number``) for one map sheet per element, and as ``INDEX`` for the small index
    map on each sheet's panel.
    """

    id = "carto:sheet_index"
    display_name = "CTR sheet index"
    group = "Cartography"
    short_help = "CTR sheet index: 1:5000 elements / 1:10000 sections numbered in the IGM sheet."
    parameters = [
        ExtentParameter("EXTENT", "area to cover: 'xmin,ymin,xmax,ymax EPSG:3003' (CRS optional)"),
        Integer("SHEET_50K", "IGM 1:50000 sheet number (1-652)", min_value=1, max_value=652),
        Enum("SCALE", "sheets of the index", options=["5000", "10000"], default="5000"),
        String("ORIGIN", "north-west corner of the 1:50000 sheet: lon,lat in ED50 degrees"),
        Boolean("NEIGHBOURS", "add the ring of neighbouring sheets", default=True),
        Crs("CRS", "CRS of EXTENT when it names none (an EXTENT naming another CRS is "
            "refused)", optional=True),
        OutputVector("OUTPUT", "sheet index GeoPackage (layer sheets)", layers=[
            Layer("sheets", "Polygon", [
                ("name", "string"), ("number", "string", "CTR number, 6 digits"),
                ("scale", "integer"), ("sheet_50k", "integer"), ("section", "integer"),
                ("element", "integer"), ("west", "real"), ("south", "real"),
                ("east", "real"), ("north", "real"), ("in_extent", "integer")],
                "sheets and their CTR numbers")]),
    ]
    outputs = [Output("STATISTICS", "sheets written, covering, numbered", "dict")]

    def check(self, params):
        self._origin(params["ORIGIN"])
        extent = params["EXTENT"]
        if extent.crs is None and params.get("CRS") is None:
            raise self.fail("EXTENT", "names no CRS: add [EPSG:...] or give CRS")

    def _origin(self, text: str) -> tuple[float, float]:
        try:
            lon, lat = (float(v) for v in str(text).split(","))
        except ValueError:
            raise self.fail("ORIGIN", f"{text!r} is not lon,lat in degrees (e.g. 11.1667,43.4)"
                            ) from None
        if not (-180 <= lon <= 180 and -90 <= lat <= 90):
            raise self.fail("ORIGIN", f"{text!r} is not a longitude,latitude in degrees")
        return lon, lat

    def process(self, params, feedback: Feedback):
        import geopandas as gpd

        from toolbox.cartography.ctr_index import ED50, IndexRequest, index_sheets
        from toolbox.io.crs import common_crs, note_transformation
        from toolbox.io.vector_write import write_layers
        from toolbox.photogrammetry.accuracy import planimetric_tolerance_m

        extent = params["EXTENT"]
        crs = common_crs({"EXTENT": extent.crs}, params["CRS"])
        scale = int(params["SCALE"])
        origin = self._origin(params["ORIGIN"])
        # the sheet edges are ED50 meridians and parallels: placed in CRS by PROJ's operation
        datum = note_transformation(feedback, ED50, crs, _lonlat_box(origin),
                                    planimetric_tolerance_m(scale), "the sheet edges (ED50)",
                                    f"the map's planimetric tolerance at 1:{scale}")
        sheets = index_sheets(IndexRequest(tuple(extent.bounds), crs, params["SHEET_50K"],
                                           scale, origin, params["NEIGHBOURS"]))
        import shapely

        area = shapely.box(*extent.bounds)
        kind = "elemento" if scale == 5000 else "sezione"
        rows = [{"name": f"{kind} {s.number}" if s.number else "",
                 "number": s.number, "scale": scale, "sheet_50k": params["SHEET_50K"],
                 "section": s.section, "element": s.element, "west": s.west, "south": s.south,
                 "east": s.east, "north": s.north,
                 "in_extent": int(polygon.intersection(area).area > 0), "geometry": polygon}
                for s, polygon in sheets]
        frame = gpd.GeoDataFrame(rows, geometry="geometry", crs=crs)
        outside = int((frame["number"] == "").sum())
        if outside:
            feedback.push_warning(f"{outside} sheets fall outside 1:50000 sheet "
                                  f"{params['SHEET_50K']:03d} and have no number")
        write_layers(params["OUTPUT"], {"sheets": frame}, crs=crs,
                     geometry_types={"sheets": "Polygon"})
        return {"OUTPUT": params["OUTPUT"],
                "STATISTICS": {"sheets": len(frame), "covering": int(frame["in_extent"].sum()),
                               "numbered": len(frame) - outside, "transformation": datum}}


def _lonlat_box(origin: tuple[float, float]) -> tuple[float, float, float, float]:
    """The 1:50000 sheet (20' x 12' south-east of its north-west corner ``origin``)."""
    return origin[0], origin[1] - 0.2, origin[0] + 1.0 / 3.0, origin[1]
