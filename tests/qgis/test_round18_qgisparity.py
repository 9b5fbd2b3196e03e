"""The QGIS provider against the CLI (round 18): each test runs a short PyQGIS script in
Debian's QGIS Python (skipped when QGIS is absent, as the other QGIS tests)."""

from __future__ import annotations

from pathlib import Path

from test_qgis_provider import needs_qgis
from test_round15_sweep_qgis import plugin_values


def _lines(path: Path) -> None:
    import geopandas as gpd
    from shapely.geometry import LineString

    gpd.GeoDataFrame({"elev": [10.0]}, geometry=[LineString([(1_680_010, 4_800_010),
                                                             (1_680_090, 4_800_090)])],
                     crs="EPSG:3003").to_file(path, driver="GPKG")


@needs_qgis
def test_a_second_grid_crs_is_not_taken_for_the_extent_crs(tmp_path):
    """carto:sheet with GRID_CRS (a second CRS ticked along the frame) and no CRS: the plugin
    took GRID_CRS for the data's CRS and sent the extent reprojected into it, so the sheet was
    refused ('no input meets the sheets', exit 2) where the CLI with the same values draws it.
    The extent stays in the data's CRS (the layer's, or the CRS parameter's)."""
    gpkg = tmp_path / "lines.gpkg"
    _lines(gpkg)
    params = [{"name": "EXTENT", "type": "extent"}, {"name": "CONTOURS", "type": "vector"},
              {"name": "CRS", "type": "crs"}, {"name": "GRID_CRS", "type": "crs"}]
    drawn = "1680000,1680100,4800000,4800100 [EPSG:3003]"  # QGIS's order
    got = plugin_values(tmp_path, params, {
        "grid": {"CONTOURS": {"layer": str(gpkg)}, "EXTENT": drawn, "GRID_CRS": "EPSG:6707"},
        "crs": {"CONTOURS": {"layer": str(gpkg)}, "EXTENT": drawn, "GRID_CRS": "EPSG:4326",
                "CRS": "EPSG:3003"}})
    for label in ("grid", "crs"):
        assert got[label]["EXTENT"] == "1680000.0,4800000.0,1680100.0,4800100.0 [EPSG:3003]"
