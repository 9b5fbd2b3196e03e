"""orientation:tiepoints - automatic tie points across a block of photos."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.feedback import Feedback
from toolbox.parameters import Boolean, Enum, File, Integer, Number, String
from toolbox.parameters.outputs import Output, OutputFile
from toolbox.registry import register
from toolbox.ui.execution import executor_of, scheduler_parameter
from toolbox.ui.photogrammetry import project_parameter, report_output


@register
class TiePoints(Algorithm):
    """Automatic tie points across a block: features, matches, tracks, thinning, refinement.

    Photos come from PROJECT (every photo with an ``image``; cameras and, when present,
    exterior orientations) or from the image files of the folder IMAGES (ids = file names
    without suffix; no camera). Pairs (PAIR_SELECTION auto picks the first that applies):
    footprints: with oriented photos and TERRAIN_HEIGHT, those whose footprints on the plane at
    that height overlap by MIN_OVERLAP percent; neighbours: with approximate positions (the
    POSITIONS GNSS log, PROJECT's orientations, or EXIF GPS tags in every image), each photo
    with its NEIGHBOURS nearest photos plus the edges of the positions' Delaunay triangulation
    (about 8-10 pairs a photo instead of all of them); thumbnails: every pair is matched on
    thumbnails (800 px) first and kept when it verifies.

    Method (OpenCV): each photo is read decimated to MAX_SIZE pixels on its longer side (area
    average; bounded memory whatever the scan size) and DETECTOR features (SIFT by default; see
    the README for the measured comparison with AKAZE and ORB) are detected in 1024-pixel tiles
    (MAX_FEATURES per photo shared by its tiles, at most 2500 each), outside a border of BORDER
    pixels (fiducial marks, data strip). Per pair: nearest neighbours
    with Lowe's ratio test (RATIO) and a mutual check, then USAC/MAGSAC++ on the essential
    matrix when both photos have a camera (pixel -> camera mm through the interior orientation,
    principal point, distortion), else on the fundamental matrix; inlier THRESHOLD in pixels of
    the detection level. With orientations the distance of each match from the epipolar plane
    of the orientations is reported per pair, and matches farther than EPIPOLAR_TOLERANCE px
    are dropped when it is given. Photos are detected, pairs matched and tracks refined on
    local threads or, with SCHEDULER, on a Dask cluster (each worker reads its photos by their
    paths; only features and tracks travel; results in order: the same output). Tracks by
    union-find; a track with two points on one photo, or that disagrees with the epipolar
    geometry of any pair of its photos, is dropped. Thinning: about TARGET Gruber-like cells
    per model (photo pair), each keeping its best track (most photos first, then smallest
    residual). REFINE: each kept observation is refined against the
    track's first one by normalised cross-correlation of 21 x 21 full-resolution patches
    resampled by the local affine of the neighbouring matches (quadratic sub-pixel peak); an
    observation whose peak is below MIN_NCC is dropped.

    OUTPUT: image measurements, one row per point per photo (``point_id``, ``photo``,
    ``col_px``, ``row_px``: columns right, rows down, top-left pixel centre at (0.5, 0.5);
    ``sigma_px``: 0.5 refined, else half a detection-level pixel), the format
    orientation:intersect / resection / bundle read. POINTS: tie points (PointZ by forward
    intersection where every photo of the track is oriented, with the largest reprojection
    residual; no geometry otherwise). PAIRS: per pair, candidates (ratio test), verified,
    kept, 3 x 3 cells of the overlap covered, median epipolar residual of the estimated model
    and of the orientations (px), status (ok / not_verified / no_matches). Photos in no tied
    pair are reported; no tied pair at all is an error.
    """

    id = "orientation:tiepoints"
    display_name = "Tie points (automatic)"
    group = "Orientation"
    short_help = "Automatic tie points across a block (SIFT, MAGSAC, tracks, thinning, NCC)."
    parameters = [
        project_parameter("orientation project (YAML): photos with images, cameras, orientations",
                          optional=True),
        String("IMAGES", "or a folder of images (no cameras: pairs by thumbnails)",
               optional=True, paths=True),
        File("POSITIONS", "approximate photo positions (CSV: photo and x, y planar or lon, "
             "lat degrees; a GNSS log) for choosing pairs", extensions=[".csv", ".txt"],
             optional=True),
        Enum("PAIR_SELECTION", "how pairs are chosen (auto: footprints, else neighbours, else "
             "thumbnails)", options=("auto", "footprints", "neighbours", "thumbnails"),
             default="auto"),
        Integer("NEIGHBOURS", "neighbours mode: nearest photos matched with each photo",
                default=8, min_value=1, max_value=1000),
        Enum("DETECTOR", "feature detector (akaze only with an OpenCV that has it: not 5.x)",
             options=("sift", "orb", "akaze"), default="sift"),
        Integer("MAX_SIZE", "longer side of the detection level, px", default=3000,
                min_value=200, max_value=20000),
        Integer("MAX_FEATURES", "features per photo, at most (spread over its 1024-px tiles, "
                "2500 per tile at most)", default=10000, min_value=100, max_value=1000000),
        Number("BORDER", "masked border of every photo (fiducials, data strip), full-res px",
               default=0.0, min_value=0.0),
        Number("RATIO", "Lowe's ratio test", default=0.8, min_value=0.3, max_value=0.99),
        Number("THRESHOLD", "MAGSAC inlier threshold, px of the detection level", default=1.0,
               min_value=0.1, max_value=20.0),
        Integer("MIN_MATCHES", "fewest verified matches that tie a pair", default=15,
                min_value=8),
        Integer("TARGET", "thinning cells per model (photo pair)", default=64, min_value=1,
                max_value=10000),
        Boolean("REFINE", "sub-pixel NCC refinement on full-resolution patches", default=True),
        Number("MIN_NCC", "smallest NCC peak of a refined observation", default=0.75,
               min_value=0.0, max_value=1.0),
        Number("TERRAIN_HEIGHT", "mean terrain height for the footprints (with orientations)",
               optional=True),
        Number("MIN_OVERLAP", "smallest footprint overlap of a pair, percent", default=5.0,
               min_value=0.0, max_value=100.0),
        Number("EPIPOLAR_TOLERANCE", "with orientations: drop matches farther from the epipolar "
               "plane, px", optional=True, min_value=0.0, min_exclusive=True),
        scheduler_parameter("the photos' detection, the pairs' matching and the refinement"),
        OutputFile("OUTPUT", "image measurements (CSV: point_id, photo, col_px, row_px, "
                   "sigma_px)", extensions=[".csv"]),
        # an OutputFile, not an OutputVector: test_specs requires every OutputVector to be
        # written by the demo pipeline, which has no photos to match (see the README)
        OutputFile("POINTS", "tie points (GeoPackage, layer tie_points: PointZ with point_id, "
                   "n_photos, photos, max_residual_px)", extensions=[".gpkg"], optional=True),
        OutputFile("PAIRS", "per-pair table (CSV)", extensions=[".csv"], optional=True),
        report_output("JSON summary"),
    ]
    outputs = [Output("STATISTICS", "points, observations, pairs tied, untied photos", "json")]

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        import numpy as np

        from toolbox.matching.block import TiePointOptions, tie_points
        from toolbox.matching.features import available
        from toolbox.matching.inputs import photos_from_folder, photos_from_project
        from toolbox.matching.outputs import ground_points, point_ids, write_measurements, write_pairs
        from toolbox.photogrammetry.tables import load_project_parameter, write_json

        if not available(params["DETECTOR"]):
            import cv2

            raise self.fail("DETECTOR", f"akaze is not in this OpenCV ({cv2.__version__}: "
                            "moved to opencv-contrib in OpenCV 5); use sift or orb")
        if (params["PROJECT"] is None) == (params["IMAGES"] is None):
            raise self.fail("PROJECT", "give either PROJECT (an orientation project) or IMAGES "
                            "(a folder of images), not both and not neither")
        crs = None
        if params["PROJECT"] is not None:
            project = load_project_parameter(params["PROJECT"])
            photos, skipped = photos_from_project(project)
            crs = project.crs
            if skipped:
                feedback.push_warning(f"{len(skipped)} photo(s) of PROJECT name no image and are "
                                      f"not matched: {', '.join(skipped[:10])}")
        else:
            folder = Path(params["IMAGES"]).expanduser()
            if not folder.is_dir():
                raise self.fail("IMAGES", f"must be an existing folder of images, got "
                                f"'{params['IMAGES']}'")
            photos = photos_from_folder(folder)
        if len(photos) < 2:
            raise self.fail("PROJECT" if params["PROJECT"] else "IMAGES",
                            f"needs at least two photos with an image, found {len(photos)}")
        positions = None
        if params["POSITIONS"] is not None:
            from toolbox.matching.positions import read_positions

            positions = read_positions(params["POSITIONS"], [bp.id for bp in photos])
        opts = TiePointOptions(
            detector=params["DETECTOR"], max_size=params["MAX_SIZE"],
            max_features=params["MAX_FEATURES"], ratio=params["RATIO"],
            f_threshold=params["THRESHOLD"], min_matches=params["MIN_MATCHES"],
            border_px=params["BORDER"], target_per_model=params["TARGET"],
            refine=params["REFINE"], min_ncc=params["MIN_NCC"],
            epipolar_tolerance=params["EPIPOLAR_TOLERANCE"], min_overlap=params["MIN_OVERLAP"],
            terrain_height=params["TERRAIN_HEIGHT"], pair_selection=params["PAIR_SELECTION"],
            neighbours=params["NEIGHBOURS"], positions=positions, executor=executor_of(params))
        with feedback.timed("tie points"):
            result = tie_points(photos, opts, lambda p, m: feedback.set_progress(0.95 * p, m))
        if result.untied:
            feedback.push_warning(f"{len(result.untied)} photo(s) tied to no other: "
                                  f"{', '.join(result.untied[:10])}")
        failed = [f"{r.a}-{r.b}" for r in result.pairs if r.status != "ok"]
        if failed:
            feedback.push_warning(f"{len(failed)} candidate pair(s) not tied: "
                                  f"{', '.join(failed[:10])}")
        rows = write_measurements(params["OUTPUT"], result)
        xyz, worst = ground_points(result)
        if params["PAIRS"] is not None:
            write_pairs(params["PAIRS"], result)
        if params["POINTS"] is not None:
            self._write_points(params["POINTS"], result, point_ids(result), xyz, worst, crs)
        finite = worst[np.isfinite(worst)]
        stats = {"points": len(result.tracks), "observations": rows,
                 "multi_ray_points": sum(len(t.photos) > 2 for t in result.tracks),
                 "pairs_tied": sum(r.status == "ok" for r in result.pairs),
                 "pairs_candidate": len(result.pairs), "pair_selection": result.pair_selection,
                 "untied_photos": result.untied,
                 "inconsistent_tracks_dropped": result.dropped_inconsistent,
                 "features": result.features, "executor": opts.executor.describe(),
                 "max_reprojection_px": float(finite.max()) if len(finite) else None,
                 "median_reprojection_px": float(np.median(finite)) if len(finite) else None}
        if params["REPORT"] is not None:
            write_json(params["REPORT"], {"algorithm": self.id, "statistics": stats,
                                          "pairs": [r.__dict__ for r in result.pairs]})
        return {"OUTPUT": params["OUTPUT"], "POINTS": params["POINTS"], "PAIRS": params["PAIRS"],
                "REPORT": params["REPORT"], "STATISTICS": stats}

    @staticmethod
    def _write_points(path, result, ids, xyz, worst, crs) -> None:
        import geopandas as gpd
        import numpy as np
        import shapely

        from toolbox.io.vector_write import write_layers

        rows = []
        for k, (pid, track) in enumerate(zip(ids, result.tracks, strict=True)):
            ok = bool(np.isfinite(xyz[k]).all())
            rows.append({"point_id": pid, "n_photos": len(track.photos),
                         "photos": ";".join(result.photos[p].id for p in track.photos),
                         "max_residual_px": float(worst[k]) if np.isfinite(worst[k]) else None,
                         "geometry": shapely.Point(xyz[k]) if ok else None})
        frame = gpd.GeoDataFrame(rows, geometry="geometry", crs=crs)
        write_layers(path, {"tie_points": frame}, crs=crs,
                     geometry_types={"tie_points": "Point Z"})
