"""Shared synthetic blocks for the mosaic tests, made once per session: two orthos of one ground
texture with a building displaced differently in each (toolbox.demo.samples.mosaic documents the
truth), and their mosaic:seamlines outputs."""

import toolbox
from toolbox.demo.samples.mosaic import make_block, pair_specs

_MADE: dict = {}


def standard_pair(tmp_path_factory):
    """(orthos, building ground footprint) of the standard pair: overlap x 400-600 m local,
    nadir points at x 250 and 750 m, the building at (500, 200) m, 40 m square."""
    if "pair" not in _MADE:
        _MADE["pair"] = make_block(tmp_path_factory.mktemp("pair"), pair_specs())
    return _MADE["pair"]


def standard_seams(tmp_path_factory):
    """mosaic:seamlines outputs ``{"voronoi": ..., "least_cost": ...}`` of the standard pair."""
    if "seams" not in _MADE:
        orthos, _ = standard_pair(tmp_path_factory)
        folder = tmp_path_factory.mktemp("seams")
        _MADE["seams"] = {method: toolbox.run("mosaic:seamlines", {
            "INPUT": [str(o.path) for o in orthos], "METHOD": method,
            "OUTPUT": str(folder / f"{method}.gpkg")}) for method in ("voronoi", "least_cost")}
    return _MADE["seams"]
