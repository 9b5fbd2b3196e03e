"""Runner and registry: discovery, validation before work, atomic outputs, reports, cancellation."""

from __future__ import annotations

import json

import numpy as np
import pytest
import rasterio

import toolbox
from toolbox.algorithm import Algorithm
from toolbox.errors import (
    AlgorithmNotFoundError,
    CanceledError,
    InputDataError,
    OutputExistsError,
    ParameterError,
    ToolboxError,
)
from toolbox.feedback import Feedback
from toolbox.parameters import Number, Output, OutputRaster, OutputVector
from toolbox.registry import get, register


@register
class _HalfWriteThenFail(Algorithm):
    """Writes part of its outputs, then fails (as a real run may, mid-way)."""

    id = "testing:half_write"
    display_name = "Half write"
    group = "Testing"
    short_help = "writes one output then raises"
    parameters = [Number("AT", default=1), OutputRaster("OUTPUT"), OutputVector("SECOND")]

    def process(self, params, feedback):
        params["OUTPUT"].write_bytes(b"partial")
        raise InputDataError("boom after writing")


@register
class _Cancelable(Algorithm):
    """Cancels itself mid-way through its loop."""

    id = "testing:cancelable"
    display_name = "Cancelable"
    group = "Testing"
    short_help = "cancels itself"
    parameters = [OutputRaster("OUTPUT")]
    outputs = [Output("STEPS", "steps done", "number")]

    def process(self, params, feedback):
        params["OUTPUT"].write_bytes(b"partial")
        for i in feedback.iterate(range(10)):
            if i == 3:
                feedback.cancel()
        return {"OUTPUT": params["OUTPUT"], "STEPS": 10}


def test_registry_discovers_builtin_algorithms():
    ids = {a.id for a in toolbox.algorithms()}
    assert {"dem:hillshade", "vector:info"} <= ids
    for alg in toolbox.algorithms():
        alg.check_spec()  # every registered spec is consistent


def test_unknown_algorithm_suggests():
    with pytest.raises(AlgorithmNotFoundError, match="did you mean dem:hillshade"):
        get("raster:hilshade")


def test_alias_resolves(monkeypatch):
    from toolbox import registry

    monkeypatch.setitem(registry.ALIASES, "raster:shade", "dem:hillshade")
    assert get("raster:shade").id == "dem:hillshade"


def test_bad_spec_refused():
    class Bad(Algorithm):
        id = "Bad-Id"
        display_name = group = short_help = "x"

    with pytest.raises(TypeError, match="group:name"):
        register(Bad)


def test_unknown_and_missing_parameters(plane_dem, tmp_path):
    with pytest.raises(ParameterError, match="CELLSIZE is not a parameter of dem:hillshade"):
        toolbox.run("dem:hillshade", {"INPUT": plane_dem[0], "CELLSIZE": 2,
                                         "OUTPUT": tmp_path / "o.tif"})
    with pytest.raises(ParameterError, match="OUTPUT is required"):
        toolbox.run("dem:hillshade", {"INPUT": plane_dem[0]})


def test_check_runs_before_work(plane_dem, tmp_path):
    with pytest.raises(ParameterError, match="BAND must be <= 1"):
        toolbox.run("dem:hillshade", {"INPUT": plane_dem[0], "BAND": 3,
                                         "OUTPUT": tmp_path / "o.tif"})
    assert [p.name for p in tmp_path.iterdir()] == ["plane.tif"]


def test_failed_run_leaves_no_partial_output(tmp_path):
    with pytest.raises(InputDataError, match="boom"):
        toolbox.run("testing:half_write", {"OUTPUT": tmp_path / "a.tif",
                                           "SECOND": tmp_path / "b.gpkg"})
    assert list(tmp_path.iterdir()) == []


def test_failed_run_keeps_previous_output(tmp_path):
    target = tmp_path / "a.tif"
    target.write_bytes(b"previous good result")
    with pytest.raises(InputDataError):
        toolbox.run("testing:half_write", {"OUTPUT": target, "SECOND": tmp_path / "b.gpkg",
                                           "OVERWRITE": True})
    assert target.read_bytes() == b"previous good result"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.tif"]


def test_canceled_run_leaves_nothing(tmp_path):
    with pytest.raises(CanceledError):
        toolbox.run("testing:cancelable", {"OUTPUT": tmp_path / "a.tif"})
    assert list(tmp_path.iterdir()) == []


def test_toolbox_errors_are_also_builtin_errors():
    assert issubclass(ParameterError, ValueError) and issubclass(ParameterError, ToolboxError)


def test_hillshade_of_a_plane_matches_lambert(plane_dem, tmp_path):
    path, sx, sy = plane_dem
    out = tmp_path / "hs.tif"
    progress = []
    result = toolbox.run("dem:hillshade", {"INPUT": str(path), "OUTPUT": str(out)},
                         feedback=Feedback(lambda p, m: progress.append(p)))
    assert result == {"OUTPUT": str(out.absolute())}
    # plane: z = 100 + 0.2 x' - 0.1 (y - y0) -> dz/dx = 0.2, dz/dy(north) = -0.1
    dzdx, dzdy = sx, sy
    az, alt = np.radians(315), np.radians(45)
    expected = (np.sin(alt) - np.cos(alt) * (dzdx * np.sin(az) + dzdy * np.cos(az))) / np.sqrt(
        1 + dzdx**2 + dzdy**2)
    with rasterio.open(out) as ds:
        band = ds.read(1)
        assert ds.crs.to_epsg() == 3003 and ds.nodata == 0
        assert ds.profile["compress"] == "deflate"
    assert np.all(band == 1 + np.round(expected * 254))
    assert progress[0] == 0 and progress[-1] == 100 and progress == sorted(progress)


def test_existing_output_needs_overwrite(plane_dem, tmp_path):
    out = tmp_path / "hs.tif"
    toolbox.run("dem:hillshade", {"INPUT": plane_dem[0], "OUTPUT": out})
    with pytest.raises(OutputExistsError):
        toolbox.run("dem:hillshade", {"INPUT": plane_dem[0], "OUTPUT": out})
    toolbox.run("dem:hillshade", {"INPUT": plane_dem[0], "OUTPUT": out}, overwrite=True)


def test_output_equal_to_input_refused(plane_dem):
    with pytest.raises(ParameterError, match="also the input INPUT"):
        toolbox.run("dem:hillshade", {"INPUT": plane_dem[0], "OUTPUT": plane_dem[0]},
                    overwrite=True)


OGR_VRT = """<OGRVRTDataSource>
  <OGRVRTLayer name="pts">
    <SrcDataSource{attribute}>{source}</SrcDataSource>
    <SrcLayer>pts</SrcLayer>
  </OGRVRTLayer>
</OGRVRTDataSource>
"""


@pytest.mark.parametrize("case", ["raster", "nested", "ogr", "ogr_absolute"])
def test_output_on_a_file_a_vrt_input_reads_is_refused(plane_dem, points_gpkg, tmp_path, case):
    """Found by the I/O sweep: OUTPUT on the data a VRT input reads (a raster VRT's source, one
    behind a VRT of a VRT, an OGR VRT's SrcDataSource) replaced the input data with --overwrite.
    Refused in one line naming OUTPUT and INPUT; every file byte-identical, nothing written."""
    import hashlib

    import rasterio.shutil

    from tests.helpers_cli import cli, one_error

    rasterio.shutil.copy(plane_dem[0], tmp_path / "plane.vrt", driver="VRT")
    text = (tmp_path / "plane.vrt").read_text(encoding="utf-8")
    assert '<SourceFilename relativeToVRT="1">plane.tif<' in text
    (tmp_path / "outer.vrt").write_text(text.replace(">plane.tif<", ">plane.vrt<"),
                                        encoding="utf-8")
    for name, attribute, source in (("pts.vrt", ' relativeToVRT="1"', "points.gpkg"),
                                    ("abs.vrt", "", points_gpkg)):
        (tmp_path / name).write_text(OGR_VRT.format(attribute=attribute, source=source),
                                     encoding="utf-8")
    algorithm, vrt, data = {"raster": ("dem:hillshade", "plane.vrt", plane_dem[0]),
                            "nested": ("dem:hillshade", "outer.vrt", plane_dem[0]),
                            "ogr": ("tin:delaunay", "pts.vrt", points_gpkg),
                            "ogr_absolute": ("tin:delaunay", "abs.vrt", points_gpkg)}[case]
    before = {f.name: hashlib.md5(f.read_bytes()).hexdigest() for f in tmp_path.iterdir()}
    code, _, err = cli("run", algorithm, "--INPUT", tmp_path / vrt, "--OUTPUT", data,
                       "--overwrite")
    line = one_error(err)
    assert code == 2 and f"OUTPUT '{data}' is the input INPUT" in line, line
    assert {f.name: hashlib.md5(f.read_bytes()).hexdigest() for f in tmp_path.iterdir()} == before


def test_json_report_content(plane_dem, tmp_path):
    report = tmp_path / "run.json"
    toolbox.run("dem:hillshade", {"INPUT": plane_dem[0], "AZIMUTH": 90,
                                     "OUTPUT": tmp_path / "hs.tif"}, report=report)
    data = json.loads(report.read_text())
    assert data["algorithm"] == "dem:hillshade"
    assert data["parameters"]["AZIMUTH"] == 90.0
    assert data["parameters"]["INPUT"] == str(plane_dem[0])
    assert data["outputs"]["OUTPUT"].endswith("hs.tif")
    assert data["versions"]["toolbox"] == toolbox.__version__
    assert data["versions"]["gdal"] and data["versions"]["proj"] and data["versions"]["geos"]
    assert data["elapsed_s"] >= 0


REPORT_WITHOUT_PANDAS = """
import json, sys
from toolbox.report import versions
found = versions()
assert "pandas" not in sys.modules and "geopandas" not in sys.modules, "pandas imported"
import pyogrio
print(json.dumps([found["pyogrio"], pyogrio.__version__]))
"""


def test_the_reports_versions_do_not_import_pandas():
    """The run report names pyogrio's version without importing pandas (pyogrio's __init__);
    the same version as the package's own ``__version__``."""
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-c", REPORT_WITHOUT_PANDAS], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    ours, theirs = json.loads(proc.stdout)
    assert ours == theirs


def test_vector_info_describes_layers(points_gpkg, tmp_path):
    out = tmp_path / "info.json"
    result = toolbox.run("vector:info", {"INPUT": points_gpkg, "OUTPUT": out})
    layer = result["INFO"]["layers"][0]
    assert layer["name"] == "pts" and layer["features"] == 10 and layer["crs"] == "EPSG:3003"
    assert layer["has_z"] and 280 <= layer["z_range"][0] <= layer["z_range"][1] <= 340
    assert json.loads(out.read_text()) == result["INFO"]


def test_plugins_come_from_the_entry_point_group(monkeypatch):
    """A third-party provider registers through the ``toolbox.algorithms`` entry points."""
    from toolbox import registry

    class PluginAlgorithm(Algorithm):
        """A provider's algorithm."""

        id = "plugin:echo"
        display_name = "Echo"
        group = "Plugins"
        short_help = "returns its number"
        parameters = [Number("VALUE", default=3)]
        outputs = [Output("VALUE_OUT", "the value", "number")]

        def process(self, params, feedback):
            return {"VALUE_OUT": params["VALUE"]}

    class FakeEntryPoint:
        name = "echo"

        def load(self):
            return PluginAlgorithm

    class BrokenEntryPoint:
        name = "broken"

        def load(self):
            raise ImportError("missing dependency of a plugin")

    def fake_entry_points(group):
        assert group == registry.ENTRY_POINT_GROUP
        return [FakeEntryPoint(), BrokenEntryPoint()]

    monkeypatch.setattr(registry, "entry_points", fake_entry_points)
    monkeypatch.delitem(registry._registry, "plugin:echo", raising=False)
    monkeypatch.setattr(registry, "_indexed", set(registry._indexed))  # plugin:echo leaves it
    monkeypatch.setattr(registry, "_loaded_all", False)
    try:
        registry.discover()  # the broken plugin is skipped with a warning
        assert toolbox.run("plugin:echo", {"VALUE": 5}) == {"VALUE_OUT": 5.0}
    finally:
        registry._registry.pop("plugin:echo", None)


def test_band_is_checked_against_the_dem_among_several_rasters(plane_dem, tmp_path):
    """One BAND check (the runner's) for algorithms with several rasters: BAND names a band of
    DEM, so a TEMPLATE beside it does not hide the mistake."""
    project = tmp_path / "p.yaml"
    project.write_text("photos: {}\n")
    with pytest.raises(ParameterError, match="BAND must be <= 1"):
        toolbox.run("ortho:batch", {"PROJECT": project, "DEM": plane_dem[0],
                                    "TEMPLATE": plane_dem[0], "BAND": 2,
                                    "FOLDER": tmp_path / "out", "OUTPUT": tmp_path / "o.json"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.yaml", "plane.tif"]
