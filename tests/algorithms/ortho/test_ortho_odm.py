"""ortho:batch on real drone photos with an OpenSfM Brown camera (Orthority's odm/ test data: 4
DJI frames, reconstruction.json, ODM's DSM). The project YAML is written here from
reconstruction.json by a minimal loader (the product's reader is orientation:convert's);
the check is the block's own consistency: where two orthos overlap, phase correlation
(scikit-image) finds them within a cell of each other, and without the lens model (the same
camera as a pinhole) they are tens of cells apart."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
import rasterio
import yaml

import toolbox

CELL = 0.3
PATCH = 32


def project_from_reconstruction(data: Path, path: Path, pinhole: bool = False) -> Path:
    """OpenSfM shots (axis-angle world -> camera rotation R_cw in OpenCV's camera frame,
    translation t; centre -R_cwᵀ·t in the topocentric frame of reference_lla, placed at the
    reference's UTM coordinates as ODM and Orthority do) -> the product's exterior
    orientation (R = R_cwᵀ·diag(1, -1, -1)) and camera spec."""
    import cv2
    from pyproj import Transformer

    from toolbox.cameras import from_opensfm
    from toolbox.photogrammetry.exterior import ExteriorOrientation

    rec = json.loads((data / "opensfm" / "reconstruction.json").read_text())[0]
    lla = rec["reference_lla"]
    origin = Transformer.from_crs("EPSG:4979", "EPSG:32651", always_xy=True).transform(
        lla["longitude"], lla["latitude"], lla["altitude"])
    cameras = []
    for name, camera in rec["cameras"].items():
        spec = from_opensfm(camera, name)
        if pinhole:
            spec = {k: v for k, v in spec.items() if k in ("im_size", "focal_len", "cx", "cy")}
            spec["type"] = "pinhole"
        cameras.append({"name": name, "model": spec})
    photos = []
    for name, shot in rec["shots"].items():
        r_cw = cv2.Rodrigues(np.array(shot["rotation"]))[0]
        centre = -r_cw.T @ np.array(shot["translation"]) + origin
        eo = ExteriorOrientation.from_matrix(name, centre, r_cw.T @ np.diag([1.0, -1.0, -1.0]))
        stem = Path(name).stem
        photos.append({"id": stem, "camera": shot["camera"],
                       "image": str(data / "images" / f"{stem}.tif"),
                       "exterior": {"X0": eo.x0, "Y0": eo.y0, "Z0": eo.z0, "omega": eo.omega,
                                    "phi": eo.phi, "kappa": eo.kappa}})
    path.write_text(yaml.safe_dump({"crs": "EPSG:32651", "angle_unit": "rad",
                                    "cameras": cameras, "photos": photos}, sort_keys=False))
    return path


def overlap_shifts(paths: list[Path]) -> dict[tuple[str, str], np.ndarray]:
    """Per overlapping pair, the phase-correlation shift (cells) of every patch valid in
    both (the orthos share one lattice, so windows of the same bounds align)."""
    from rasterio.windows import from_bounds
    from skimage.registration import phase_cross_correlation

    out = {}
    for a, b in itertools.combinations(paths, 2):
        with rasterio.open(a) as sa, rasterio.open(b) as sb:
            left, bottom = max(sa.bounds.left, sb.bounds.left), max(sa.bounds.bottom,
                                                                     sb.bounds.bottom)
            right, top = min(sa.bounds.right, sb.bounds.right), min(sa.bounds.top, sb.bounds.top)
            if left >= right or bottom >= top:
                continue
            da = sa.read(window=from_bounds(left, bottom, right, top, sa.transform)
                         .round_offsets().round_lengths()).astype(float)
            db = sb.read(window=from_bounds(left, bottom, right, top, sb.transform)
                         .round_offsets().round_lengths()).astype(float)
        h, w = min(da.shape[1], db.shape[1]), min(da.shape[2], db.shape[2])
        ok = (da[3, :h, :w] == 255) & (db[3, :h, :w] == 255)
        ga, gb = da[:3, :h, :w].mean(axis=0), db[:3, :h, :w].mean(axis=0)
        shifts = []
        for i in range(0, h - PATCH, PATCH):
            for j in range(0, w - PATCH, PATCH):
                p = (slice(i, i + PATCH), slice(j, j + PATCH))
                if ok[p].all():
                    s, _, _ = phase_cross_correlation(ga[p], gb[p], upsample_factor=20,
                                                      normalization=None)
                    shifts.append(float(np.hypot(*s)))
        if len(shifts) >= 5:
            out[(a.stem, b.stem)] = np.array(shifts)
    return out


@pytest.fixture(scope="module")
def odm(orthority_data):
    return orthority_data / "odm"


def run_block(odm: Path, folder: Path, pinhole: bool = False) -> dict:
    folder.mkdir()
    project = project_from_reconstruction(odm, folder / "project.yaml", pinhole)
    return toolbox.run("ortho:batch", {"PROJECT": project, "DEM": odm / "odm_dem" / "dsm.tif",
                                       "CELL_SIZE": CELL, "FOLDER": str(folder / "orthos"),
                                       "OUTPUT": folder / "batch.json"})


def test_drone_block_orthos_agree_where_they_overlap(odm, tmp_path):
    out = run_block(odm, tmp_path / "brown")
    assert out["STATISTICS"]["done"] == 4 and out["STATISTICS"]["failed"] == 0
    orthos = sorted((tmp_path / "brown" / "orthos").glob("*.tif"))
    with rasterio.open(orthos[0]) as src:
        assert src.count == 4 and src.crs.to_epsg() == 32651 and src.res == (CELL, CELL)
    shifts = overlap_shifts(orthos)
    assert len(shifts) >= 4, list(shifts)
    for pair, s in shifts.items():
        assert np.median(s) < 1.0, (pair, np.median(s))  # within a cell
        assert (s < 1.0).mean() > 0.5, (pair, (s < 1.0).mean())
    # without the lens model the same block falls apart by many cells
    run_block(odm, tmp_path / "pinhole", pinhole=True)
    wrong = overlap_shifts(sorted((tmp_path / "pinhole" / "orthos").glob("*.tif")))
    assert np.median(np.concatenate(list(wrong.values()))) > 5.0
