"""A paletted TEMPLATE of the fiducial mark (orientation:fiducials) is read as its colours, as
the scans are (toolbox/raster/photo_grid.py), not as its colour codes: a mark drawn with code 0
= light grey on code 1 = dark grey was read as a dark mark on a light ground (the negative of
the scan's mark), and with POLARITY bright no mark was found (exit 2, "no photo could be
fitted")."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
import rasterio

from tests.helpers_cli import cli
from toolbox.demo.samples import scans as sc


@pytest.fixture(scope="module")
def scan(tmp_path_factory):
    folder = tmp_path_factory.mktemp("palette_template")
    rendered = sc.render_scan(folder / "upright.tif", angle_deg=1.5)
    return sc.project_yaml(folder / "scans.yaml", {"upright": rendered.path.name}), rendered


def paletted_mark(path):
    from toolbox.matching.marks import draw

    mark = draw("cross", sc.MARK, sc.LINE, sc.PIXEL)
    codes = np.where(mark > 0.5, 0, 1).astype("uint8")  # code 0 the mark, code 1 the ground
    with rasterio.open(path, "w", driver="GTiff", width=codes.shape[1], height=codes.shape[0],
                       count=1, dtype="uint8") as dst:
        dst.write(codes, 1)
        dst.write_colormap(1, {0: (190, 190, 190, 255), 1: (40, 40, 40, 255)})
    return path


def test_paletted_template_is_read_as_its_colours(tmp_path):
    from toolbox.matching.marks import read_template

    path = paletted_mark(tmp_path / "mark_pal.tif")
    rgb = tmp_path / "mark_rgb.tif"  # GDAL's own expansion: the reference
    subprocess.run(["gdal_translate", "-q", "-expand", "rgb", str(path), str(rgb)], check=True)
    with rasterio.open(rgb) as src:
        expected = src.read().astype("float32").mean(axis=0)
    grey, dtype = read_template(path)
    assert dtype == "uint8"
    np.testing.assert_array_equal(grey, expected)
    assert set(np.unique(grey)) == {40.0, 190.0}


def test_fiducials_match_a_paletted_template(scan, tmp_path):
    project, rendered = scan
    code, _, err = cli("run", "orientation:fiducials", "--PROJECT", project, "--TEMPLATE",
                       paletted_mark(tmp_path / "mark_pal.tif"), "--POLARITY", "bright",
                       "--OUTPUT", tmp_path / "io.json")  # bright: the codes' negative fails
    assert code == 0, err
    entry = json.loads((tmp_path / "io.json").read_text())["photos"][0]
    assert entry["marks"] == 8 and not entry.get("missing"), entry.get("missing")
    error = [np.hypot(r["col_px"] - rendered.centres[r["mark"]][0],
                      r["row_px"] - rendered.centres[r["mark"]][1]) for r in entry["residuals"]]
    assert np.sqrt(np.mean(np.square(error))) <= 0.3, error
