"""orientation:control with a reference orthophoto in another CRS (round 19, crsmix): the one
error line names both CRSs by their codes; before, it printed the ortho's whole WKT
(``ORTHO is in PROJCS["WGS 84 / UTM zone 32N",GEOGCS[...`` over several hundred characters)."""

from __future__ import annotations

import rasterio
from test_control_ortho import scene  # noqa: F401  (the module's scene, reused)


def test_control_ortho_in_another_crs_names_both_codes(scene, tmp_path):  # noqa: F811
    from conftest import run_cli
    from rasterio.warp import calculate_default_transform, reproject

    other = tmp_path / "ortho_utm.tif"  # the ortho warped to UTM 32N (inside its area of use)
    with rasterio.open(scene["folder"] / "ortho.tif") as src:
        transform, width, height = calculate_default_transform(
            src.crs, "EPSG:32632", src.width, src.height, *src.bounds)
        profile = {**src.profile, "crs": "EPSG:32632", "transform": transform,
                   "width": width, "height": height}
        with rasterio.open(other, "w", **profile) as dst:
            for band in range(1, src.count + 1):
                reproject(rasterio.band(src, band), rasterio.band(dst, band))
    res = run_cli("run", "orientation:control", "--PROJECT", scene["project"], "--CONTROL",
                  scene["control"], "--ORTHO", other, "--OUTPUT", tmp_path / "template.csv")
    assert res.returncode == 2, res.stderr
    line = res.stderr.strip().splitlines()[-1]
    assert line == ("toolbox: error: ORTHO is in EPSG:32632, not in the project's CRS "
                    "(EPSG:3003): reproject it first"), line
