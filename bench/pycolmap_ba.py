"""pycolmap (COLMAP/Ceres) bundle adjustment of observations exported by bundle_bench.py.

Runs in an interpreter that has pycolmap (a scratch venv; not a toolbox dependency):

    /path/to/venv/bin/python bench/pycolmap_ba.py IN.npz OUT.npz

IN.npz: ``f_px, cx, cy, width, height`` (one pinhole camera, fixed), ``R_cw`` (n, 3, 3),
``t_cw`` (n, 3) start poses (OpenCV/COLMAP camera frame, local ground coordinates),
``points`` (P, 3) start points, ``obs_photo, obs_point`` (m,), ``obs_uv`` (m, 2) pixels,
``constant`` (c,) indices of points held fixed (the control: COLMAP has no weighted ground
observations). OUT.npz: adjusted ``R_cw, t_cw, points``, ``seconds`` and ``cpu_seconds`` (the
adjustment only; CPU time of all threads).
"""

from __future__ import annotations

import sys
import time

import numpy as np


def main(src: str, dst: str) -> None:
    import pycolmap

    d = np.load(src)
    rec = pycolmap.Reconstruction()
    cam = pycolmap.Camera(model="SIMPLE_PINHOLE", width=int(d["width"]), height=int(d["height"]),
                          params=[float(d["f_px"]), float(d["cx"]), float(d["cy"])], camera_id=1)
    rec.add_camera_with_trivial_rig(cam)
    obs_photo, obs_point, uv = d["obs_photo"], d["obs_point"], d["obs_uv"]
    order = np.argsort(obs_photo, kind="stable")
    index_in_image = np.empty(len(order), dtype=np.int64)
    n = len(d["R_cw"])
    for j in range(n):
        rows = order[obs_photo[order] == j]
        index_in_image[rows] = np.arange(len(rows))
        image = pycolmap.Image(name=str(j), keypoints=uv[rows], camera_id=1, image_id=j + 1)
        pose = pycolmap.Rigid3d(np.column_stack([d["R_cw"][j], d["t_cw"][j]]))
        rec.add_image_with_trivial_frame(image, pose)
    point_ids = []
    by_point = np.argsort(obs_point, kind="stable")
    starts = np.searchsorted(obs_point[by_point], np.arange(len(d["points"]) + 1))
    for k, xyz in enumerate(d["points"]):
        rows = by_point[starts[k]:starts[k + 1]]
        track = pycolmap.Track([pycolmap.TrackElement(int(obs_photo[r]) + 1,
                                                      int(index_in_image[r])) for r in rows])
        point_ids.append(rec.add_point3D(xyz, track))
    options = pycolmap.BundleAdjustmentOptions()
    options.refine_focal_length = False
    options.refine_principal_point = False
    options.refine_extra_params = False
    config = pycolmap.BundleAdjustmentConfig()
    for j in range(n):
        config.add_image(j + 1)
    config.set_constant_cam_intrinsics(1)
    for k in d["constant"]:
        config.add_constant_point(point_ids[int(k)])
    adjuster = pycolmap.create_default_bundle_adjuster(options, config, rec)
    t0, c0 = time.perf_counter(), time.process_time()
    adjuster.solve()
    seconds, cpu_seconds = time.perf_counter() - t0, time.process_time() - c0
    r_cw = np.array([rec.image(j + 1).cam_from_world().rotation.matrix() for j in range(n)])
    t_cw = np.array([rec.image(j + 1).cam_from_world().translation for j in range(n)])
    pts = np.array([rec.point3D(i).xyz for i in point_ids])
    np.savez(dst, R_cw=r_cw, t_cw=t_cw, points=pts, seconds=seconds, cpu_seconds=cpu_seconds)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
