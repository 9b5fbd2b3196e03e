"""Batch pipelines: several algorithms in order, like a graphical model (PDAL-style stage list).

Format (YAML)::

    variables:                 # optional; also set with --set NAME=VALUE
      data: sample
    steps:
      - name: dem              # optional, default step1, step2, ...
        algorithm: dem:idw
        params:
          INPUT: ${data}/points.gpkg
          CELL_SIZE: 2
          OUTPUT: out/dem.tif
      - name: shade
        algorithm: dem:hillshade
        params:
          INPUT: ${dem.OUTPUT}  # an earlier step's output
          OUTPUT: out/hillshade.tif

Relative paths of file and layer parameters are relative to the pipeline file's folder.
``${name}`` is a variable, ``${step.OUTPUT}`` an earlier step's output; a value that is only a
reference keeps the referenced value's type (number, list, path).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from toolbox.errors import PipelineError, ToolboxError
from toolbox.feedback import Feedback
from toolbox.parameters import Destination, File, MultipleLayers, RasterLayer, VectorLayer

REF_RE = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)(?:\.([A-Z][A-Z0-9_]*))?\}")
PATH_TYPES = (Destination, File, MultipleLayers, RasterLayer, VectorLayer)


@dataclass
class Step:
    name: str
    algorithm: str
    params: dict[str, Any]


@dataclass
class Pipeline:
    steps: list[Step]
    base_dir: Path
    variables: dict[str, Any] = field(default_factory=dict)


def load_pipeline(path: str | Path, variables: dict[str, Any] | None = None) -> Pipeline:
    """Read and statically validate a pipeline: algorithms exist, parameter names are known,
    every reference points to a variable or to an output of an earlier step."""
    import yaml

    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise PipelineError(f"cannot read pipeline {path}: {exc}") from None
    return parse_pipeline(doc, path.parent, variables, str(path))


def parse_pipeline(doc: Any, base_dir: Path, variables: dict[str, Any] | None = None,
                   source: str = "pipeline") -> Pipeline:
    from toolbox.registry import get

    if not isinstance(doc, dict) or not isinstance(doc.get("steps"), list) or not doc["steps"]:
        raise PipelineError(f"{source}: expected a mapping with a non-empty 'steps' list")
    values = dict(doc.get("variables") or {})
    values.update(variables or {})
    steps: list[Step] = []
    available: dict[str, set[str]] = {}
    for i, raw in enumerate(doc["steps"], start=1):
        if not isinstance(raw, dict) or "algorithm" not in raw:
            raise PipelineError(f"{source}: step {i} needs an 'algorithm'")
        name = str(raw.get("name") or f"step{i}")
        if name in available or name in values:
            raise PipelineError(f"{source}: step name {name!r} is used twice")
        try:
            alg = get(str(raw["algorithm"]))
        except ToolboxError as exc:
            raise PipelineError(f"{source}: step {name!r}: {exc}") from None
        params = raw.get("params") or {}
        if not isinstance(params, dict):
            raise PipelineError(f"{source}: step {name!r}: 'params' must be a mapping")
        known = {n for p in alg.parameters for n in (p.name, *p.deprecated_names)} | {"OVERWRITE"}
        for key, value in params.items():
            if key not in known:
                raise PipelineError(f"{source}: step {name!r}: {key} is not a parameter of "
                                    f"{alg.id}; its parameters are: "
                                    f"{', '.join(p.name for p in alg.parameters)}")
            for ref_step, ref_out in _references(value):
                if ref_out is None:
                    if ref_step not in values:
                        raise PipelineError(f"{source}: step {name!r}: {key} uses ${{{ref_step}}}"
                                            " but no such variable is set")
                elif ref_step not in available:
                    raise PipelineError(f"{source}: step {name!r}: {key} refers to step "
                                        f"{ref_step!r}, which does not come earlier")
                elif ref_out not in available[ref_step]:
                    raise PipelineError(f"{source}: step {name!r}: {key} refers to "
                                        f"{ref_step}.{ref_out}, but that step's outputs are: "
                                        f"{', '.join(sorted(available[ref_step]))}")
        available[name] = {p.name for p in alg.destinations()} | {o.name for o in alg.outputs}
        steps.append(Step(name, alg.id, dict(params)))
    return Pipeline(steps, base_dir, values)


def _references(value: Any):
    if isinstance(value, str):
        for match in REF_RE.finditer(value):
            yield match.group(1), match.group(2)
    elif isinstance(value, list):
        for item in value:
            yield from _references(item)


def _substitute(value: Any, scope: dict[str, Any]) -> Any:
    if isinstance(value, list):
        return [_substitute(v, scope) for v in value]
    if not isinstance(value, str):
        return value

    def lookup(match: re.Match) -> Any:
        ref_step, ref_out = match.group(1), match.group(2)
        return scope[ref_step] if ref_out is None else scope[ref_step][ref_out]

    whole = REF_RE.fullmatch(value)
    if whole:
        return lookup(whole)
    return REF_RE.sub(lambda m: str(lookup(m)), value)


def _absolutise(value: Any, base_dir: Path) -> Any:
    if isinstance(value, list):
        return [_absolutise(v, base_dir) for v in value]
    if isinstance(value, (str, Path)) and str(value) and not Path(str(value)).expanduser().is_absolute():
        return str(base_dir / str(value))
    return value


def run_pipeline(pipeline: Pipeline, feedback: Feedback | None = None, overwrite: bool = False,
                 report_dir: str | Path | None = None) -> dict[str, dict[str, Any]]:
    """Run every step in order; return ``{step name: outputs}``. A failing step stops the run
    with an error naming it (outputs of completed steps stay)."""
    from toolbox.registry import get
    from toolbox.runner import run

    feedback = feedback or Feedback()
    scope: dict[str, Any] = dict(pipeline.variables)
    results: dict[str, dict[str, Any]] = {}
    n = len(pipeline.steps)
    for i, step in enumerate(pipeline.steps):
        feedback.check_canceled()
        alg = get(step.algorithm)
        params = {}
        for key, value in step.params.items():
            value = _substitute(value, scope)
            if key != "OVERWRITE" and isinstance(alg.parameter(key), PATH_TYPES):
                value = _absolutise(value, pipeline.base_dir)
            params[key] = value
        feedback.push_info(f"step {i + 1}/{n} {step.name}: {alg.id}")
        report = None if report_dir is None else Path(report_dir) / f"{step.name}.json"
        try:
            outputs = run(alg.id, params, feedback=feedback.step(100 * i / n, 100 * (i + 1) / n),
                          overwrite=overwrite, report=report)
        except ToolboxError as exc:
            raise PipelineError(f"step {step.name!r} ({alg.id}): {exc}") from exc
        scope[step.name] = outputs
        results[step.name] = outputs
    return results
