"""Bundle block adjustment benchmark: a synthetic block of many photos and tie points.

    .venv/bin/python bench/bundle_bench.py                         # 1,000 photos, 100,000 points
    .venv/bin/python bench/bundle_bench.py --strips 4 --photos 5 --points 2000   # a quick check

The block: ``strips`` x ``photos`` vertical digital frames (c = 153 mm, 0.012 mm pixels,
1:10,000, 60/25 % overlap, strips flown both ways) over hilly terrain, ``points`` tie points at
random ground positions, each imaged on every photo that sees it through the toolbox's camera
chain, 0.3 px noise; full control points at the block's corners and every 4th model along the
edges. Start values: the truth disturbed by 5 m and 5 mrad, points by 5 m. The adjustment runs
without data snooping and precision (pure solve; precision needs the dense reduced inverse,
6·photos squared). Measured: wall time of the adjustment and the process's peak resident memory
(``ru_maxrss``), plus the result against the truth. ``*_cpu_s``: the CPU time of the adjustment
(process time summed over threads: the compiled kernels of the linearisation and of the Schur
complement run on both cores, BLAS on one; on a shared machine the CPU time is closer to what a
quiet one would take than the wall time).

``--pycolmap PYTHON``: the same observations and start values handed to pycolmap's bundle
adjustment (COLMAP, Ceres; ``bench/pycolmap_ba.py``) in an interpreter that has pycolmap (a
scratch venv: ``python -m venv /tmp/colmap && /tmp/colmap/bin/pip install pycolmap``), with the
control points held fixed there (COLMAP has no weighted ground observations), fixed intrinsics:
its adjust time, the time ratio and the largest difference of the projection centres.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def make_observations(strips: int, photos: int, n_points: int, seed: int = 0):
    from scipy.spatial import cKDTree

    from toolbox.photogrammetry.camera import Camera
    from toolbox.photogrammetry.exterior import ExteriorOrientation
    from toolbox.photogrammetry.photo import Photo
    from toolbox.triangulation.synthetic import terrain_height

    rng = np.random.default_rng(seed)
    c, scale, frame, pixel = 153.0, 10000.0, 230.0, 0.012
    foot = frame * scale / 1000.0
    base, spacing = 0.4 * foot, 0.75 * foot
    camera = Camera("digital", c, (0.0, 0.0), image_size_px=(19167, 19167), pixel_size_mm=pixel,
                    frame_size_mm=(frame, frame))
    truth = []
    for s in range(strips):
        for k in range(photos):
            truth.append([k * base + rng.normal(0, 10), -s * spacing + rng.normal(0, 10),
                          c * scale / 1000.0 + 300.0 + rng.normal(0, 10),
                          *rng.normal(0, 0.01, 2), (0.0 if s % 2 == 0 else np.pi) +
                          rng.normal(0, 0.01)])
    truth = np.array(truth)
    xs = rng.uniform(-0.45 * foot, (photos - 1) * base + 0.45 * foot, n_points)
    ys = rng.uniform(-(strips - 1) * spacing - 0.45 * foot, 0.45 * foot, n_points)
    pts = np.column_stack([xs, ys, terrain_height(xs, ys, 300.0, 150.0, (0.0, 0.0))])
    tree = cKDTree(pts[:, :2])
    obs_photo, obs_point, obs_xy = [], [], []
    for j, eo in enumerate(truth):
        photo = Photo(str(j), camera, ExteriorOrientation(str(j), *map(float, eo)))
        near = np.array(tree.query_ball_point(eo[:2], 0.75 * foot), dtype=np.int64)
        mm = photo.ground_to_image(pts[near], behind="nan")
        inside = (np.abs(mm) < 0.47 * frame).all(axis=1)
        obs_photo.append(np.full(inside.sum(), j))
        obs_point.append(near[inside])
        obs_xy.append(mm[inside])
    obs_photo = np.concatenate(obs_photo)
    obs_point = np.concatenate(obs_point)
    obs_xy = np.concatenate(obs_xy) + rng.normal(0, 0.3 * pixel, (len(obs_photo), 2))
    rays = np.bincount(obs_point, minlength=n_points)
    keep_pt = rays >= 2
    remap = np.cumsum(keep_pt) - 1
    sel = keep_pt[obs_point]
    return (camera, truth, pts[keep_pt], obs_photo[sel], remap[obs_point[sel]], obs_xy[sel],
            0.3 * pixel)


def control_points(pts: np.ndarray, count: int = 12) -> np.ndarray:
    lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)
    targets = [(x, y) for x in np.linspace(lo[0], hi[0], max(2, count // 4 + 1))
               for y in (lo[1], hi[1])] + [(lo[0], 0.5 * (lo[1] + hi[1])),
                                           (hi[0], 0.5 * (lo[1] + hi[1]))]
    from scipy.spatial import cKDTree

    return np.unique(cKDTree(pts[:, :2]).query(np.array(targets))[1])


def _pycolmap(python: str, camera, ext0, pts0, ph, pt, xy, ctrl, pts) -> dict:
    """Run bench/pycolmap_ba.py in ``python`` on the same observations; adjusted centres."""
    import subprocess
    import tempfile

    from toolbox.photogrammetry.rotation import rotation_matrix

    flip = np.diag([1.0, -1.0, -1.0])
    origin = np.round(pts0.mean(axis=0))
    rot = rotation_matrix(ext0[:, 3], ext0[:, 4], ext0[:, 5])
    r_cw = flip @ np.transpose(rot, (0, 2, 1))  # p_cam = F·Rᵀ·(P - C)
    t_cw = -np.einsum("nij,nj->ni", r_cw, ext0[:, :3] - origin)
    size = camera.image_size_px
    ps = camera.pixel_size_mm
    uv = np.column_stack([xy[:, 0] / ps + size[0] / 2, -xy[:, 1] / ps + size[1] / 2])
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        start = pts0.copy()
        start[ctrl] = pts[ctrl]  # control held fixed at its surveyed position
        np.savez(src, f_px=camera.c / ps, cx=size[0] / 2, cy=size[1] / 2, width=size[0],
                 height=size[1], R_cw=r_cw, t_cw=t_cw, points=start - origin, obs_photo=ph,
                 obs_point=pt, obs_uv=uv, constant=ctrl)
        script = Path(__file__).with_name("pycolmap_ba.py")
        subprocess.run([python, str(script), str(src), str(dst)], check=True)
        out = np.load(dst)
        centres = -np.einsum("nji,nj->ni", out["R_cw"], out["t_cw"]) + origin
        return {"centres": centres, "seconds": float(out["seconds"]),
                "cpu_seconds": float(out["cpu_seconds"])}


def run(args) -> dict:
    from toolbox.triangulation.adjust import adjust
    from toolbox.triangulation.block import Block, Options

    t0 = time.perf_counter()
    camera, truth, pts, ph, pt, xy, sigma = make_observations(args.strips, args.photos,
                                                              args.points, args.seed)
    t_make = time.perf_counter() - t0
    ctrl = control_points(pts)
    n = len(truth)
    block = Block([str(j) for j in range(n)], np.zeros(n, dtype=np.int64), ["digital"],
                  [[camera.c, 0, 0, 0, 0, 0, 0, 0]], [f"t{k}" for k in range(len(pts))], ph, pt,
                  xy, np.full((len(xy), 2), sigma), ground_point=ctrl, ground_xyz=pts[ctrl],
                  ground_sigma=np.full((len(ctrl), 3), 0.01))
    rng = np.random.default_rng(1)
    ext0 = truth + np.column_stack([rng.normal(0, 5, (n, 3)), rng.normal(0, 0.005, (n, 3))])
    pts0 = pts + rng.normal(0, 5, pts.shape)
    t1, c1 = time.perf_counter(), time.process_time()
    sol = adjust(block, ext0, pts0, Options(snooping=False, precision=False))
    t_adjust, c_adjust = time.perf_counter() - t1, time.process_time() - c1
    d = sol.exterior[:, :3] - truth[:, :3]
    colmap = None
    if args.pycolmap:
        colmap = _pycolmap(args.pycolmap, camera, ext0, pts0, ph, pt, xy, ctrl, pts)
    result = {"photos": n, "points": len(pts), "image_observations": len(xy),
              "control_points": len(ctrl), "generate_s": round(t_make, 2),
              "adjust_s": round(t_adjust, 2), "adjust_cpu_s": round(c_adjust, 2),
              "iterations": sol.iterations,
              "sigma0": round(sol.sigma0, 4),
              "rms_centre_error_m": round(float(np.sqrt((d ** 2).mean())), 4),
              "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}
    if colmap is not None:
        centres = colmap["centres"]
        result["pycolmap_adjust_s"] = round(colmap["seconds"], 2)
        result["pycolmap_adjust_cpu_s"] = round(colmap["cpu_seconds"], 2)
        result["time_ratio_ours_to_pycolmap"] = round(t_adjust / colmap["seconds"], 2)
        result["pycolmap_rms_centre_error_m"] = round(
            float(np.sqrt(((centres - truth[:, :3]) ** 2).mean())), 4)
        result["max_centre_difference_m"] = round(
            float(np.abs(centres - sol.exterior[:, :3]).max()), 4)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--strips", type=int, default=20)
    parser.add_argument("--photos", type=int, default=50, help="photos per strip")
    parser.add_argument("--points", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--pycolmap", default=None,
                        help="python interpreter with pycolmap: compare with its adjustment")
    parser.add_argument("--json", type=Path, default=None, help="write the result here")
    args = parser.parse_args()
    result = run(args)
    text = json.dumps(result, indent=2)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")


if __name__ == "__main__":
    main()
