"""Whole blocks: one photo of a block as a picklable task (:func:`run_task`, for Dask workers
or threads)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from toolbox.ortho.run import OrthoOptions, orthorectify


@dataclass
class OrthoTask:
    """One photo of a block: everything :func:`run_task` needs (picklable, for Dask workers)."""

    photo: Any
    image: Any  # RasterInfo
    dem: Any  # RasterInfo
    grid: Any
    output: Any  # final path
    options: OrthoOptions
    reference_height: float
    map_scale: float | None = None
    #: threads for this photo's windows; None: one per CPU (:func:`toolbox.executor.local_executor`)
    window_workers: int | None = None


def run_task(task: OrthoTask) -> dict[str, Any]:
    """Orthorectify one photo of a block into a staged file (:func:`toolbox.io.staging.atomic_path`)
    moved to ``task.output`` on success; a user error is returned as ``{"photo", "error"}`` (the
    block goes on)."""
    from pathlib import Path

    from toolbox.errors import ToolboxError
    from toolbox.executor import local_executor
    from toolbox.feedback import CollectingFeedback
    from toolbox.io.staging import atomic_path

    final = Path(task.output)
    feedback = CollectingFeedback()  # its caller reports the warnings, once
    try:
        with atomic_path(final, "FOLDER") as staged:
            report = orthorectify(task.photo, task.image, task.dem, task.grid, staged,
                                  task.options, None, task.reference_height,
                                  map_scale=task.map_scale, feedback=feedback,
                                  executor=local_executor(task.window_workers))
    except ToolboxError as exc:
        return {"photo": task.photo.id, "error": str(exc)}
    report["output"] = str(final)
    report["warnings"] = feedback.warnings
    return report
