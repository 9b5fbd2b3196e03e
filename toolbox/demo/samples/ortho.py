"""Orthophoto sample: synthetic photos of the Siena block with the real orientations.

Three photos of the case study (1_7150 and 1_7151 of strip 1, 2_7139 of strip 2, whose camera
carries the calibrated distortion table) are rendered through the collinearity equations
(:func:`toolbox.photogrammetry.synthetic.render_photo`: each pixel's ray marched down to the
sample DEM of :mod:`.terrain`) from the landscape of :mod:`.landscape` (a town, roads, fields and
woods, shaded with the DEM), so the orthos, the mosaic and the vectors can be judged by eye. The
scans are 16644 px; the samples are the same photos at 1/32 of that resolution (520 x 520 px of
0.448 mm), so their interior orientation is the real pixel -> fiducial fit composed with a scale
of 32. Exterior orientations, cameras and distortion are the block adjustment's
(``siena_project.yaml``).

Also renders all six photos of the block into ``siena_block/`` (with its ``project.yaml``), for
the tie-point, bundle, dense-matching and true-ortho steps: these see the landscape's buildings
standing (:func:`.landscape.landscape_surface`, flat roofs 7-16 m high on a 1 m surface), so
the DSM has roofs and the seams have buildings to go round. Writes ``siena_ortho/<photo>.tif``
(RGB, not georeferenced, as a scan), ``siena_ortho/project.yaml`` (an orientation project
naming them) and ``siena_ortho/camera_1_7150.yaml`` (that photo's camera alone). Deterministic.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

PHOTOS = ("1_7150", "1_7151", "2_7139")
BLOCK = ("1_7150", "1_7151", "1_7152", "2_7138", "2_7139", "2_7140")  # the whole Siena block
REDUCTION = 32
SIZE = 520  # 16644 / 32, rounded down


def texture():
    from toolbox.demo.samples.landscape import landscape_texture

    return landscape_texture()


def demo_project(target: Path, photo_ids=PHOTOS):
    """The Siena project restricted to ``photo_ids``, at 1/32 of the scan resolution."""
    from dataclasses import replace

    from toolbox.demo.samples.siena import BUNDLED
    from toolbox.photogrammetry.fiducials import InteriorOrientation
    from toolbox.photogrammetry.project import Project, load_project

    project = load_project(BUNDLED / "siena_project.yaml")
    scale = np.diag([float(REDUCTION), float(REDUCTION), 1.0])
    cameras, photos = {}, {}
    for pid in photo_ids:
        photo = project.photo(pid)
        cam = photo.camera
        cameras[cam.name] = replace(cam, image_size_px=(SIZE, SIZE),
                                    pixel_size_mm=cam.pixel_size_mm * REDUCTION)
        interior = InteriorOrientation(photo.interior.pixel_to_fiducial @ scale,
                                       photo.interior.transformation)
        photos[pid] = replace(photo, camera=cameras[cam.name], interior=interior,
                              image=target / f"{pid}.tif")
    return Project(project.crs, cameras, photos)


def make(folder: Path, made: dict) -> dict:
    from toolbox.demo.samples.landscape import landscape_surface
    from toolbox.demo.samples.terrain import terrain
    from toolbox.photogrammetry.project import save_project
    from toolbox.photogrammetry.synthetic import render_photo, write_photo

    paint = texture()
    projects = {}
    # the three photos on the terrain (the ortho tests compare their orthos with the texture);
    # the block's six on the landscape's surface, buildings standing (for the DSM, true orthos)
    for name, ids, (z, transform) in (("siena_ortho", PHOTOS, terrain()),
                                      ("siena_block", BLOCK, landscape_surface())):
        target = Path(folder) / name
        target.mkdir(parents=True, exist_ok=True)
        projects[name] = demo_project(target, ids)
        for photo in projects[name].photos.values():
            write_photo(photo.image, render_photo(photo, z, transform, paint, dtype="uint8",
                                                  fill=0))
    paths = {name: save_project(project, Path(folder) / name / "project.yaml")
             for name, project in projects.items()}
    target = Path(folder) / "siena_ortho"
    project, path = projects["siena_ortho"], paths["siena_ortho"]
    # the first photo's camera alone, for ortho:photo's CAMERA + EXTERIOR form (pixel transform
    # from the pixel size: image centre = fiducial centre)
    import yaml

    first = project.photos[PHOTOS[0]].camera.as_dict()
    first.pop("fiducials_mm", None)
    (target / f"camera_{PHOTOS[0]}.yaml").write_text(yaml.safe_dump(first, sort_keys=False))
    return {"siena_ortho_project": path, "siena_ortho_photo": target / f"{PHOTOS[0]}.tif",
            "siena_block_project": paths["siena_block"]}
