"""``toolbox warmup`` runs the demo steps of every algorithm with numba kernels, and the steps
whose outputs they read, so that the kernels are compiled into the per-user cache."""

from __future__ import annotations

from toolbox.demo import demo_pipeline_doc
from toolbox.registry import spec_index
from toolbox.warmup import EXTRA_STEPS, KERNEL_ALGORITHMS, warmup_steps


def test_warmup_runs_every_kernel_algorithm_after_the_steps_it_reads_from():
    steps = warmup_steps(demo_pipeline_doc()["steps"])
    names = [step["name"] for step in steps]
    assert {step["algorithm"] for step in steps} >= KERNEL_ALGORITHMS
    for k, step in enumerate(steps):  # any other step is one a later step reads from
        if step["algorithm"] not in KERNEL_ALGORITHMS:
            assert any(f"${{{step['name']}." in str(later.get("params")) for later in
                       steps[k + 1:]), step["name"]
    assert names.index("tin_delaunay") < names.index("tin_to_raster")  # the TIN it rasterises
    assert "topology_check" not in names and names[-len(EXTRA_STEPS):] == \
        [step["name"] for step in EXTRA_STEPS]
    assert KERNEL_ALGORITHMS <= set(spec_index())


def test_warmup_pipeline_validates_on_the_demo_data(demo_run, tmp_path):
    """The steps warmup runs are a pipeline `toolbox batch --validate` accepts on the demo's
    sample data (every parameter, enum, range, input and reference; nothing run): a warm-up step
    left behind by a renamed parameter or a removed demo step fails here, not on a user's first
    install."""
    import yaml
    from trust_data import demo  # the module demo_run built (on sys.path by conftest)

    from toolbox.batch import load_pipeline, validate_pipeline

    _, variables = demo()
    doc = {"variables": dict(variables) | {"out": str(tmp_path)},
           "steps": warmup_steps(demo_pipeline_doc()["steps"])}
    path = tmp_path / "warmup_pipeline.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    validate_pipeline(load_pipeline(path), overwrite=True)


def test_every_warmed_algorithm_reaches_a_compiled_kernel():
    """KERNEL_ALGORITHMS lists algorithms whose code imports (at any depth, function-level
    imports too) a module of numba kernels cached on disk (``cache=True``): warming one without
    kernels would cost a minute of a first install for nothing."""
    from pathlib import Path

    import grimp

    root = Path(__file__).resolve().parents[2]
    kernels = {".".join(p.relative_to(root).with_suffix("").parts)
               for p in (root / "toolbox").rglob("*.py")
               if "cache=True" in p.read_text(encoding="utf-8") and p.name != "cache.py"}
    assert {"toolbox.terrain.gridding.idw_kernel", "toolbox.photogrammetry.kernels"} <= kernels
    graph = grimp.build_graph("toolbox", "algorithms", cache_dir=None)
    for algorithm in sorted(KERNEL_ALGORITHMS):
        module = "algorithms." + algorithm.replace(":", ".")
        assert graph.find_upstream_modules(module) & kernels, algorithm
