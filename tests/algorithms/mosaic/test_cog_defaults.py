"""Deliverables as COGs by default (issue 30): the mosaic and its source index pass the COG layout
check without asking; COG=false gives a plain tiled GeoTIFF."""

from __future__ import annotations

import sys

import mosaic_scene
import pytest
import rasterio

import toolbox
from toolbox.raster.writer import cog_problems


def test_mosaic_and_source_index_are_cogs_by_default(tmp_path_factory, tmp_path):
    orthos, _ = mosaic_scene.standard_pair(tmp_path_factory)
    inputs = [str(o.path) for o in orthos]
    toolbox.run("mosaic:build", {"INPUT": inputs, "BLEND": "none", "OUTPUT": tmp_path / "m.tif",
                                 "SOURCE_INDEX": tmp_path / "i.tif"})
    for name in ("m.tif", "i.tif"):
        assert cog_problems(tmp_path / name) == [], name
        with rasterio.open(tmp_path / name) as src:
            assert src.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") == "COG"
    toolbox.run("mosaic:build", {"INPUT": inputs, "BLEND": "none", "COG": False,
                                 "OUTPUT": tmp_path / "plain.tif"})
    with rasterio.open(tmp_path / "plain.tif") as src:
        assert src.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") != "COG"
    assert not list(tmp_path.glob(".*tiled*"))  # no intermediate left


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_FSIZE fault injection")
def test_a_cog_that_cannot_be_written_is_an_output_error(tmp_path_factory, tmp_path):
    """A full disk while the COG is made (a 20 kB file-size limit): exit 2, one line naming
    OUTPUT (not an unreadable input), nothing left."""
    import resource
    import signal
    import subprocess

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))

    orthos, _ = mosaic_scene.standard_pair(tmp_path_factory)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "toolbox.cli", "run", "mosaic:build",
                           "--INPUT", str(orthos[0].path), "--INPUT", str(orthos[1].path),
                           "--OUTPUT", str(out / "m.tif")], preexec_fn=limit,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("toolbox: error: cannot write OUTPUT"), \
        proc.stderr
    assert not out.exists() or list(out.iterdir()) == []
