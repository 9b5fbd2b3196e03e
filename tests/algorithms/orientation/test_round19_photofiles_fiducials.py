"""orientation:fiducials on a paletted copy of a rendered scan (the same grey levels stored as
shuffled colour codes with a grey colour table, as a scanner's palette export): the marks must
be found where the plain TIFF's are (within 0.01 px) and where they were drawn, not reported
"covered" because the colour codes were matched as grey levels (the ortho of the same photo
reads its colours)."""

from __future__ import annotations

import json

import numpy as np
import rasterio

import toolbox
from toolbox.demo.samples import scans as sc


def test_paletted_scan_gives_the_plain_scans_marks(tmp_path):
    scan = sc.render_scan(tmp_path / "plain.tif", angle_deg=1.5)
    with rasterio.open(scan.path) as src:
        grey, profile = src.read(1), src.profile
    perm = np.random.default_rng(5).permutation(256)  # colour code perm[g] shows grey g
    with rasterio.open(tmp_path / "pal.tif", "w", **profile) as dst:
        dst.write(perm[grey].astype(np.uint8), 1)
        dst.write_colormap(1, {int(perm[g]): (g, g, g, 255) for g in range(256)})
    project = sc.project_yaml(tmp_path / "scans.yaml", {"plain": "plain.tif", "pal": "pal.tif"})
    stats = toolbox.run("orientation:fiducials", {
        "PROJECT": project, "MARK_SIZE": sc.MARK, "LINE_WIDTH": sc.LINE,
        "OUTPUT": tmp_path / "io.json"})["STATISTICS"]
    assert stats["photos"] == 2 and stats["marks_missing"] == 0
    photos = {e["photo"]: e for e in json.loads((tmp_path / "io.json").read_text())["photos"]}
    plain = {r["mark"]: (r["col_px"], r["row_px"]) for r in photos["plain"]["residuals"]}
    pal = {r["mark"]: (r["col_px"], r["row_px"]) for r in photos["pal"]["residuals"]}
    assert sorted(pal) == sorted(plain) == sorted(sc.MARKS)
    for mark, centre in scan.centres.items():
        assert np.hypot(*np.subtract(pal[mark], plain[mark])) <= 0.01, mark
        assert np.hypot(*np.subtract(pal[mark], centre)) <= 0.3, mark  # the drawn centre
