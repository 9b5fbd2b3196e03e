"""Shared synthetic blocks: two orthos of one ground texture with a building displaced
differently in each (toolbox.demo.samples.mosaic documents the truth)."""

import pytest

import toolbox
from toolbox.demo.samples.mosaic import make_block, pair_specs


@pytest.fixture(scope="session")
def pair(tmp_path_factory):
    """(orthos, building ground footprint) of the standard pair: overlap x 400-600 m local,
    nadir points at x 250 and 750 m, the building at (500, 200) m, 40 m square."""
    return make_block(tmp_path_factory.mktemp("pair"), pair_specs())


@pytest.fixture(scope="session")
def seams(pair, tmp_path_factory):
    """mosaic:seamlines least_cost and voronoi GeoPackages of the pair."""
    orthos, _ = pair
    folder = tmp_path_factory.mktemp("seams")
    out = {}
    for method in ("voronoi", "least_cost"):
        out[method] = toolbox.run("mosaic:seamlines", {
            "INPUT": [str(o.path) for o in orthos], "METHOD": method,
            "OUTPUT": str(folder / f"{method}.gpkg")})
    return out
