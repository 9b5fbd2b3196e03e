"""The default least-cost seam avoids the neighbourhood of strong, structured differences
(issue 30): a building whose roof both orthos show alike but whose facades differ is gone round,
not cut through, with no DSM or building layer; the term itself on known arrays."""

from __future__ import annotations

import geopandas as gpd
import numpy as np
import pytest
import shapely

import toolbox
from toolbox.demo.samples.mosaic import make_block, pair_specs, texture
from toolbox.mosaic.seams import structure_term


def test_structure_term_is_the_neighbourhood_of_a_structured_difference():
    diff = np.zeros((60, 60))
    diff[10:50, 30] = 0.5  # a 40-cell facade edge seen in one ortho only
    diff[5, 5] = diff[55, 50] = 0.9  # isolated speckles: not structured
    term = structure_term(diff, 0.1, 8.0)
    rows, cols = np.indices(diff.shape)
    # distance to the segment (10..49, 30), computed independently of the code
    dist = np.hypot(np.clip(rows, 10, 49) - rows, cols - 30)
    assert np.array_equal(term == 1.0, dist <= 8.0)
    assert term[5, 5] == 0 and term[55, 50] == 0
    assert not structure_term(np.full((20, 20), 0.09), 0.1, 5.0).any()  # weak: nothing


def test_uniform_gain_is_no_structured_difference():
    from toolbox.mosaic.seams import CostWeights, cost_surface

    x, y = np.meshgrid(np.arange(300.0), np.arange(200.0))
    a = texture(x, y)
    plain = cost_surface(a, a, CostWeights())
    brighter = cost_surface(a, 1.08 * a - 6, CostWeights())  # the demo's balance difference
    off = cost_surface(a, 1.08 * a - 6, CostWeights(structure=0))
    assert np.array_equal(brighter, off)  # the term adds nothing
    assert np.allclose(plain, cost_surface(a, a, CostWeights(structure=0)))


@pytest.fixture(scope="module")
def roof_pair(tmp_path_factory):
    """The standard pair, but the building's relief displacement small (±5 m): both orthos show
    a common 30 m band of the same roof over the Voronoi line x = 500 m, while its facades (one
    wall colour per ortho) differ on either side."""
    folder = tmp_path_factory.mktemp("roof")
    orthos, footprint = make_block(folder, pair_specs(), building=(500.0, 200.0, 20.0),
                                   displacement=0.02)
    building = shapely.union_all([footprint] + [o.roof for o in orthos])
    return folder, orthos, building


def run(folder, orthos, name, **extra):
    out = folder / f"{name}.gpkg"
    toolbox.run("mosaic:seamlines", {"INPUT": [str(o.path) for o in orthos],
                                     "METHOD": "least_cost", "OUTPUT": out, **extra})
    return shapely.union_all(list(gpd.read_file(out, layer="seamlines").geometry))


def test_default_seam_goes_round_the_building(roof_pair):
    folder, orthos, building = roof_pair
    seam = run(folder, orthos, "default")
    assert seam.intersection(building).length == 0
    assert seam.distance(building) > 5.0  # round its neighbourhood, not along a wall
    # without the term the same seam runs straight through the shared roof
    through = run(folder, orthos, "no_structure", STRUCTURE_WEIGHT=0)
    assert through.intersection(building).length >= 30.0
