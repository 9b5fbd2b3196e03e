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
