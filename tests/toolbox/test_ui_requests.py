"""The parameter layer (toolbox/ui): validated parameters become the libraries' typed requests in
one place, with the algorithms' defaults; the ortho distortion block is MAP_BLOCK (TILE_SIZE is
the dem:* tile), its old name still accepted."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from toolbox.raster.grid_request import GridRequest
from toolbox.registry import get
from toolbox.terrain.gridding.request import (
    DEFAULT_MIN_RCOND,
    DEFAULT_NODATA,
    CellOptions,
    Execution,
    MethodOptions,
)
from toolbox.ui.gridding import gridding_request
from toolbox.ui.topology import explicit_tolerances, linework_sources


def test_gridding_request_from_parameters_and_defaults():
    request = gridding_request({"INPUT": "pts", "Z_FIELD": "z", "CELL_SIZE": 2.0, "POWER": 1.0,
                                "NEIGHBOURS": 8, "TILE_SIZE": 256, "OUTPUT": Path("o.tif"),
                                "EXTRAPOLATE": True, "MAX_DISTANCE": 30.0})
    assert request.sources.points == "pts" and request.sources.z_field == "z"
    assert request.sources.duplicates == "mean" and request.sources.duplicate_tolerance == 0.0
    assert request.grid == GridRequest(cell_size=2.0)
    assert request.method == MethodOptions(neighbours=8, power=1.0, max_distance=30.0,
                                           min_rcond=DEFAULT_MIN_RCOND)
    assert request.cells == CellOptions(nodata=DEFAULT_NODATA, extrapolate=True)
    assert request.execution == Execution(tile_size=256)
    assert request.output == Path("o.tif") and request.quality is None


def test_every_gridding_parameter_is_translated():
    """A parameter of a dem:<method> spec the translation does not read would be silently
    ignored: each one must change the request (or be an output / the grid's size guard)."""
    from toolbox.ui.gridding import point_cloud_parameters

    base = {"OUTPUT": Path("o.tif")}
    plain = gridding_request(base)
    special = {"OUTPUT": None, "Z_FIELD": None}  # read with INPUT; tested above
    samples = {"CLASSES": "2", "RETURNS": "last", "DUPLICATES": "max", "CRS": "EPSG:3003",
               "EXTENT": object(), "TEMPLATE": object(), "MASK": "m", "SCHEDULER": "local",
               "OVERVIEWS": False, "COG": True, "QUALITY": Path("q.json"), "NODATA": -1.0,
               "MIN_RCOND": 0.5, "SECTORS": 4, "RADIUS": 9.0, "MIN_NEIGHBOURS": 3,
               "DUPLICATE_TOLERANCE": 0.5, "MAX_CELLS": 7, "WORKERS": 3}
    names = {p.name for alg in ("dem:idw", "dem:cubic", "dem:tin_linear", "dem:nearest")
             for p in get(alg).parameters} | {p.name for p in point_cloud_parameters()}
    for name in sorted(names - set(special)):
        value = samples.get(name, 5 if name in ("NEIGHBOURS", "TILE_SIZE") else "x")
        if name in ("POWER", "CELL_SIZE"):
            value = 3.0
        assert gridding_request(base | {name: value}) != plain, name


def test_topology_sources_and_explicit_tolerances():
    params = {"INPUT": "lines", "LABELS": "labels", "SNAP_TOLERANCE": 0.3, "PARAMETERS": None}
    sources = linework_sources(params)
    assert (sources.lines, sources.labels, sources.codes) == ("lines", "labels", None)
    assert explicit_tolerances(params) == {"SNAP_TOLERANCE": 0.3, "CLOSURE_TOLERANCE": None,
                                           "MIN_DANGLE_LENGTH": None, "MIN_AREA": None,
                                           "PRECISION": None}


@pytest.mark.parametrize("algorithm", ["ortho:photo", "ortho:batch"])
def test_ortho_distortion_block_is_map_block_and_tile_size_its_old_name(algorithm):
    cls = get(algorithm)
    block = next(p for p in cls.parameters if p.name == "MAP_BLOCK")
    assert block.advanced and block.default == 64 and "TILE_SIZE" in block.deprecated_names
    assert "TILE_SIZE" not in {p.name for p in cls.parameters}
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        assert cls.rename_deprecated({"TILE_SIZE": 32}) == {"MAP_BLOCK": 32}
