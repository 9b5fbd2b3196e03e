"""A CONTROL CSV with a ``.prj`` beside it, checked against CRS (orientation:absolute, :models
and the RPC ortho's GCPs: wherever ``tables.control_crs`` is used). The ``.prj`` was ignored: a
table in ED50 / UTM 32N read as if in WGS 84 / UTM 32N (CRS EPSG:32632), 213 m off, exit 0.
Now the table's centroid is transformed from the ``.prj``'s CRS to CRS (pyproj) and a shift over
1 mm is refused (exit 2, both CRSs and the shift named). The ``.prj`` files are GDAL's own (a
Shapefile written through pyogrio carries an ESRI ``.prj``): the ESRI forms of EPSG:3003, 32632
and 6707, which do not all compare equal to their codes, pass."""

from __future__ import annotations

import math
import re
import shutil

import geopandas as gpd
import numpy as np
import pyogrio
import pytest
import shapely
from pyproj import CRS, Transformer
from scipy.spatial.transform import Rotation

import toolbox
from tests.helpers_cli import cli, one_error
from toolbox.errors import InputDataError

#: a point inside the area of use of each CRS (Tuscany)
CENTRES = {3003: (1_688_000.0, 4_799_500.0), 32632: (688_000.0, 4_799_500.0),
           6707: (688_000.0, 4_799_500.0), 23032: (688_000.0, 4_799_500.0)}


def gdal_prj(folder, epsg: int):
    """The ``.prj`` GDAL writes for EPSG:``epsg`` (ESRI WKT, as beside a Shapefile)."""
    shp = folder / f"gdal_{epsg}.shp"
    pyogrio.write_dataframe(gpd.GeoDataFrame({"a": [1]}, geometry=[shapely.Point(0, 0)],
                                             crs=f"EPSG:{epsg}"), shp)
    return shp.with_suffix(".prj")


def tables(folder, epsg: int, prj_epsg: int | None):
    """model.csv and control.csv (the model scaled, turned and moved to ``epsg``'s centre),
    with GDAL's ``.prj`` of ``prj_epsg`` beside control.csv."""
    rng = np.random.default_rng(4)
    model = rng.uniform(-50, 50, (8, 3))
    rot = Rotation.from_euler("XYZ", [0.05, 0.02, -1.0]).as_matrix()
    ground = 2.0 * model @ rot.T + [*CENTRES[epsg], 300.0]
    (folder / "model.csv").write_text("id,X,Y,Z\n" + "".join(
        f"p{k},{x},{y},{z}\n" for k, (x, y, z) in enumerate(model)))
    (folder / "control.csv").write_text("id,X,Y,Z\n" + "".join(
        f"p{k},{x:.4f},{y:.4f},{z:.4f}\n" for k, (x, y, z) in enumerate(ground)))
    if prj_epsg is not None:
        shutil.copy(gdal_prj(folder, prj_epsg), folder / "control.prj")
    return folder / "model.csv", folder / "control.csv", ground


def test_absolute_refuses_an_ed50_prj_under_crs_32632(tmp_path):
    model, control, ground = tables(tmp_path, 32632, 23032)
    code, _, err = cli("run", "orientation:absolute", "--INPUT", model, "--CONTROL", control,
                       "--CRS", "EPSG:32632", "--REPORT", tmp_path / "r.json")
    assert code == 2, err
    line = one_error(err)
    assert "EPSG:23032" in line and "EPSG:32632" in line and "control.prj" in line, line
    # the shift: pyproj's ED50 -> WGS 84 of the centroid (on the grid; the message measures on
    # the ellipsoid: within the scale factor, 0.9996-1.0004 here)
    x, y = ground[:, :2].mean(axis=0)
    x2, y2 = Transformer.from_crs(23032, 32632, always_xy=True).transform(x, y)
    expected = math.hypot(x2 - x, y2 - y)
    shift = float(re.search(r"move by ([0-9.]+) m", line).group(1))
    assert 200 < expected < 230 and shift == pytest.approx(expected, rel=1e-3), (shift, expected)
    assert not (tmp_path / "r.json").exists()


def test_models_refuses_an_ed50_prj_under_crs_32632(tmp_path):
    _, control, _ = tables(tmp_path, 32632, 23032)
    (tmp_path / "models.csv").write_text("model,point_id,x,y,z\n" + "".join(
        f"m{m},p{k},{k * 10.0 + m},{k * 3.0},{k * 1.0}\n" for m in (1, 2) for k in range(8)))
    code, _, err = cli("run", "orientation:models", "--INPUT", tmp_path / "models.csv",
                       "--CONTROL", control, "--CRS", "EPSG:32632",
                       "--OUTPUT", tmp_path / "o.gpkg", "--REPORT", tmp_path / "r.json")
    assert code == 2, err
    line = one_error(err)
    assert "EPSG:23032" in line and "EPSG:32632" in line and " m from one" in line, line


def test_rpc_control_refuses_an_ed50_prj(tmp_path):
    """The RPC ortho's GCPs (ortho:photo, ortho:batch): checked before the measurements are
    read."""
    from toolbox.ui.photogrammetry import rpc_gcps

    _, control, _ = tables(tmp_path, 32632, 23032)
    with pytest.raises(InputDataError, match=r"EPSG:23032 but CRS is EPSG:32632.* m from"):
        rpc_gcps({"CONTROL": control, "MEASUREMENTS": tmp_path / "none.csv"},
                 CRS.from_epsg(32632))


@pytest.mark.parametrize("epsg", [3003, 32632, 6707])
def test_gdal_esri_prj_of_the_same_crs_passes(tmp_path, epsg):
    model, control, ground = tables(tmp_path, epsg, epsg)
    own = CRS.from_wkt((tmp_path / "control.prj").read_text())
    out = toolbox.run("orientation:absolute", {
        "INPUT": model, "CONTROL": control, "CRS": f"EPSG:{epsg}",
        "OUTPUT": tmp_path / "o.gpkg", "REPORT": tmp_path / "r.json"})
    assert out["STATISTICS"]["sigma0"] < 1e-3
    assert pyogrio.read_info(tmp_path / "o.gpkg")["crs"] == f"EPSG:{epsg}"
    if epsg == 6707:  # the case a comparison of definitions refuses
        assert not own.equals(CRS.from_epsg(epsg))


def test_prj_without_crs_is_the_tables_crs(tmp_path):
    """No CRS: the ``.prj``'s CRS is the control's (the output was written without a CRS)."""
    model, control, _ = tables(tmp_path, 3003, 3003)
    toolbox.run("orientation:absolute", {"INPUT": model, "CONTROL": control,
                                         "OUTPUT": tmp_path / "o.gpkg",
                                         "REPORT": tmp_path / "r.json"})
    written = CRS.from_user_input(pyogrio.read_info(tmp_path / "o.gpkg")["crs"])
    assert written.to_epsg() == 3003


@pytest.mark.parametrize(("prj_epsg", "refused"), [(6707, False), (23032, True)])
def test_bundle_judges_a_control_prj_by_the_shift_too(tmp_path, prj_epsg, refused):
    """orientation:bundle's own check of a CONTROL ``.prj`` against PROJECT compared the
    definitions: GDAL's ESRI ``.prj`` of EPSG:6707 beside control in a project in EPSG:6707
    was refused ("CONTROL is in RDN2008 / UTM zone 32N (N-E) but PROJECT is in EPSG:6707");
    an ED50 one still is."""
    from toolbox.errors import ParameterError
    from toolbox.registry import get

    _, control, ground = tables(tmp_path, 6707, prj_epsg)
    bundle = get("orientation:bundle")()
    feedback = toolbox.Feedback()
    if refused:
        with pytest.raises(ParameterError, match="EPSG:23032 but PROJECT is in EPSG:6707"):
            bundle._check_crs("CONTROL", control, "EPSG:6707", ground[:, :2], feedback)
    else:
        bundle._check_crs("CONTROL", control, "EPSG:6707", ground[:, :2], feedback)
        assert not CRS.from_wkt((tmp_path / "control.prj").read_text()).equals(
            CRS.from_epsg(6707))
