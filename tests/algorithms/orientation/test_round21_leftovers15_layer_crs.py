"""A GeoPackage CONTROL layer's CRS against CRS (orientation:absolute, through
``tables.control_crs``) and against the project's (``tables.ground_points``): compared by
definition, so a layer GDAL wrote from the ESRI ``.prj`` of EPSG:6707 (``gdalsrsinfo -o
wkt_esri EPSG:6707``, GDAL 3.6.2; GDAL keeps it as "RDN2008 / UTM zone 32N (N-E)", without its
code) was refused with CRS EPSG:6707 ("reproject the inputs to one CRS first", exit 2). Now the
``.prj`` rule: one CRS when the layer's points' centroid moves by at most 1 mm; ED50 is refused
naming both CRSs and the shift, checked against ``gdaltransform``."""

from __future__ import annotations

import math

import geopandas as gpd
import numpy as np
import pyogrio
import pytest
import shapely
from pyproj import CRS
from scipy.spatial.transform import Rotation

from tests.helpers_cli import cli, one_error
from toolbox.errors import InputDataError
from toolbox.photogrammetry import tables

#: the CRS ``ogr2ogr -f GPKG -a_srs <the .prj of gdalsrsinfo -o wkt_esri EPSG:6707>``
#: stores in the GeoPackage (GDAL 3.6.2): GDAL's reading of the ESRI WKT, easting first,
#: without the code
GDAL_6707 = (
    'PROJCS["RDN2008 / UTM zone 32N (N-E)",GEOGCS["RDN2008",DATUM["Rete_Dinamica_Nazionale_2008",'
    'SPHEROID["GRS 1980",6378137,298.257222101,AUTHORITY["EPSG","7019"]],AUTHORITY["EPSG",'
    '"1132"]],PRIMEM["Greenwich",0],UNIT["Degree",0.0174532925199433]],'
    'PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],'
    'PARAMETER["central_meridian",9],PARAMETER["scale_factor",0.9996],'
    'PARAMETER["false_easting",500000],PARAMETER["false_northing",0],'
    'UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AXIS["Northing",NORTH]]')


def _tables(folder, layer_crs):
    """model.csv and control.gpkg (the model scaled, turned and moved near Siena; the layer in
    ``layer_crs``, its X, Y, Z columns as the points' coordinates)."""
    rng = np.random.default_rng(4)
    model = rng.uniform(-50, 50, (8, 3))
    rot = Rotation.from_euler("XYZ", [0.05, 0.02, -1.0]).as_matrix()
    ground = 2.0 * model @ rot.T + [688_000.0, 4_799_500.0, 300.0]
    (folder / "model.csv").write_text("id,X,Y,Z\n" + "".join(
        f"p{k},{x},{y},{z}\n" for k, (x, y, z) in enumerate(model)))
    frame = gpd.GeoDataFrame({"id": [f"p{k}" for k in range(8)], "X": ground[:, 0],
                              "Y": ground[:, 1], "Z": ground[:, 2]},
                             geometry=shapely.points(ground[:, :2]), crs=layer_crs)
    pyogrio.write_dataframe(frame, folder / "control.gpkg", layer="control")
    return folder / "model.csv", folder / "control.gpkg", ground


def test_layer_written_from_the_esri_prj_of_crs_is_crs(tmp_path):
    model, control, ground = _tables(tmp_path, GDAL_6707)
    own = tables.table_crs(control)
    assert not own.equals(CRS.from_epsg(6707))  # as GDAL stored it: not the code's definition
    assert tables.control_crs(control, CRS.from_epsg(6707)) == CRS.from_epsg(6707)
    ids, xyz, _ = tables.ground_points(control, crs=CRS.from_epsg(6707))
    assert np.allclose(xyz, ground)
    code, _, err = cli("run", "orientation:absolute", "--INPUT", model, "--CONTROL", control,
                       "--CRS", "EPSG:6707", "--REPORT", tmp_path / "r.json")
    assert code == 0, err


def test_layer_in_ed50_is_refused_naming_both_and_the_shift(tmp_path):
    """The centroid (688030.473, 4799508.676) in ED50 / UTM 32N goes to 687947.760576859
    4799312.57036894 in EPSG:6707 (``gdaltransform -s_srs EPSG:23032 -t_srs EPSG:6707``, GDAL
    3.6.2): 212.835 m on the grid, 212.828 m on the ellipsoid (scale factor 1.000034 there)."""
    model, control, ground = _tables(tmp_path, "EPSG:23032")
    x, y = ground[:, :2].mean(axis=0)
    expected = math.hypot(x - 687947.760576859, y - 4799312.57036894) / 1.000034
    with pytest.raises(InputDataError) as info:
        tables.control_crs(control, CRS.from_epsg(6707))
    message = str(info.value)
    assert message.startswith("CONTROL is in EPSG:23032 but CRS is in EPSG:6707: its points"), \
        message
    assert float(message.split("move by ")[1].split(" m")[0]) == pytest.approx(expected,
                                                                               abs=0.002)
    with pytest.raises(InputDataError, match="EPSG:23032 but the project is in EPSG:6707 "
                                             r"\(its points"):
        tables.ground_points(control, crs=CRS.from_epsg(6707))
    code, _, err = cli("run", "orientation:absolute", "--INPUT", model, "--CONTROL", control,
                       "--CRS", "EPSG:6707", "--REPORT", tmp_path / "r.json")
    assert code == 2 and "move by 212.828 m" in one_error(err)
    assert not (tmp_path / "r.json").exists()
