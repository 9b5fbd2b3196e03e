"""``toolbox warmup``: compile every numba kernel into the per-user cache before the first run.

A numba kernel compiles on its first call: a first ``dem:nearest`` on 4,500 points takes about
5 s against 1.7 s once its kernels are cached (``bench/startup_bench.py``). ``make venv`` runs
this once, so that a newcomer's first run loads compiled kernels. It runs the demo pipeline's
steps of the algorithms that have kernels (and the steps they read from) on the demo's sample
data in a temporary folder, plus the options the demo does not use: the real calls, so that the
cached specialisations are the ones a run asks for. It then builds the kernels that
:mod:`toolbox.aot` compiles ahead of time (a run loads them without importing numba). About a
minute; the cache folder (:func:`toolbox.cache.user_cache_dir`) can be deleted at any time.
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

from toolbox.feedback import Feedback

#: the algorithms with numba kernels (their demo steps are run)
KERNEL_ALGORITHMS = frozenset({
    "orientation:footprints", "orientation:monoplot", "tin:delaunay", "tin:to_raster",
    "dem:nearest", "dem:idw", "dem:plane", "dem:quadratic", "dem:cubic", "dem:tin_linear",
    "dem:cross_validate", "ortho:photo", "ortho:batch", "carto:contours", "mosaic:seamlines"})
#: options with kernels of their own that the demo does not use
EXTRA_STEPS = [
    {"name": "warmup_idw_sectors", "algorithm": "dem:idw",
     "params": {"INPUT": "${mass_points}", "CELL_SIZE": 8, "SECTORS": 4, "RADIUS": 60,
                "OUTPUT": "${out}/warmup_idw_sectors.tif",
                "QUALITY": "${out}/warmup_idw_sectors.json"}},
]


def warmup_steps(steps: list[dict]) -> list[dict]:
    """The steps of ``KERNEL_ALGORITHMS`` and, before them, the steps they read from
    (``${step.OUTPUT}`` references), in pipeline order; then :data:`EXTRA_STEPS`."""
    by_name = {step["name"]: step for step in steps}
    wanted: set[str] = set()

    def need(name: str) -> None:
        if name in wanted or name not in by_name:
            return
        wanted.add(name)
        for ref in re.findall(r"\$\{(\w+)\.", str(by_name[name].get("params", {}))):
            need(ref)

    for step in steps:
        if step["algorithm"] in KERNEL_ALGORITHMS:
            need(step["name"])
    return [step for step in steps if step["name"] in wanted] + EXTRA_STEPS


def warmup(feedback: Feedback | None = None) -> int:
    """Compile the kernels (see the module docstring); return the number of steps run."""
    import yaml

    from toolbox.batch import load_pipeline, run_pipeline
    from toolbox.demo import demo_pipeline_doc
    from toolbox.demo.samples import make_samples

    feedback = feedback or Feedback()
    with tempfile.TemporaryDirectory(prefix="toolbox-warmup-") as tmp:
        work = Path(tmp)
        with feedback.timed("samples"):
            variables = make_samples(work / "data")
        steps = warmup_steps(demo_pipeline_doc()["steps"])
        doc = {"variables": {k: str(v) for k, v in variables.items()} | {"out": str(work)},
               "steps": steps}
        pipeline_file = work / "warmup_pipeline.yaml"
        pipeline_file.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
        run_pipeline(load_pipeline(pipeline_file), feedback=feedback.step(10, 100),
                     overwrite=True)
    compile_large_input_kernels()
    with feedback.timed("ahead-of-time kernels"):
        build_ahead_of_time()
    return len(steps)


def build_ahead_of_time() -> list[str]:
    """The kernels of :mod:`toolbox.aot` compiled into the per-user cache; on failure (no C
    compiler or Python headers, no ``numba.pycc``) a warning, and runs keep numba's JIT.
    Returns the module files built."""
    import logging

    from toolbox.aot import build_compiled

    try:
        return build_compiled()
    except Exception as exc:  # noqa: BLE001 - the C toolchain fails in many ways; none is fatal
        logging.getLogger("toolbox").warning(
            "the ahead-of-time kernels were not built (%s: %s): runs use numba's JIT",
            type(exc).__name__, str(exc).splitlines()[0] if str(exc) else "")
        return []


def compile_large_input_kernels() -> None:
    """The bin kernels that only inputs above the numpy crossover use (the demo's are smaller:
    :data:`toolbox.terrain.gridding.neighbours.NUMPY_MAX_POINTS`), through the same calls; and
    the JIT of the TIN's uniqueness check (large triangulations with shared coordinates), for a
    machine where its ahead-of-time build fails."""
    import numpy as np

    from toolbox.terrain.gridding import neighbours
    from toolbox.terrain.tin.unique_kernel import cocircular_edges

    cocircular_edges(np.zeros((3, 2)), np.full((1, 6), 1, dtype=np.uint32))

    saved = neighbours.NUMPY_MAX_POINTS
    neighbours.NUMPY_MAX_POINTS = -1
    try:
        bins = neighbours.PointBins.build(np.random.default_rng(0).uniform(0, 10, (50, 2)))
        bins.has_duplicates()
        bins.in_rect(1.0, 1.0, 5.0, 5.0)
    finally:
        neighbours.NUMPY_MAX_POINTS = saved
