"""The EXIF-orientation warning of a photo (toolbox/raster/photo_grid.py) reaches the run's
feedback: ``toolbox.run(..., feedback=f)`` callers find it in ``f.warnings``. It was a Python
``UserWarning``: not in the feedback's warnings (the CLI showed it labelled by the module that
warned: "(fiducials)", "(warp)")."""

from __future__ import annotations

import json

import rasterio
from PIL import Image

import toolbox
from tests.helpers_cli import cli
from toolbox.demo.samples import scans as sc


def turned_jpeg_scan(folder):
    """A rendered scan written as a JPEG whose EXIF says "rotate 90 CW to view" (tag 6)."""
    rendered = sc.render_scan(folder / "upright.tif", angle_deg=1.5)
    with rasterio.open(rendered.path) as src:
        grey = src.read(1)
    image = Image.fromarray(grey)
    exif = image.getexif()
    exif[0x0112] = 6
    image.save(folder / "turned.jpg", exif=exif, quality=100)
    with rasterio.open(folder / "turned.jpg") as src:  # GDAL reads the tag, keeps the grid
        assert src.tags().get("EXIF_Orientation") == "6" and src.read(1).shape == grey.shape
    return sc.project_yaml(folder / "scans.yaml", {"upright": "turned.jpg"})


def test_exif_orientation_warning_is_in_the_feedback(tmp_path):
    project = turned_jpeg_scan(tmp_path)
    feedback = toolbox.Feedback()
    toolbox.run("orientation:fiducials", {"PROJECT": project, "MARK_SIZE": sc.MARK,
                                          "LINE_WIDTH": sc.LINE, "OUTPUT": tmp_path / "io.json"},
                feedback=feedback)
    exif = [w for w in feedback.warnings if "EXIF Orientation 6" in w]
    assert len(exif) == 1 and "turned.jpg" in exif[0], feedback.warnings
    assert exif[0].endswith("the pixels are used as stored, not turned; image measurements and "
                            "camera files must refer to the stored grid")


def test_exif_orientation_warning_is_in_the_run_report(tmp_path):
    project = turned_jpeg_scan(tmp_path)
    code, _, err = cli("run", "--run-report", tmp_path / "run.json", "orientation:fiducials",
                       "--PROJECT", project, "--MARK_SIZE", sc.MARK, "--LINE_WIDTH", sc.LINE,
                       "--OUTPUT", tmp_path / "io.json")
    assert code == 0, err
    line = [ln for ln in err.splitlines() if "EXIF Orientation 6" in ln]
    # one line, not labelled by the module that warned ("... stored grid (fiducials)")
    assert len(line) == 1 and line[0].endswith("must refer to the stored grid"), err
    report = json.loads((tmp_path / "run.json").read_text())
    assert [w for w in report["warnings"] if "EXIF Orientation 6" in w] == \
        [line[0].split("WARNING: ", 1)[-1]], report["warnings"]
    assert json.loads((tmp_path / "io.json").read_text())["photos"][0]["marks"] == 8
