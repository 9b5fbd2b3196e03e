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

Relative paths of file, folder and layer parameters are relative to the pipeline file's folder.
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
from toolbox.io.paths import absolute_paths
from toolbox.io.text import yaml_error_line

REF_RE = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)(?:\.([A-Z][A-Z0-9_]*))?\}")


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
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise PipelineError(f"cannot read pipeline {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise PipelineError(f"cannot read pipeline {path}: not UTF-8 text (byte "
                            f"{exc.start}); save it as UTF-8") from None
    except yaml.YAMLError as exc:
        raise PipelineError(f"cannot read pipeline {path}: {yaml_error_line(exc)}") from None
    return parse_pipeline(doc, path.parent, variables, str(path))


def parse_pipeline(doc: Any, base_dir: Path, variables: dict[str, Any] | None = None,
                   source: str = "pipeline") -> Pipeline:
    from toolbox.registry import get

    if not isinstance(doc, dict) or not isinstance(doc.get("steps"), list) or not doc["steps"]:
        raise PipelineError(f"{source}: expected a mapping with a non-empty 'steps' list")
    raw_variables = doc.get("variables") or {}
    if not isinstance(raw_variables, dict):
        raise PipelineError(f"{source}: 'variables' must be a mapping of NAME: value, got "
                            f"{type(raw_variables).__name__}")
    values = {str(k): v for k, v in raw_variables.items()}
    used = {ref for v in [*values.values(), *(s.get("params") for s in doc["steps"]
                                                if isinstance(s, dict))]
            for ref, out in _references_deep(v) if out is None}
    for name in variables or {}:  # a misspelt --set would be ignored: the run goes elsewhere
        if name not in values and name not in used:
            known = ", ".join(sorted(set(values) | used)) or "none"
            raise PipelineError(f"{source}: --set {name}: the pipeline has no variable {name!r}"
                                f" (its variables: {known})")
    values.update(variables or {})
    values = _expand_variables(values, source)
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
        if "OVERWRITE" in params and not any(True for _ in _references(params["OVERWRITE"])):
            from toolbox.parameters import Boolean, ValidationContext

            try:
                Boolean("OVERWRITE").validate(params["OVERWRITE"], ValidationContext())
            except ToolboxError as exc:
                raise PipelineError(f"{source}: step {name!r}: {exc}") from None
        for key, value in params.items():
            if not isinstance(key, str) or key not in known:
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
        try:  # an old parameter name: its current one from here on (with the run's warning)
            params = alg.rename_deprecated(params)
        except ToolboxError as exc:
            raise PipelineError(f"{source}: step {name!r}: {exc}") from None
        steps.append(Step(name, alg.id, dict(params)))
    return Pipeline(steps, base_dir, values)


def _expand_variables(values: dict[str, Any], source: str) -> dict[str, Any]:
    """Variables whose values name other variables (``out: ${run}/out``), expanded until none
    is left; an unknown name or a cycle is a :class:`PipelineError`."""
    done: dict[str, Any] = {}

    def expand(name: str, chain: tuple[str, ...]) -> Any:
        if name in done:
            return done[name]
        if name in chain:
            raise PipelineError(f"{source}: variable {name!r} refers to itself through "
                                f"{' -> '.join((*chain, name))}")
        value = values[name]
        for ref, out in _references(value):
            if out is not None:
                raise PipelineError(f"{source}: variable {name!r} uses ${{{ref}.{out}}}; a "
                                    "variable cannot name a step's output")
            if ref not in values:
                raise PipelineError(f"{source}: variable {name!r} uses ${{{ref}}} but no such "
                                    "variable is set")
            expand(ref, (*chain, name))
        done[name] = _substitute(value, done) if any(True for _ in _references(value)) \
            else value
        return done[name]

    for name in values:
        expand(name, ())
    return done


def _references(value: Any):
    if isinstance(value, str):
        for match in REF_RE.finditer(value):
            yield match.group(1), match.group(2)
    elif isinstance(value, list):
        for item in value:
            yield from _references(item)


def _references_deep(value: Any):
    """:func:`_references` of a value and of the values of a mapping (a step's params)."""
    if isinstance(value, dict):
        for item in value.values():
            yield from _references(item)
    else:
        yield from _references(value)


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


def _absolutise(value: Any, base_dir: Path, param: Any) -> Any:
    """A path parameter's value relative to the pipeline file's folder."""
    return absolute_paths(value, base_dir, comma_separated=getattr(param, "paths", False))


def step_label(index: int, count: int, algorithm: str, name: str) -> str:
    """How messages name a pipeline step: its number, the algorithm and its name, e.g.
    ``step 3 of 7 (dem:idw 'grid')`` (``index`` 0-based)."""
    return f"step {index + 1} of {count} ({algorithm} {name!r})"


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
    names = [step.name for step in pipeline.steps]
    written: set[Path] = set()  # the files the steps run so far wrote
    if report_dir is not None and overwrite:  # an earlier run's reports of these steps describe
        for name in names:                    # that run: gone first, as a step that reads the
            (Path(report_dir) / f"{name}.json").unlink(missing_ok=True)  # folder would use them
    for i, step in enumerate(pipeline.steps):
        feedback.check_canceled()
        alg = get(step.algorithm)
        params = {}
        for key, value in step.params.items():
            value = _substitute(value, scope)
            if key != "OVERWRITE" and alg.parameter(key).holds_paths:
                value = _absolutise(value, pipeline.base_dir, alg.parameter(key))
            params[key] = value
        feedback.push_info(f"step {i + 1}/{n} {step.name}: {alg.id}")
        _warn_stale_reports(alg, params, names, report_dir, step.name, feedback, written)
        report = None if report_dir is None else Path(report_dir) / f"{step.name}.json"
        try:
            outputs = run(alg.id, params, feedback=feedback.step(100 * i / n, 100 * (i + 1) / n),
                          overwrite=overwrite, report=report)
        except ToolboxError as exc:
            label = step_label(i, n, alg.id, step.name)
            error = PipelineError(f"{label}: {exc}")
            error.step = label  # as below, if a signal caused it
            raise error from exc
        except (KeyboardInterrupt, Exception) as exc:  # the CLI names the step (an
            try:                                       # interruption: the steps done stay)
                exc.step = step_label(i, n, alg.id, step.name)
            except AttributeError:  # an exception type without a __dict__
                pass
            raise
        scope[step.name] = outputs
        results[step.name] = outputs
        for dest in alg.destinations():  # what this run wrote: no earlier run's report
            if isinstance(outputs.get(dest.name), (str, Path)):
                written.update(_files_written(dest, _abs(outputs[dest.name])))
    return results


def _warn_stale_reports(alg: Any, params: dict[str, Any], names: list[str],
                        report_dir: str | Path | None, step: str, feedback: Feedback,
                        written: set[Path] = frozenset()) -> None:
    """A folder input (report:quality's REPORTS) holding reports named after this pipeline's
    steps that this run does not write there: they are an earlier run's, read as this one's.
    A file an earlier step of this run wrote (``written``: a step's own JSON output named
    after a step) is this run's, not counted."""
    from toolbox.parameters import Folder

    here = None if report_dir is None else Path(report_dir).expanduser().resolve()
    for p in alg.parameters:
        value = params.get(p.name)
        if not isinstance(p, Folder) or not isinstance(value, (str, Path)):
            continue
        folder = Path(value).expanduser()
        if here is not None and folder.resolve() == here:
            continue
        stale = [name for name in names if (folder / f"{name}.json").is_file()
                 and (folder / f"{name}.json").resolve() not in written]
        if stale:
            feedback.push_warning(
                f"step {step!r}: {p.name} '{value}' holds run reports named after steps of this "
                f"pipeline ({', '.join(stale[:5])}{', ...' if len(stale) > 5 else ''}) that this "
                f"run does not write there: they are of an earlier run; rerun with "
                f"--report-dir '{value}' --overwrite to report this run")


# -- value validation (``toolbox batch --validate`` and before a CLI batch run) -----------------
def validate_pipeline(pipeline: Pipeline, overwrite: bool = False,
                      existing: list[Path] | None = None,
                      report_dir: str | Path | None = None) -> None:
    """Check every step's values before anything runs: ranges, enums and types, inputs that
    exist (or that an earlier step writes), references to optional outputs left unset, two steps
    writing one file, a step writing its own or an earlier step's input, existing outputs without
    ``overwrite`` (collected in ``existing`` instead when a list is given). Raises
    :class:`PipelineError` naming the step."""
    from toolbox.errors import OutputExistsError
    from toolbox.parameters import Field, Folder, OutputFolder, ValidationContext
    from toolbox.registry import get
    from toolbox.runner import check_magnitudes, check_parameter_crs, planned_paths
    from toolbox.runner import validate as runner_validate
    from toolbox.runner.paths import input_paths

    written: dict[Path, str] = {}  # output path -> "step.NAME"
    read: dict[Path, str] = {}  # input path -> "step.NAME"
    outputs_of: dict[str, dict[str, Any]] = {}  # step -> {NAME: final path or True}
    for index, step in enumerate(pipeline.steps):
        alg = get(step.algorithm)

        def fail(message: str, step=step, alg=alg, index=index) -> PipelineError:
            return PipelineError(f"{step_label(index, len(pipeline.steps), alg.id, step.name)}: "
                                 f"{message}")

        ctx = ValidationContext(overwrite=True)
        resolved_all = True
        step_inputs: dict[Path, str] = {}
        for p in [q for q in alg.parameters if not q.is_output] + alg.destinations():
            raw = step.params.get(p.name)
            refs = [r for r in _references(raw) if r[1] is not None]
            for ref_step, ref_out in refs:
                target = outputs_of.get(ref_step, {}).get(ref_out)
                if target is None:
                    raise fail(f"{p.name} uses ${{{ref_step}.{ref_out}}}, but step {ref_step!r} "
                               f"does not set its optional output {ref_out}")
                if isinstance(target, Path) and not p.is_output:
                    step_inputs[target] = p.name
            if refs:
                resolved_all = False
                continue
            value = _substitute(raw, pipeline.variables) if raw is not None else None
            if p.holds_paths and value is not None:
                value = _absolutise(value, pipeline.base_dir, p)
            try:
                if p.is_output:
                    ctx.values[p.name] = p.resolve(value, ctx)
                elif isinstance(p, Field) and ctx.values.get(p.parent) is None \
                        and value is not None:
                    resolved_all = False
                elif isinstance(p, Folder) and report_dir is not None and value is not None \
                        and _abs(value) == _abs(report_dir):
                    resolved_all = False  # the run's --report-dir: made as the steps run
                elif value is not None and _later_file(value, written, isinstance(p, Folder)):
                    resolved_all = False  # an earlier step writes it: checked when it runs
                    for item in value if isinstance(value, list) else [value]:
                        step_inputs[_abs(item)] = p.name
                else:
                    ctx.values[p.name] = p.resolve(value, ctx)
                    check_parameter_crs(alg, p, ctx.values[p.name])
            except ToolboxError as exc:
                raise fail(str(exc)) from None
        try:
            check_magnitudes(alg, ctx.values)
        except ToolboxError as exc:
            raise fail(str(exc)) from None
        for path, name in ctx.input_paths.items():
            step_inputs[path] = name
        for path, name in input_paths(alg, ctx.values).items():  # a VRT's sources, a project's
            step_inputs.setdefault(path, name)                   # photos: what the run protects
        for path, name in step_inputs.items():
            read.setdefault(path, f"{step.name}.{name}")
        outputs_of[step.name] = {o.name: True for o in alg.outputs}
        for dest in alg.destinations():
            final = ctx.values.get(dest.name)
            if final is None:
                continue
            path = _abs(final)
            for file in _files_written(dest, path):
                what = f"{dest.name} '{final}'" + ("" if file == path else
                                                   f" (its layer file '{file}')")
                if file in step_inputs:
                    raise fail(f"{what} is also this step's input {step_inputs[file]}")
                if file in read:
                    raise fail(f"{what} is the input {read[file]} of an earlier step; an input "
                               "is never overwritten")
                if file in written:
                    raise fail(f"{what} is also written by {written[file]}")
                if isinstance(dest, OutputFolder):
                    pass  # an existing folder is fine: its planned files are checked below
                elif file.exists() and not overwrite and existing is not None:
                    existing.append(file)
                elif file.exists() and not overwrite:
                    raise fail(str(OutputExistsError(dest.name, f"'{file}' exists; pass "
                                                     "--overwrite to replace it")))
                written[file] = f"{step.name}.{dest.name}"
            outputs_of[step.name][dest.name] = path
        if resolved_all:  # every value known now: every check the run makes before it writes
            values = {k: _absolutise(_substitute(v, pipeline.variables), pipeline.base_dir,
                                     alg.parameter(k))
                      if k != "OVERWRITE" and alg.parameter(k).holds_paths
                      else _substitute(v, pipeline.variables) for k, v in step.params.items()}
            try:
                checked = runner_validate(alg, values, overwrite=True)
                for paths in planned_paths(alg, checked).values():
                    for path in paths:
                        if path.resolve() in read:
                            raise fail(f"would write '{path}', the input {read[path.resolve()]}"
                                       " of an earlier step; an input is never overwritten")
                        if path.exists() and not overwrite and existing is not None:
                            existing.append(path)
                        elif path.exists() and not overwrite:
                            raise fail(f"would replace '{path}', which exists; pass "
                                       "--overwrite to replace it")
            except PipelineError:
                raise
            except ToolboxError as exc:
                raise fail(str(exc)) from None


def _abs(value: Any) -> Path:
    text = str(getattr(value, "path", value)).split("|", 1)[0]
    return Path(text).expanduser().resolve()


def _files_written(dest: Any, path: Path) -> list[Path]:
    """The files output ``dest`` writes at ``path``: the path and, for a vector output in a
    one-layer format (Shapefile...), the files of its other declared layers
    (``<stem>_<layer><ext>``; layers named after the data or a parameter left out)."""
    from toolbox.io.vector_write import layer_paths
    from toolbox.parameters import OutputVector

    if not isinstance(dest, OutputVector) or not dest.layers:
        return [path]
    files = layer_paths(path, [layer.name for layer in dest.layers])
    return list(dict.fromkeys([path] + [file for name, file in files.items()
                                        if not set(name) & set("*{")]))


def _later_file(value: Any, written: dict[Path, str], folder: bool = False) -> bool:
    """Whether an earlier step writes ``value`` (a path or a list of paths): the file itself, or
    a file inside an output folder of an earlier step (the photos of an ortho:batch FOLDER);
    with ``folder`` (a :class:`~toolbox.parameters.Folder` input: report:quality's REPORTS)
    also a file an earlier step writes inside the folder ``value`` (empty, or not yet made,
    when the pipeline is validated)."""
    for item in value if isinstance(value, list) else [value]:
        if isinstance(item, (str, Path)):
            path = _abs(item)
            if path in written or any(parent in written for parent in path.parents):
                return True
            if folder and any(path in file.parents for file in written):
                return True
    return False
