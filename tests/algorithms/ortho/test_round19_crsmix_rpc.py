"""RPC GCPs (round 19, crsmix): CONTROL given as a GeoPackage layer in another CRS than the
ortho's is refused naming both CRSs; before, its X/Y columns were read as if in the ortho's CRS
(ED50 / UTM 32N numbers taken as WGS 84 / UTM 32N, about 200 m off, exit 0)."""

from __future__ import annotations

import csv

import geopandas as gpd
import numpy as np
import pytest
from pyproj import Transformer
from rpc_scene import synthetic_rpc, write_gcps, write_ramp, write_synthetic_dem  # noqa: E402

import toolbox
from toolbox.cameras import read_rpc
from toolbox.errors import InputDataError


def _as_gpkg(control_csv, path, crs):
    """CONTROL's points (EPSG:32632) converted to ``crs`` by pyproj: X/Y columns and geometry."""
    with open(control_csv, newline="") as f:
        rows = list(csv.DictReader(f))
    x, y = Transformer.from_crs("EPSG:32632", crs, always_xy=True).transform(
        [float(r["X"]) for r in rows], [float(r["Y"]) for r in rows])
    gpd.GeoDataFrame({"id": [r["id"] for r in rows], "X": x, "Y": y,
                      "Z": [float(r["Z"]) for r in rows]},
                     geometry=gpd.points_from_xy(x, y), crs=crs).to_file(path)
    return path, np.hypot(np.array(x) - [float(r["X"]) for r in rows],
                          np.array(y) - [float(r["Y"]) for r in rows])


@pytest.mark.parametrize("algorithm", ["ortho:photo", "ortho:batch"])
def test_rpc_control_layer_in_another_crs_is_refused(tmp_path, algorithm):
    write_synthetic_dem(tmp_path / "dem.tif")
    ramp = write_ramp(tmp_path / "ramp.tif", synthetic_rpc(), 1200, 1000)
    control, measured = write_gcps(tmp_path, read_rpc(ramp, "EPSG:32632"), "ramp.tif", 6, seed=8)
    ed50, offset = _as_gpkg(control, tmp_path / "control_ed50.gpkg", "EPSG:23032")
    assert (offset > 150).all()  # what a silent run would put the GCPs off by
    common = {"DEM": tmp_path / "dem.tif", "CONTROL": ed50, "MEASUREMENTS": measured,
              "CELL_SIZE": 40.0}
    if algorithm == "ortho:photo":
        params = {**common, "INPUT": ramp, "OUTPUT": tmp_path / "out.tif"}
    else:
        params = {**common, "IMAGES": tmp_path, "FOLDER": tmp_path / "orthos",
                  "OUTPUT": tmp_path / "out.json"}
    with pytest.raises(InputDataError, match="CONTROL is in EPSG:23032 but CRS is in "
                                             "EPSG:32632"):
        toolbox.run(algorithm, params)
    assert not (tmp_path / "out.tif").exists() and not (tmp_path / "out.json").exists()
    # the same points labelled with the ortho's CRS: accepted, the bias fitted on all six
    utm, _ = _as_gpkg(control, tmp_path / "control_utm.gpkg", "EPSG:32632")
    if algorithm == "ortho:photo":
        stats = toolbox.run(algorithm, {**params, "CONTROL": utm,
                                        "EXTENT": "656000,4983300,656800,4984100"})["STATISTICS"]
        assert stats["bias"]["gcps"] == 6 and stats["bias"]["rms_after_px"] < 1e-3
