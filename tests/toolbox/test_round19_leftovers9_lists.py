"""An empty item in a list-of-files parameter is refused (exit 2, one line naming the parameter,
the value and what was expected), by the one check :func:`toolbox.parameters.base.
refuse_empty_items`: ``carto:sheet --LAYERS ''`` drew the sheet without the layer (exit 0) and
``orientation:convert --INPUT 'a.yaml,,'`` read ``a.yaml`` alone (exit 0)."""

from __future__ import annotations

from pathlib import Path

import geopandas as gpd
import pytest
import shapely

import toolbox
from tests.helpers_cli import cli, one_error
from toolbox.errors import ParameterError

EXTENT = "1500000,5000000,1500100,5000100 EPSG:3003"
SIENA = Path(__file__).resolve().parents[2] / "toolbox/demo/data/siena/siena_project.yaml"


@pytest.fixture
def points(tmp_path) -> Path:
    path = tmp_path / "p.gpkg"
    gpd.GeoDataFrame({"a": [1]}, geometry=[shapely.Point(1500050, 5000050)],
                     crs=3003).to_file(path)
    return path


def test_an_empty_layers_option_is_refused_not_drawn_without(tmp_path):
    code, _, err = cli("run", "carto:sheet", "--EXTENT", EXTENT, "--SCALE", "1000",
                       "--LAYERS", "", "--PNG", tmp_path / "a.png")
    line = one_error(err)
    assert code == 2, err
    assert "LAYERS has an empty item 1 of 1 in ''" in line, line
    assert "expected 0+ vector layers" in line, line
    assert not (tmp_path / "a.png").exists()


def test_an_empty_item_among_layers_is_refused_naming_it(tmp_path, points):
    code, _, err = cli("run", "carto:sheet", "--EXTENT", EXTENT, "--SCALE", "1000",
                       "--LAYERS", points, "--LAYERS", " ", "--LAYERS", points,
                       "--PNG", tmp_path / "a.png")
    line = one_error(err)
    assert code == 2 and "LAYERS has an empty item 2 of 3 in [" in line, line
    with pytest.raises(ParameterError, match=r"empty items 1, 3 of 3") as caught:
        toolbox.validate("carto:sheet", {"EXTENT": EXTENT, "SCALE": 1000, "PNG": "a.png",
                                         "LAYERS": [None, str(points), ""]})
    assert caught.value.name == "LAYERS"


def test_an_empty_list_of_layers_stays_no_layers(points):
    """No layers at all (min_count 0) is still fine: an empty list is not an empty item."""
    for layers in ([], None, [str(points)]):
        toolbox.validate("carto:sheet", {"EXTENT": EXTENT, "SCALE": 1000, "PNG": "a.png",
                                         "LAYERS": layers})


def test_an_empty_ortho_among_the_mosaic_inputs_is_refused(tmp_path):
    code, _, err = cli("run", "mosaic:seamlines", "--INPUT", "", "--OUTPUT", tmp_path / "s.gpkg")
    line = one_error(err)
    assert code == 2 and "INPUT has an empty item 1 of 1 in ''" in line, line
    assert "raster layers" in line, line


def test_an_empty_item_of_a_comma_separated_path_list_is_refused(tmp_path):
    out = tmp_path / "s.csv"
    code, _, err = cli("run", "orientation:convert", "--INPUT", f"{SIENA},,", "--FORMAT_OUT",
                       "csv", "--OUTPUT", out)
    line = one_error(err)
    assert code == 2 and "INPUT has empty items 2, 3 of 3 in '" in line, line
    assert "expected a path, or several separated by commas" in line, line
    assert not out.exists()
    code, _, err = cli("run", "ortho:batch", "--IMAGES", "a.tif,,b.tif", "--DEM", "d.tif",
                       "--FOLDER", tmp_path / "o")
    line = one_error(err)
    assert code == 2 and "IMAGES has an empty item 2 of 3 in 'a.tif,,b.tif'" in line, line


def test_a_path_with_commas_in_its_name_is_still_one_path(tmp_path):
    """An existing file or folder whose name holds commas is taken whole, not split into
    items (orientation:tiepoints' IMAGES folder)."""
    from toolbox.parameters import String, ValidationContext

    odd = tmp_path / "photos,,2026"
    odd.mkdir()
    param = String("IMAGES", paths=True, optional=True)
    assert param.resolve(str(odd), ValidationContext()) == str(odd)
    with pytest.raises(ParameterError, match="empty items 2, 4 of 4"):
        param.resolve(f"{odd}x,", ValidationContext())
