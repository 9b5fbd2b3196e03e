"""ortho:batch - orthophotos of every photo of an orientation project on one shared grid."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.errors import InputDataError, ParameterError
from toolbox.feedback import Feedback
from toolbox.parameters import (
    Boolean,
    Crs,
    Integer,
    Number,
    Output,
    OutputFile,
    OutputFolder,
    RasterLayer,
    String,
)
from toolbox.registry import register
from toolbox.ui.execution import executor_of, scheduler_parameter
from toolbox.ui.photogrammetry import (  # duplicate-ok: the same groups as ortho:photo
    dem_parameters,
    ortho_method_parameters,
    project_parameter,
    rpc_gcp_parameters,
)


@register
class OrthoBatch(Algorithm):
    """Orthophotos of a whole block: every oriented photo of PROJECT (or those listed in
    PHOTOS) orthorectified as ortho:photo does, on ONE shared grid lattice, so the orthos
    mosaic without resampling (mosaic:*).

    The cell is CELL_SIZE, default the LARGEST ground sample distance among the photos (as the
    thesis' software advises, S002 par. 3.8: uniform resolution over the block), or TEMPLATE's
    cell and lattice (CELL_SIZE is then not given: the rule of every raster output). Each ortho covers its
    photo's footprint on the DEM, with edges on the shared lattice. The photos' image files are
    the project's ``image`` paths (relative to the project file); IMAGES gives another folder
    holding them under the same file names.

    HEIGHTS: the orientations' height datum, as in ortho:photo (the DEM converted once when its
    vertical datum differs; STATISTICS ``heights`` says what was done).

    Satellite images with RPCs (GDAL's: GeoTIFF RPC tags, ``.RPB``, ``_RPC.TXT``): no PROJECT,
    IMAGES a folder of them (files without RPCs are skipped with a warning) or a comma-separated
    list (each must carry RPCs). Each image is orthorectified as ortho:photo does an RPC image
    (every cell projected exactly by the RPCs on the DEM's heights, ellipsoidal unless HEIGHTS
    says otherwise), its id the file stem, in CRS (default: the DEM's); CONTROL and
    MEASUREMENTS (``photo`` = the image's file name or stem) refine each image's RPC bias
    (BIAS), and an image without a GCP measured on it fails (the others still finish). The
    default cell is the largest GSD among the images.

    Photos run in parallel on local threads (WORKERS) or on a Dask cluster (SCHEDULER or
    DASK_SCHEDULER_ADDRESS), with one progress bar. A photo that fails (missing image, camera
    looking away, no DEM under it...) is reported and the others still finish. The orthos are
    written into FOLDER as ``<photo id>.tif``: all of them or none (they are written into a
    hidden staged folder and moved into FOLDER when the run succeeds; a run killed or out of
    disk space leaves nothing). An ortho may not replace an input (a photo, the DEM, a file of
    the project) and replaces an existing file only with --overwrite; other files of FOLDER are
    left alone. OUTPUT (JSON) lists them (``orthos``, ready for mosaic:*), with one report per
    photo (as ortho:photo's) and the failures.
    """

    crs_labels_inputs = False  # CRS is the ortho's (the DEM's is its own or the project's)

    id = "ortho:batch"
    display_name = "Orthophotos of a block"
    group = "Orthophoto"
    short_help = ("Orthorectify every photo of an orientation project, or satellite images "
                  "with RPCs, on one shared grid.")
    parameters = [
        project_parameter("orientation project (YAML or another program's file); none for "
                          "satellite images with RPCs (IMAGES)", optional=True),
        String("PHOTOS", "photo ids, comma separated (default: every oriented photo)",
               optional=True),
        String("IMAGES", "folder of the image files (default: the project's paths); without "
               "PROJECT: satellite images with RPCs, a folder or a comma-separated list",
               optional=True, paths=True),
        Crs("CRS", "RPC images: the orthos' CRS (default: the DEM's)", optional=True),
        *dem_parameters("terrain heights, any CRS"),
        String("HEIGHTS", "height datum of the orientations: 'ellipsoidal' or a vertical CRS "
               "(EPSG:3855...); default the project CRS's vertical part", optional=True),
        Number("CELL_SIZE", "ground cell size (default: the largest GSD of the photos)",
               optional=True, min_value=0, min_exclusive=True),
        RasterLayer("TEMPLATE", "align the grid to this raster's lattice and cell",
                    optional=True),
        *ortho_method_parameters(),
        Boolean("OCCLUSION", "true orthos: leave hidden cells empty", default=False),
        Boolean("COG", "write Cloud Optimized GeoTIFFs", default=False),
        Boolean("OVERVIEWS", "build internal overviews", default=True),
        Number("MAP_SCALE", "map scale denominator for the expected accuracy", optional=True,
               min_value=1),
        *rpc_gcp_parameters(),
        scheduler_parameter("the photos"),
        Integer("WORKERS", "photos in parallel on local threads", default=2, min_value=1),
        OutputFolder("FOLDER", "folder of the orthos <photo id>.tif (created if missing)"),
        OutputFile("OUTPUT", "JSON list of the orthos with the per-photo reports",
                   extensions=[".json"]),
    ]
    outputs = [Output("STATISTICS", "photos done and failed, cell size", "dict")]

    def check(self, params: dict[str, Any]) -> None:
        if params["PROJECT"] is None:
            if params["IMAGES"] is None:
                raise self.fail("PROJECT", "give PROJECT, or IMAGES with satellite images that "
                                "carry RPCs (a folder or a comma-separated list)")
            for name in ("OCCLUSION", "MAP_SCALE"):
                if params[name]:
                    raise self.fail(name, "does not apply to RPC images")
            if (params["CONTROL"] is None) != (params["MEASUREMENTS"] is None):
                raise self.fail("CONTROL", "and MEASUREMENTS go together (the GCPs of the RPC "
                                "images)")
            return
        for name in ("CRS", "CONTROL", "MEASUREMENTS"):
            if params[name] is not None:
                raise self.fail(name, "applies to RPC images only (IMAGES without PROJECT); a "
                                "project's orthos are in its CRS")

    def planned_files(self, params: dict[str, Any]) -> dict[str, list[str]]:
        """One ``<photo id>.tif`` per photo (the runner refuses one that is an input: a file
        of IMAGES, a list of IMAGES or an image the project names)."""
        if params["PROJECT"] is None:
            from toolbox.ortho.rpc_block import rpc_images, select_rpc_images

            ids = [i.id for i in select_rpc_images(rpc_images(params["IMAGES"])[0],
                                                   params["PHOTOS"])]
        else:
            ids = [p.id for p in select_photos(load_batch_project(params), params["PHOTOS"])]
        return {"FOLDER": [f"{pid}.tif" for pid in ids]}

    def process(self, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
        from toolbox.io.crs import crs_label

        if params["PROJECT"] is None:
            return rpc_batch(self.id, params, feedback)
        project = load_batch_project(params, last=True)
        crs = project.crs
        if crs is None and params["DEM"].crs is not None:  # else the orthos would have no CRS
            crs = params["DEM"].crs
            feedback.push_warning(f"PROJECT names no crs: its coordinates are taken to be in "
                                  f"the DEM's, {crs_label(crs)}, and the orthos are written in it")
        from toolbox.ortho.vertical import dem_in_photo_datum

        with dem_in_photo_datum(params["DEM"], params["BAND"], params["HEIGHTS"], crs,
                                feedback, executor_of(params), params["FOLDER"]
                                ) as (dem, band, heights):
            return self._orthos(params, feedback, project, crs, dem, band, heights)

    def _orthos(self, params: dict[str, Any], feedback: Feedback, project: Any, crs: Any,
                dem: Any, band: int, heights: Any) -> dict[str, Any]:
        """The orthos of :meth:`process` on ``dem`` (in the photos' height datum)."""
        from toolbox.executor import map_tiles
        from toolbox.io.crs import crs_label
        from toolbox.io.raster import open_raster_info
        from toolbox.ortho.block import OrthoTask, run_task
        from toolbox.ortho.metrics import nice_cell_size
        from toolbox.ortho.plan import check_geometry, lattice_grid, plan_photo, tilt_warning
        from toolbox.ortho.run import OrthoOptions
        from toolbox.photogrammetry.photo import fit_image_size
        from toolbox.raster.grid_request import template_lattice

        executor = executor_of(params)
        photos = select_photos(project, params["PHOTOS"])
        failed: list[dict[str, Any]] = []
        origin = (0.0, 0.0)
        cell = params["CELL_SIZE"]
        template = params["TEMPLATE"]
        if template is not None:
            cell, origin = template_lattice(template, cell, crs, "the project")

        def plan(photo: Any) -> tuple[Any, Any, str | None]:
            image = open_raster_info(image_path(photo, params["IMAGES"]), "IMAGES")
            photo = fit_image_size(photo, image.width, image.height, image.path)
            check_geometry(photo)
            warning = tilt_warning(photo)
            return plan_photo(photo, dem, crs, band), image, warning

        workers = executor.workers if executor.kind == "local" else 1
        plans = plan_each(photos, plan, failed, feedback, workers)
        for _, _, warning in plans:  # in the photos' order, whichever thread planned them
            if warning:
                feedback.push_warning(warning)
        if cell is None:
            cell = max(nice_cell_size(plan.gsd) for plan, _, _ in plans)
        options = OrthoOptions(
            resampling=params["RESAMPLING"], outside=params["OUTSIDE"], nodata=params["NODATA"],
            block=params["MAP_BLOCK"], tolerance_px=params["MAP_TOLERANCE"],
            dem_factor=params["DEM_FACTOR"], band=band, occlusion=params["OCCLUSION"],
            overviews=params["OVERVIEWS"], cog=params["COG"])
        folder = Path(params["FOLDER"])  # staged by the runner: moved into place on success
        tasks = [OrthoTask(plan.photo, image, dem,
                           lattice_grid(on_heights(plan.extent, plan.surface), cell, crs, origin),
                           folder / f"{plan.photo.id}.tif", options, plan.mean_height,
                           params["MAP_SCALE"], window_workers(k, len(plans), executor))
                 for k, (plan, image, _) in enumerate(plans)]
        reports = collect(map_tiles(run_task, tasks, executor=executor, feedback=feedback,
                                    total=len(tasks), start=10, end=100), failed, feedback)
        stats = {"photos": len(photos), "done": len(reports), "failed": len(failed),
                 "cell_size": cell, "crs": crs_label(crs), "executor": executor.describe(),
                 "heights": heights.as_dict()}
        return write_listing(self.id, params["OUTPUT"], reports, failed, stats)


def window_workers(index: int, count: int, executor: Any) -> int | None:
    """Threads for the windows of photo ``index`` of ``count`` on ``executor``. On local
    threads the photos already keep every thread busy, except the last ``count % workers``
    (or all of a block smaller than the pool), which may run alone: those split their windows
    on a pool of their own, the others run their windows on the photo's thread (a nested pool
    for every photo doubled the threads on the cores and their GIL hand-offs: ODM's 4 drone
    photos 1.43 -> 1.32 s, NGI 5 m 1.29 -> 1.17 s wall in one interleaved sitting, 15-20 MB less
    peak: bench/results/orthority.md). A Dask worker's photo keeps one thread per CPU of its
    worker (``None``)."""
    if executor.kind != "local":
        return None
    workers = executor.workers
    return 1 if index < count - count % workers else workers


def plan_each(items: list[Any], plan: Any, failed: list[dict[str, Any]], feedback: Feedback,
              workers: int = 1) -> list[Any]:
    """``plan(item)`` of every photo or image (progress 0-10 %), on ``workers`` threads (a
    plan is mostly NumPy and GDAL reads, which release the GIL), the results and failures in
    the items' order; one whose plan raises a user error is appended to ``failed`` and
    reported, the others go on; none planned: an error."""

    def attempt(item: Any) -> tuple[Any, Exception | None]:
        try:
            return plan(item), None
        except (InputDataError, ParameterError) as exc:
            return None, exc

    from toolbox.executor import Executor, map_tiles

    threads = Executor("local", workers if len(items) > 1 else 1)  # the photos' pool after
    plans = []
    results = map_tiles(attempt, items, executor=threads, feedback=feedback, total=len(items),
                        start=0, end=10)
    for (planned, exc), item in zip(results, items):  # the results first: the pool's exit runs
        if exc is None:
            plans.append(planned)
        else:
            failed.append({"photo": item.id, "error": str(exc)})
            feedback.push_warning(f"photo {item.id} failed: {exc}")
    if not plans:
        raise none_done(failed)
    return plans


def none_done(failed: list[dict[str, Any]]) -> InputDataError:
    """The error of a batch whose every photo failed (``failed``: their errors)."""
    return InputDataError("no photo could be orthorectified: " +
                          "; ".join(f"{f['photo']}: {f['error']}" for f in failed))


def collect(results: Any, failed: list[dict[str, Any]], feedback: Feedback
            ) -> list[dict[str, Any]]:
    """The reports of the photos done (their warnings pushed); failures appended to ``failed``.
    A batch of which no photo is done but some failed is an error (nothing is kept)."""
    from toolbox.io.staging import final_path

    reports = []
    for result in results:
        if "error" in result:
            failed.append(result)
            feedback.push_warning(f"photo {result['photo']} failed: {result['error']}")
        else:
            result["output"] = str(final_path(result["output"]))
            reports.append(result)
            for text in result.pop("warnings", []):
                if text not in feedback.warnings:  # one datum transformation for all photos
                    feedback.push_warning(text)
    if failed and not reports:
        raise none_done(failed)
    return reports


def rpc_batch(algorithm_id: str, params: dict[str, Any], feedback: Feedback) -> dict[str, Any]:
    """ortho:batch of satellite images with RPCs (IMAGES without PROJECT; the class docstring):
    each image planned (camera in CRS, GCP bias, GSD), the cell the largest GSD (or CELL_SIZE,
    TEMPLATE), every ortho on the shared lattice."""
    from toolbox.executor import map_tiles
    from toolbox.io.crs import crs_label
    from toolbox.ortho.metrics import nice_cell_size
    from toolbox.ortho.rpc import rpc_crs, rpc_plan
    from toolbox.ortho.rpc_block import (
        RpcTask,
        plan_rpc_image,
        rpc_images,
        run_rpc_task,
        select_rpc_images,
    )
    from toolbox.ortho.run import OrthoOptions
    from toolbox.ortho.vertical import dem_in_photo_datum
    from toolbox.raster.grid_request import template_lattice
    from toolbox.ui.photogrammetry import rpc_gcps

    everything, skipped = rpc_images(params["IMAGES"])
    for name in skipped:
        feedback.push_warning(f"IMAGES: {name} has no RPCs and is skipped")
    images = select_rpc_images(everything, params["PHOTOS"])
    executor = executor_of(params)
    crs = rpc_crs(params["CRS"], params["DEM"])
    gcps = None if params["CONTROL"] is None else rpc_gcps(params, crs)
    cell, origin = params["CELL_SIZE"], (0.0, 0.0)
    if params["TEMPLATE"] is not None:
        cell, origin = template_lattice(params["TEMPLATE"], cell, crs, "the orthos")
    failed: list[dict[str, Any]] = []
    with dem_in_photo_datum(params["DEM"], params["BAND"], params["HEIGHTS"] or "ellipsoidal",
                            None, feedback, executor, params["FOLDER"]) as (dem, band, heights):
        plans = plan_each(images, lambda image: plan_rpc_image(
            image, crs, dem, band, gcps, params["BIAS"], single=len(everything) == 1), failed,
            feedback)
        if cell is None:
            cell = max(nice_cell_size(plan.gsd) for plan in plans)
        options = OrthoOptions(
            resampling=params["RESAMPLING"], outside=params["OUTSIDE"], nodata=params["NODATA"],
            dem_factor=params["DEM_FACTOR"], band=band, overviews=params["OVERVIEWS"],
            cog=params["COG"])
        folder = Path(params["FOLDER"])  # staged by the runner: moved into place on success
        tasks = [RpcTask(plan.image.id, plan.camera, plan.info, dem,
                         rpc_plan(plan.camera, dem, band, cell, None, origin)[0],
                         folder / f"{plan.image.id}.tif", options,
                         window_workers(k, len(plans), executor))
                 for k, plan in enumerate(plans)]
        reports = collect(map_tiles(run_rpc_task, tasks, executor=executor, feedback=feedback,
                                    total=len(tasks), start=10, end=100), failed, feedback)
    by_id = {plan.image.id: plan for plan in plans}
    for report in reports:
        report.update(photo_gsd_m=by_id[report["photo"]].gsd, bias=by_id[report["photo"]].bias)
    stats = {"photos": len(images), "done": len(reports), "failed": len(failed),
             "skipped": skipped, "cell_size": cell, "crs": crs_label(crs), "camera": "rpc",
             "executor": executor.describe(), "heights": heights.as_dict()}
    return write_listing(algorithm_id, params["OUTPUT"], reports, failed, stats)


def write_listing(algorithm_id: str, output: Any, reports: list[dict[str, Any]],
                  failed: list[dict[str, Any]], stats: dict[str, Any]) -> dict[str, Any]:
    """OUTPUT (JSON: the orthos, the per-photo reports, the failures, the statistics) written;
    the algorithm's outputs."""
    from toolbox.photogrammetry.tables import write_json

    write_json(output, {"algorithm": algorithm_id, "orthos": [r["output"] for r in reports],
                        "photos": reports, "failed": failed, "statistics": stats})
    return {"OUTPUT": output, "STATISTICS": stats}


def on_heights(extent: tuple[float, float, float, float], surface: Any
               ) -> tuple[float, float, float, float]:
    """``extent`` cut to the box of the DEM cells that hold a height (``surface``, in the
    orthos' CRS; to their outer edges: the heights hold the edge value across the DEM's outer
    half cell): a cell outside it has no height, so it would only be written empty (ODM's DSM
    leaves 20-30 % of its drone photos' footprints without heights)."""
    import numpy as np

    ok = np.isfinite(surface.z)
    rows, cols = np.flatnonzero(ok.any(axis=1)), np.flatnonzero(ok.any(axis=0))
    cx, cy = surface.cell_x, surface.cell_y
    xmin, xmax = surface.x0 + (cols[0] - 0.5) * cx, surface.x0 + (cols[-1] + 0.5) * cx
    ymin, ymax = surface.y0 - (rows[-1] + 0.5) * cy, surface.y0 - (rows[0] - 0.5) * cy
    cut = (max(extent[0], xmin), max(extent[1], ymin), min(extent[2], xmax),
           min(extent[3], ymax))
    return cut if cut[0] < cut[2] and cut[1] < cut[3] else extent


_LOADED: dict[tuple, Any] = {}  # the last project loaded: planned_files, then process


def load_batch_project(params: dict[str, Any], last: bool = False) -> Any:
    """PROJECT loaded (once per run: planned_files keeps it for process, which takes it,
    ``last``; the key holds the files' modification times); another
    program's orientation file (GeoJSON, CSV, reconstruction.json...) gets its images matched
    by file stem in IMAGES when given."""
    path, images = Path(params["PROJECT"]), params["IMAGES"]
    try:
        key = (str(path.resolve()), path.stat().st_mtime_ns, images,
               Path(images).stat().st_mtime_ns if images is not None else None)
    except OSError:
        return _load_batch_project(path, images)
    project = _LOADED.pop(key, None)
    _LOADED.clear()
    if project is None:
        project = _load_batch_project(path, images)
    if not last:
        _LOADED[key] = project
    return project


def _load_batch_project(path: Path, images: str | None) -> Any:
    from toolbox.photogrammetry.tables import load_project_parameter

    if images is None or path.suffix.lower() in (".yaml", ".yml"):
        return load_project_parameter(path)
    from toolbox.exchange import project_from_file

    try:
        return project_from_file(path, images)
    except InputDataError as exc:
        text = str(exc)
        raise InputDataError(text if text.startswith("IMAGES") else f"PROJECT: {text}") from None


def select_photos(project: Any, listed: str | None) -> list[Any]:
    if listed is None:
        photos = project.oriented()
        if not photos:
            raise InputDataError(f"PROJECT {project.source} has no oriented photo")
        return photos
    ids = [p.strip() for p in listed.split(",") if p.strip()]
    unknown = [p for p in ids if p not in project.photos]
    if unknown or not ids:
        raise ParameterError("PHOTOS", f"names photos the project does not have: "
                             f"{', '.join(unknown) or listed!r} (photos: "
                             f"{', '.join(project.photos)})")
    return [project.photos[p] for p in ids]


def image_path(photo: Any, folder: str | None) -> Path:
    if photo.image is None:
        raise InputDataError(f"photo {photo.id!r} has no image file in the project")
    return Path(photo.image) if folder is None else Path(folder) / Path(photo.image).name
