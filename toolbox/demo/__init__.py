"""``toolbox demo``: build the bundled sample data, run the demo pipeline on it, list the outputs.

Sample data come from :mod:`toolbox.demo.samples` (one module per domain, generated
deterministically or derived from data shipped with a dependency); the pipeline is the
concatenation of ``pipeline/*.yaml`` fragments in name order, each a list of batch steps that may
use the sample variables (``${dem}``, ``${out}``...) and earlier steps' outputs. The demo writes
it as one pipeline file, ``OUT/demo_pipeline.yaml`` (variables included), and runs that file as
``toolbox batch`` does: ``toolbox batch demo_out/demo_pipeline.yaml --overwrite --report-dir
demo_out/reports`` reruns it.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from toolbox.feedback import Feedback


def demo_pipeline_doc() -> dict:
    """The demo pipeline: every fragment's steps, in fragment-name order."""
    import yaml

    steps = []
    folder = resources.files("toolbox.demo") / "pipeline"
    for item in sorted(folder.iterdir(), key=lambda p: p.name):
        if item.name.endswith(".yaml"):
            steps.extend(yaml.safe_load(item.read_text()) or [])
    return {"steps": steps}


def run_demo(out_dir: Path, feedback: Feedback | None = None) -> str:
    """Generate sample data under ``out_dir/data``, run the pipeline into ``out_dir``; return a
    human summary of what was written where."""
    from toolbox.batch import run_pipeline
    from toolbox.demo.samples import make_samples

    feedback = feedback or Feedback()
    out_dir = Path(out_dir).absolute()
    out_dir.mkdir(parents=True, exist_ok=True)
    with feedback.timed("samples"):
        variables = make_samples(out_dir / "data")
    import yaml

    from toolbox.batch import load_pipeline

    variables = {k: str(v) for k, v in variables.items()} | {"out": str(out_dir)}
    pipeline_file = out_dir / "demo_pipeline.yaml"
    doc = {"variables": variables} | demo_pipeline_doc()
    pipeline_file.write_text("# The demo pipeline (toolbox demo wrote it; rerun with\n"
                             f"#   toolbox batch {pipeline_file} --overwrite --report-dir "
                             f"{out_dir / 'reports'})\n"
                             + yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    pipeline = load_pipeline(pipeline_file)
    # a rerun into the same folder: the previous run's reports of these steps go first, since
    # report:quality reads the reports folder (it would read its own old report, and the runner
    # refuses to write a report over a file of an input folder)
    for step in doc["steps"]:
        (out_dir / "reports" / f"{step['name']}.json").unlink(missing_ok=True)
    results = run_pipeline(pipeline, feedback=feedback.step(5, 100), overwrite=True,
                           report_dir=out_dir / "reports")
    lines = [f"Demo finished: {len(results)} steps, outputs in {out_dir}", ""]
    for step, outputs in results.items():
        files = [v for v in outputs.values() if isinstance(v, str) and Path(v).exists()]
        for path in files:
            lines.append(f"  {step:<22} {Path(path).relative_to(out_dir)}")
    for step, outputs in results.items():  # a bundle compared with a reference solution
        stats = outputs.get("STATISTICS")
        reference = stats.get("reference") if isinstance(stats, dict) else None
        if isinstance(reference, dict) and isinstance(reference.get("line"), str):
            lines += ["", f"  {step}: {reference['line']}"]
    lines += ["", f"  the pipeline           {pipeline_file}",
              f"  sample inputs in       {out_dir / 'data'}",
              f"  JSON run reports in    {out_dir / 'reports'}"]
    return "\n".join(lines)
