"""Every field the mosaic algorithms and topology:build_areas write is declared in their output
layers (name and type) and named in their docs: mosaic:seamlines and mosaic:build wrote
``a_id``/``b_id`` in their seamlines layers that neither declared nor documented, and mosaic:cut
documented its sheet index's ``sheet_id`` as ``id``. The written fields are read back with
pyogrio (GDAL), not from the code's own tables."""

from __future__ import annotations

import numpy as np
import pyogrio
import pytest
import rasterio
from affine import Affine

import toolbox
from toolbox.registry import get as get_algorithm

KINDS = {"integer": "int64", "real": "float64", "string": "object", "boolean": "bool"}


def ortho(path, x0):
    r, c = np.indices((40, 50))
    with rasterio.open(path, "w", driver="GTiff", width=50, height=40, count=1, dtype="uint8",
                       crs="EPSG:3003", transform=Affine(1, 0, x0, 0, -1, 4800000.0),
                       nodata=0) as dst:
        dst.write((40 + c + r).astype("uint8"), 1)
    return str(path)


def written(path):
    """``{layer: [(field, dtype)]}`` of a GeoPackage, as GDAL reads it."""
    out = {}
    for name, _ in pyogrio.list_layers(path):
        if name == "layer_styles":
            continue
        info = pyogrio.read_info(path, layer=name)
        out[str(name)] = [(str(f), str(d)) for f, d in zip(info["fields"], info["dtypes"],
                                                           strict=True)]
    return out


def declared(algorithm_id, output):
    spec = next(p for p in get_algorithm(algorithm_id).parameters if p.name == output)
    return {layer.name: [(f.name, KINDS[f.type]) for f in layer.fields] for layer in spec.layers}


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fields")
    return folder, [ortho(folder / "a.tif", 1688000.0), ortho(folder / "b.tif", 1688030.0)]


def documented(algorithm_id):
    cls = get_algorithm(algorithm_id)
    return " ".join((cls.__doc__ or "").split())


def test_seamlines_writes_exactly_its_declared_fields(block):
    folder, orthos = block
    out = folder / "seams.gpkg"
    toolbox.run("mosaic:seamlines", {"INPUT": orthos, "METHOD": "voronoi", "OUTPUT": str(out)})
    got = written(out)
    assert got == declared("mosaic:seamlines", "OUTPUT")
    assert [f for f, _ in got["seamlines"]] == ["a_id", "b_id", "a", "b", "method", "length"]
    doc = documented("mosaic:seamlines")
    for layer, fields in got.items():
        assert layer in doc
        for name, _ in fields:
            assert name in doc, (layer, name)


def test_build_seamlines_writes_exactly_its_declared_fields(block):
    folder, orthos = block
    out = folder / "build_seams.gpkg"
    toolbox.run("mosaic:build", {"INPUT": orthos, "OUTPUT": str(folder / "m.tif"),
                                 "SEAMLINES": str(out)})
    got = written(out)
    assert got == declared("mosaic:build", "SEAMLINES")
    doc = documented("mosaic:build")
    assert all(name in doc for name, _ in got["seamlines"])


def test_cut_sheet_index_fields_are_documented(block):
    folder, orthos = block
    toolbox.run("mosaic:build", {"INPUT": orthos, "OUTPUT": str(folder / "m2.tif")})
    toolbox.run("mosaic:cut", {"INPUT": str(folder / "m2.tif"), "SCALE": 1000,
                               "SHEET_WIDTH": 2, "SHEET_HEIGHT": 2, "OUTPUT": str(folder / "cut")})
    got = written(folder / "cut" / "sheets.gpkg")
    assert list(got) == ["sheets"]
    assert "layer sheets: sheet_id, file, written" in documented("mosaic:cut")
    assert [f for f, _ in got["sheets"]] == ["sheet_id", "file", "written"]


def test_build_areas_writes_its_declared_fields_and_the_label_attributes(tmp_path):
    from toolbox.demo.samples import linework as sample

    data = sample.make(tmp_path, {})
    out = tmp_path / "areas.gpkg"
    toolbox.run("topology:build_areas", {
        "INPUT": data["linework"], "LABELS": data["linework_labels"],
        "PARAMETERS": data["linework_parameters"], "OUTPUT": out})
    got, want = written(out), declared("topology:build_areas", "OUTPUT")
    assert list(got) == list(want)
    label_fields = [str(f) for f in pyogrio.read_info(data["linework_labels"])["fields"]]
    assert label_fields == ["code", "quota"]
    for layer, fields in got.items():
        extra = [f for f in fields if f not in want[layer]]
        # areas also get the label point's code and attributes (said in the layer's description)
        assert [f for f, _ in extra] == (label_fields if layer == "areas" else []), layer
        assert [f for f in fields if f in want[layer]] == want[layer], layer
    doc = documented("topology:build_areas")
    for layer, fields in want.items():
        assert layer in doc
        for name, _ in fields:
            assert name in doc, (layer, name)
