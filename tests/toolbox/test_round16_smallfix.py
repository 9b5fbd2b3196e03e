"""Round sixteen, smallfix: defects other helpers reported, each checked against independent
truth (GDAL's own readers, hand counts)."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio

import toolbox
from toolbox.raster.writer import cog_problems


# -- 1. rectify:image MODE=gcps honours OVERVIEWS and COG ----------------------------------------
def _gcp_transform(tmp_path, size):
    rows = ["id,col,row,X,Y"]
    for k, (c, r) in enumerate([(0, 0), (size, 0), (0, size), (size, size), (size // 2, 30)]):
        rows.append(f"P{k},{c},{r},{1688000 + c},{4799000 - r}")
    (tmp_path / "gcps.csv").write_text("\n".join(rows) + "\n")
    toolbox.run("rectify:estimate", {"INPUT": tmp_path / "gcps.csv", "CRS": "EPSG:3003",
                                     "MODEL": "affine", "ROBUST": "none",
                                     "OUTPUT": tmp_path / "t.json"})
    return tmp_path / "t.json"


@pytest.mark.parametrize("cog", [True, False])
def test_rectify_gcps_mode_writes_overviews_and_cog(tmp_path, cog):
    # MODE=gcps wrote a 1200 x 1200 photo without overviews although OVERVIEWS was true, and
    # COG=true made no COG (the parameters were ignored in silence)
    size = 1200
    data = np.random.default_rng(1).integers(0, 255, (1, size, size), dtype=np.uint8)
    photo = tmp_path / "photo.tif"
    with rasterio.open(photo, "w", driver="GTiff", width=size, height=size, count=1,
                       dtype="uint8") as dst:
        dst.write(data)
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": _gcp_transform(tmp_path, size),
                                        "MODE": "gcps", "COG": cog, "OUTPUT": tmp_path / "g.tif"})
    with rasterio.open(out["OUTPUT"]) as ds:
        assert ds.overviews(1) == [2, 4]  # halving until one 512 tile holds the image
        assert len(ds.gcps[0]) == 5 and ds.gcps[1].to_epsg() == 3003
        np.testing.assert_array_equal(ds.read(), data)
    # the COG layout (GDAL's validator rules): made with COG=true only
    assert (cog_problems(out["OUTPUT"]) == []) is cog
    out = toolbox.run("rectify:image", {"INPUT": photo, "TRANSFORM": tmp_path / "t.json",
                                        "MODE": "gcps", "COG": cog, "OVERVIEWS": False,
                                        "OUTPUT": tmp_path / "n.tif"})
    with rasterio.open(out["OUTPUT"]) as ds:
        assert ds.overviews(1) == []


# -- 2. report:quality's overall verdict says how many criteria were checked --------------------
def _verdicts(statuses):
    from toolbox.cartography.quality import Verdict

    names = ["check points RMSE", "largest fiducial residual", "height RMSE", "errors left"]
    return [Verdict("Product", name, "1 m", "<= 2 m", status)
            for name, status in zip(names, statuses, strict=False)]


def _overall_text(verdicts):
    from toolbox.cartography.quality import Specification, verdict_section

    section = verdict_section(verdicts, Specification(), 4)
    return next(b[1] for b in section.blocks if b[0] == "text" and b[1].startswith("Overall"))


def test_quality_verdict_counts_the_criteria_checked():
    from toolbox.cartography.quality import FAIL, NOT_CHECKED, PASS

    # 1 of 4 measured: was "Overall: ACCEPTED, 3 criterion(s) not checked (4 criteria ...)"
    text = _overall_text(_verdicts([PASS, NOT_CHECKED, NOT_CHECKED, NOT_CHECKED]))
    assert text.startswith("Overall: ACCEPTED (1 of 4 criteria checked; not checked: "
                           "Product: largest fiducial residual; Product: height RMSE; "
                           "Product: errors left)")
    assert _overall_text(_verdicts([PASS, PASS])).startswith(
        "Overall: ACCEPTED (2 of 2 criteria checked)")
    # none measured: NOT CHECKED, not ACCEPTED (was "ACCEPTED, 2 criterion(s) not checked")
    text = _overall_text(_verdicts([NOT_CHECKED, NOT_CHECKED]))
    assert text.startswith("Overall: NOT CHECKED") and " ACCEPTED" not in text
    assert _overall_text(_verdicts([])).startswith("Overall: NOT CHECKED")
    assert _overall_text(_verdicts([FAIL, PASS, NOT_CHECKED])).startswith(
        "Overall: NOT ACCEPTED: 1 of 3 criteria failed")


def test_quality_contents_carry_the_verdict_and_refuse_acceptance_without_a_measure(tmp_path):
    from toolbox.cartography import quality
    from toolbox.cartography.quality import NOT_CHECKED, PASS

    real = quality.build_sections
    for statuses, overall, accepted in (
            ([PASS, NOT_CHECKED, NOT_CHECKED, NOT_CHECKED],
             "ACCEPTED (1 of 4 criteria checked; not checked: ", True),
            ([NOT_CHECKED], "NOT CHECKED", False)):  # accepted was true with nothing measured
        quality.build_sections = lambda reports, spec, s=statuses: (_verdicts(s), [])
        try:
            (tmp_path / "r").mkdir(exist_ok=True)
            contents = quality.write_report(tmp_path / "r", tmp_path / "q.html", "T")
        finally:
            quality.build_sections = real
        assert contents["accepted"] is accepted
        assert contents.get("overall", "").startswith(overall)
        assert f"Overall: {overall}" in (tmp_path / "q.html").read_text(encoding="utf-8")


# -- 4. the Python API takes pathlib.Path for text parameters holding paths ---------------------
def test_path_text_parameter_accepts_a_pathlib_path(tmp_path):
    from toolbox.errors import ParameterError

    missing = tmp_path / "none.json"
    # was "INPUT must be text, got ...": the Path itself refused, not what it names
    with pytest.raises(ParameterError, match=r"INPUT.*none\.json' does not exist"):
        toolbox.run("orientation:convert", {"INPUT": missing, "OUTPUT": tmp_path / "o.yaml"})
    # a text parameter that holds no path still wants text
    from toolbox.parameters.values import String

    with pytest.raises(ParameterError, match="must be text, got"):
        String("TITLE").validate(tmp_path, None)
    assert String("INPUT", paths=True).validate(missing, None) == str(missing)


# -- 6. vector:info's path is absolute, as the run report's -------------------------------------
def test_vector_info_path_is_absolute(tmp_path, monkeypatch):
    import json
    import os

    import geopandas as gpd
    import shapely

    gpd.GeoDataFrame(geometry=[shapely.Point(1, 2)], crs="EPSG:3003").to_file(
        tmp_path / "pts.gpkg", layer="pts")
    monkeypatch.chdir(tmp_path)
    out = toolbox.run("vector:info", {"INPUT": "pts.gpkg", "OUTPUT": "info.json"})
    written = json.loads((tmp_path / "info.json").read_text())
    # was "pts.gpkg": it named nothing once the JSON left this folder
    assert written["path"] == out["INFO"]["path"] == os.path.join(str(tmp_path), "pts.gpkg")


# -- 8. carto:grid's "empty grid" warning says what was written --------------------------------
@pytest.mark.parametrize("extent, labels", [
    ("1688050,4799010,1688150,4799090 [EPSG:3003]", 2),  # the line x = 1688100 crosses it
    ("1688010,4799010,1688090,4799090 [EPSG:3003]", 0),  # no grid line at all
])
def test_grid_without_cross_says_how_many_labels_were_written(tmp_path, extent, labels):
    import geopandas as gpd

    # 1:1000, 100 mm: crosses every 100 m, none inside either extent
    feedback = toolbox.Feedback()
    toolbox.run("carto:grid", {"EXTENT": extent, "SCALE": 1000, "OUTPUT": tmp_path / "g.gpkg"},
                feedback=feedback)
    assert len(gpd.read_file(tmp_path / "g.gpkg", layer="grid")) == 0
    assert len(gpd.read_file(tmp_path / "g.gpkg", layer="grid_labels")) == labels
    (warning,) = [w for w in feedback.warnings if w.startswith("no grid cross")]
    # was "...: the grid is empty" while grid_labels held 2 labels
    if labels:
        assert f"{labels} label(s) of the grid lines crossing it written" in warning
    else:
        assert warning.endswith("the grid layer is empty, and so are its labels")


# -- 9. measured (M) inputs: one warning per input naming the layer ----------------------------
def _write_measured(tmp_path, wkt, layer, nlt):
    """A GeoPackage layer with M values, written by GDAL's ogr2ogr (pyogrio drops M)."""
    import shutil
    import subprocess

    ogr2ogr = shutil.which("ogr2ogr")
    if ogr2ogr is None:
        pytest.skip("ogr2ogr (GDAL) writes the measured layer")
    csv = tmp_path / f"{layer}.csv"
    csv.write_text(f'id,WKT\n1,"{wkt}"\n')
    out = tmp_path / f"{layer}.gpkg"
    subprocess.run([ogr2ogr, "-f", "GPKG", str(out), str(csv), "-nln", layer, "-a_srs",
                    "EPSG:3003", "-nlt", nlt], check=True, capture_output=True)
    return out


@pytest.mark.parametrize("wkt, nlt, original", [
    ("LINESTRING M (0 0 5, 10 0 6)", "LINESTRINGM", "Measured LineString"),
    ("POINT ZM (0 0 1 5)", "POINTZM", "Measured 3D Point"),
])
def test_measured_input_warns_once_naming_the_layer(tmp_path, wkt, nlt, original, recwarn):
    import json

    layer = "survey_m"
    path = _write_measured(tmp_path, wkt, layer, nlt)
    report = tmp_path / "run.json"
    toolbox.run("vector:info", {"INPUT": path}, report=report)
    warnings = json.loads(report.read_text())["warnings"]
    # was: no warning of the toolbox (pyogrio's own, repeated, naming no layer, outside it)
    assert warnings == [f"INPUT '{path}' layer '{layer}' has measured geometries ({original}): "
                        "their M values are dropped, only X, Y (and Z) are read"]
    assert not [w for w in recwarn if "Measured (M)" in str(w.message)]
