"""Blocks of satellite images with RPCs (ortho:batch without a project): the images found
(:func:`rpc_images`: a folder, or a comma-separated list of files), each one planned on the
block's shared lattice (:func:`plan_rpc_block`) and orthorectified as a picklable task
(:func:`run_rpc_task`, for threads or Dask workers) by :func:`toolbox.ortho.rpc.rpc_orthorectify`.

An image's id is its file stem; its ortho is ``<id>.tif``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from toolbox.errors import ParameterError

RPC_SUFFIXES = {".tif", ".tiff", ".ntf", ".nitf", ".jp2", ".img", ".vrt"}


@dataclass(frozen=True)
class RpcImage:
    """One satellite image of a block: id (file stem) and path."""

    id: str
    path: Path


def rpc_images(value: str, name: str = "IMAGES") -> tuple[list[RpcImage], list[str]]:
    """The RPC images of ``value`` (a folder, or file paths separated by commas) and the files
    skipped (those of a folder without RPCs). A listed file that is missing or has no RPCs, a
    folder without any RPC image, or two images with one stem: :class:`ParameterError`."""
    from toolbox.ortho.rpc import has_rpc

    text = str(value).strip()
    folder = Path(text).expanduser()
    skipped: list[str] = []
    if folder.is_dir():
        files = sorted(p for p in folder.iterdir() if p.is_file() and not
                       p.name.startswith(".") and p.suffix.lower() in RPC_SUFFIXES)
        paths = [p for p in files if has_rpc(p)]
        skipped = [p.name for p in files if p not in paths]
        if not paths:
            raise ParameterError(name, f"folder '{folder}' holds no image with RPCs (GeoTIFF "
                                 "RPC tags, .RPB or _RPC.TXT)" + (f"; without RPCs: "
                                                                 f"{', '.join(skipped)}"
                                                                 if skipped else ""))
    else:
        paths = [Path(p.strip()).expanduser() for p in text.split(",") if p.strip()]
        for path in paths:
            if not path.is_file():
                raise ParameterError(name, f"'{path}' is neither a folder nor an image file")
            if not has_rpc(path):
                raise ParameterError(name, f"'{path}' has no RPCs (no GeoTIFF RPC tags, .RPB or "
                                     "_RPC.TXT file): without PROJECT, IMAGES are satellite "
                                     "images with RPCs")
    images = [RpcImage(p.stem, p) for p in paths]
    stems = [i.id for i in images]
    twice = sorted({s for s in stems if stems.count(s) > 1})
    if twice:
        raise ParameterError(name, f"holds two images named {', '.join(twice)} (an ortho is "
                             "<file stem>.tif)")
    return images, skipped


def select_rpc_images(images: list[RpcImage], listed: str | None) -> list[RpcImage]:
    """The images whose ids ``listed`` names (PHOTOS, comma separated), or all."""
    if listed is None:
        return images
    by_id = {i.id: i for i in images}
    ids = [p.strip() for p in listed.split(",") if p.strip()]
    unknown = [p for p in ids if p not in by_id]
    if unknown or not ids:
        raise ParameterError("PHOTOS", f"names images IMAGES does not have: "
                             f"{', '.join(unknown) or listed!r} (images: {', '.join(by_id)})")
    return [by_id[p] for p in ids]


@dataclass
class RpcPlan:
    """One image planned: its camera (bias refined), raster, GSD and bias report."""

    image: RpcImage
    camera: Any
    info: Any  # RasterInfo
    gsd: float
    bias: dict[str, Any] | None


def plan_rpc_image(image: RpcImage, crs: Any, dem: Any, band: int, gcps: tuple | None = None,
                   bias_model: str = "auto", single: bool = False) -> RpcPlan:
    """``image``'s camera in ``crs`` (GCP bias refined when ``gcps`` = (measurements,
    control) is given: :func:`refine_from_gcps`) and its GSD on ``dem``."""
    from toolbox.cameras import read_rpc
    from toolbox.io.raster import open_raster_info
    from toolbox.ortho.rpc import rpc_plan

    info = open_raster_info(image.path, "IMAGES")
    camera = read_rpc(image.path, crs)
    bias = None
    if gcps is not None:
        camera, bias = refine_from_gcps(camera, image.path.name, *gcps, bias_model, single)
    _, gsd = rpc_plan(camera, dem, band)
    return RpcPlan(image, camera, info, gsd, bias)


def refine_from_gcps(camera: Any, image_name: str, measurements: tuple, control: tuple,
                     model: str = "auto", single: bool = True) -> tuple[Any, dict[str, Any]]:
    """The camera with its bias fitted to the control points measured on ``image_name``
    (:func:`toolbox.ortho.rpc.gcp_pairs`; ``single``: a table naming one photo is this
    image's) and the bias report with the points' ids."""
    from toolbox.cameras import refine_bias
    from toolbox.ortho.rpc import gcp_pairs

    ids, ground, pixels = gcp_pairs(image_name, measurements, control, single)
    camera, bias = refine_bias(camera, ground, pixels, model)
    bias["points"] = ids
    return camera, bias


@dataclass
class RpcTask:
    """One image of a block: everything :func:`run_rpc_task` needs (picklable)."""

    id: str
    camera: Any
    image: Any  # RasterInfo
    dem: Any  # RasterInfo
    grid: Any
    output: Any  # final path
    options: Any  # OrthoOptions
    window_workers: int | None = None  # as OrthoTask's


def run_rpc_task(task: RpcTask) -> dict[str, Any]:
    """Orthorectify one image into a staged file moved to ``task.output`` on success; a user
    error is returned as ``{"photo", "error"}`` (the block goes on)."""
    from toolbox.errors import ToolboxError
    from toolbox.executor import local_executor
    from toolbox.feedback import CollectingFeedback
    from toolbox.io.staging import atomic_path
    from toolbox.ortho.rpc import rpc_orthorectify

    final = Path(task.output)
    feedback = CollectingFeedback()
    try:
        with atomic_path(final, "FOLDER") as staged:
            report = rpc_orthorectify(task.camera, task.image, task.dem, task.grid, staged,
                                      task.options, feedback,
                                      executor=local_executor(task.window_workers))
    except ToolboxError as exc:
        return {"photo": task.id, "error": str(exc)}
    report.update(photo=task.id, output=str(final), warnings=feedback.warnings)
    return report

