"""Size guards (issue 24 §2): parameters that would allocate or write an absurd amount are refused
before any work, with the estimate, the limit and the parameter to change (toolbox.limits). Each
test makes the heavy step fail if it were reached, so the refusal must come first."""

from __future__ import annotations

import time

import geopandas as gpd
import numpy as np
import pytest
from rasterio.transform import from_origin
from shapely.geometry import LineString

import toolbox
from toolbox.errors import ParameterError
from toolbox.raster.writer import write_raster

E0, N0 = 1688000.0, 4799000.0
CRS = "EPSG:3003"


def never(*args, **kwargs):
    raise AssertionError("the heavy step ran before the size guard")


def refused(algorithm: str, params: dict, parameter: str, *words: str) -> str:
    started = time.perf_counter()
    with pytest.raises(ParameterError) as info:
        toolbox.run(algorithm, params)
    text = str(info.value)
    assert info.value.name == parameter and text.startswith(parameter + " "), text
    assert "over the limit of" in text and "\n" not in text
    for word in words:
        assert word in text, text
    assert time.perf_counter() - started < 20
    return text


@pytest.fixture
def dem(tmp_path):
    z = 300.0 + np.add.outer(np.arange(40.0), np.arange(50.0))  # 300 .. 388 m
    path = tmp_path / "dem.tif"
    write_raster(path, z.astype("float32"), from_origin(E0, N0 + 400, 10, 10), CRS,
                 nodata=-9999.0)
    return path


@pytest.fixture
def lines(tmp_path):
    path = tmp_path / "l.gpkg"
    gpd.GeoDataFrame({"id": [1]}, geometry=[LineString([(E0 + 20, N0 + 20),
                                                        (E0 + 320, N0 + 20)])],
                     crs=CRS).to_file(path)
    return path


def test_contours_tiny_interval_and_huge_heights(dem, tmp_path, monkeypatch):
    from toolbox.cartography import contour_io

    monkeypatch.setattr(contour_io, "trace_raster", never)
    text = refused("carto:contours", {"INPUT": dem, "INTERVAL": 1e-9,
                                      "OUTPUT": tmp_path / "c.gpkg"},
                   "INTERVAL", "300 .. 388", "contour levels", "use a larger INTERVAL")
    assert "88,000,000,001 contour levels" in text  # (388 - 300) / 1e-9 + 1
    z = np.full((30, 30), 100.0, "float32")
    z[5, 5] = 1e30  # a DEM with a wild height
    write_raster(tmp_path / "wild.tif", z, from_origin(E0, N0, 10, 10), CRS, nodata=-9999.0)
    refused("carto:contours", {"INPUT": tmp_path / "wild.tif", "OUTPUT": tmp_path / "c.gpkg"},
            "INTERVAL", "1e+30")
    assert not (tmp_path / "c.gpkg").exists()


def test_grid_on_a_huge_extent(tmp_path, monkeypatch):
    from toolbox.cartography import grid_io

    monkeypatch.setattr(grid_io, "map_grid", never)
    refused("carto:grid", {"EXTENT": f"0,0,1e8,1e8 [{CRS}]", "OUTPUT": tmp_path / "g.gpkg"},
            "MAP_STEP", "40,000,400,001 grid crosses")  # (1e8 / 500 + 1)^2


def test_profile_tiny_step_and_spacing(dem, lines, tmp_path, monkeypatch):
    from toolbox.cartography import profile_io

    monkeypatch.setattr(profile_io, "sample_stations", never)
    base = {"INPUT": lines, "DEM": dem, "OUTPUT": tmp_path / "p.gpkg"}
    refused("carto:profile", base | {"STEP": 1e-9}, "STEP", "along 300 units",
            "300,000,000,001 vertices")
    refused("carto:profile", base | {"MODE": "sections", "SPACING": 1e-6}, "SPACING",
            "sections")
    refused("carto:profile", base | {"MODE": "sections", "STEP": 1e-6, "HALF_WIDTH": 100},
            "STEP", "across")


def test_sample_tiny_distance(lines, tmp_path, monkeypatch):
    from toolbox.attribution import editing

    monkeypatch.setattr(editing, "densify", never)
    monkeypatch.setattr(editing, "sample_by_distance", never)
    for method in ("densify", "distance"):
        refused("attribution:sample", {"INPUT": lines, "METHOD": method, "DISTANCE": 1e-9,
                                       "OUTPUT": tmp_path / "s.gpkg"},
                "DISTANCE", "300,000,000,001 vertices")


def test_cut_tiny_sheets(dem, tmp_path, monkeypatch):
    from toolbox.mosaic import sheets

    monkeypatch.setattr(sheets, "sheet_grid", never)
    refused("mosaic:cut", {"INPUT": dem, "SCALE": 2000, "SHEET_WIDTH": 0.001,
                           "SHEET_HEIGHT": 0.001, "OUTPUT": tmp_path / "cut"},
            "SHEET_WIDTH", "sheets", "SCALE")
    assert not (tmp_path / "cut").exists()


def test_cut_huge_sheets(dem, tmp_path, monkeypatch):
    """One sheet 4.3e16 cm wide over a 10 m raster: each sheet is written over its bounds, so
    its cells are refused (the hypothesis sweep found an OverflowError here)."""
    from toolbox.mosaic import sheets

    monkeypatch.setattr(sheets, "clip_raster", never)
    refused("mosaic:cut", {"INPUT": dem, "SCALE": 5000, "SHEET_WIDTH": 4.3e16,
                           "SHEET_HEIGHT": 10, "OUTPUT": tmp_path / "cut"},
            "SHEET_WIDTH", "cells", "10 x 10 cells", "use smaller or fewer sheets")
    assert not (tmp_path / "cut").exists()


def test_seamlines_tiny_seam_cell(dem, tmp_path, monkeypatch):
    from toolbox.mosaic import seams

    monkeypatch.setattr(seams, "least_cost_cells", never)
    refused("mosaic:seamlines", {"INPUT": [dem, dem], "SEAM_CELL_SIZE": 0.0001,
                                 "OUTPUT": tmp_path / "s.gpkg"},
            "SEAM_CELL_SIZE", "40,000,000,000,000 cells")  # 2 x 500 x 400 m at 1e-4


def test_sheet_at_scale_one(tmp_path, monkeypatch):
    from toolbox.cartography import sheet_job

    monkeypatch.setattr(sheet_job, "render_sheet", never)
    refused("carto:sheet", {"EXTENT": f"{E0},{N0},{E0 + 2000},{N0 + 1000} [{CRS}]",
                            "SCALE": 1, "OUTPUT": tmp_path / "s.pdf"},
            "SCALE", "1:1", "pixels", "PNG_DPI 120")


def test_limits_are_raised_by_their_environment_variable(dem, tmp_path, monkeypatch):
    """The same guard, one helper: a lower TOOLBOX_MAX_FEATURES refuses a normal run, a bad
    value of the variable is named."""
    monkeypatch.setenv("TOOLBOX_MAX_FEATURES", "10")
    refused("carto:contours", {"INPUT": dem, "INTERVAL": 1, "OUTPUT": tmp_path / "c.gpkg"},
            "INTERVAL", "89 contour levels", "limit of 10 features", "TOOLBOX_MAX_FEATURES")
    monkeypatch.setenv("TOOLBOX_MAX_FEATURES", "lots")
    with pytest.raises(ParameterError, match="TOOLBOX_MAX_FEATURES"):
        toolbox.run("carto:contours", {"INPUT": dem, "OUTPUT": tmp_path / "c.gpkg"})
    monkeypatch.delenv("TOOLBOX_MAX_FEATURES")
    out = toolbox.run("carto:contours", {"INPUT": dem, "INTERVAL": 10,
                                         "OUTPUT": tmp_path / "c.gpkg"})
    assert out["STATISTICS"]["levels"] == 9  # 310 .. 390 within 300 .. 388: 310..380
