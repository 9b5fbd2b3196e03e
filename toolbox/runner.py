"""Runner: validate parameters -> execute -> move outputs into place -> optional JSON report.

>>> import toolbox
>>> toolbox.run("dem:hillshade", {"INPUT": "dem.tif", "OUTPUT": "hs.tif"})  # doctest: +SKIP
{'OUTPUT': '/abs/path/hs.tif'}
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.errors import ParameterError
from toolbox.feedback import Feedback
from toolbox.io.staging import OutputStaging
from toolbox.parameters import Boolean, ValidationContext
from toolbox.registry import get

OVERWRITE = "OVERWRITE"


def _pop_overwrite(parameters: dict[str, Any], overwrite: bool) -> tuple[dict[str, Any], bool]:
    params = dict(parameters)
    if OVERWRITE in params:
        overwrite = Boolean(OVERWRITE).validate(params.pop(OVERWRITE), ValidationContext())
    return params, overwrite


def validate(algorithm: type[Algorithm] | str, parameters: dict[str, Any],
             overwrite: bool = False) -> dict[str, Any]:
    """Validate ``parameters`` for an algorithm; return the normalised values.

    Unknown names, missing required values and bad values raise :class:`ParameterError`.
    Nothing is written.
    """
    alg = get(algorithm) if isinstance(algorithm, str) else algorithm
    params, overwrite = _pop_overwrite(alg.rename_deprecated(parameters), overwrite)
    known = {p.name for p in alg.parameters}
    unknown = sorted(set(params) - known)
    if unknown:
        raise ParameterError(unknown[0], f"is not a parameter of {alg.id}; its parameters are: "
                             f"{', '.join(p.name for p in alg.parameters)}")
    ctx = ValidationContext(overwrite=overwrite)
    # inputs first (so outputs can be checked against every input path), in declaration order
    ordered = [p for p in alg.parameters if not p.is_output] + alg.destinations()
    for p in ordered:
        ctx.values[p.name] = p.resolve(params.get(p.name), ctx)
    values = {p.name: ctx.values[p.name] for p in alg.parameters}
    alg().check(values)
    return values


def run(algorithm_id: str, parameters: dict[str, Any] | None = None,
        feedback: Feedback | None = None, overwrite: bool = False,
        report: str | Path | None = None) -> dict[str, Any]:
    """Run an algorithm and return its outputs (``{name: value}``; files as absolute paths).

    Parameters
    ----------
    algorithm_id : str
        ``group:name``, e.g. ``"dem:idw"``.
    parameters : dict
        Parameter values by UPPERCASE name (Python objects or text as on the command line).
        ``OVERWRITE: True`` may be given here instead of ``overwrite``.
    feedback : Feedback, optional
        Progress, messages and cancellation. A silent one is used by default.
    overwrite : bool
        Replace existing outputs (otherwise an existing output is an error).
    report : path, optional
        Write a JSON run report (parameters, versions, timings, outputs, warnings) there.

    Raises
    ------
    ToolboxError
        For every problem the user can fix (bad parameters, unreadable inputs...). No output is
        left behind when a run fails or is canceled.
    """
    feedback = (feedback or Feedback()).step(0, 100)  # run-local messages and timings
    alg_cls = get(algorithm_id)
    started = time.time()
    t0 = time.perf_counter()
    params, overwrite = _pop_overwrite(parameters or {}, overwrite)
    values = validate(alg_cls, params, overwrite)
    staging = OutputStaging()
    report_path = None
    if report is not None:
        report_path = Path(report).expanduser()
        for dest_value in values.values():
            if isinstance(dest_value, Path) and dest_value.absolute() == report_path.absolute():
                raise ParameterError("run report", f"'{report}' is also an output path")
        if report_path.exists() and not overwrite:
            raise ParameterError("run report", f"'{report}' exists; pass --overwrite to replace it")
    staged = dict(values)
    for dest in alg_cls.destinations():
        if values[dest.name] is not None:
            staged[dest.name] = staging.stage(values[dest.name])
    try:
        feedback.set_progress(0)
        result = alg_cls().process(staged, feedback) or {}
        feedback.check_canceled()
        written = set(staging.commit())
    finally:
        staging.rollback()
    outputs = _final_outputs(alg_cls, values, result, written)
    feedback.set_progress(100)
    if report_path is not None:
        from toolbox.report import write_report

        write_report(report_path, alg_cls, values, outputs, feedback, started,
                     time.perf_counter() - t0)
    return outputs


def _final_outputs(alg_cls: type[Algorithm], values: dict[str, Any], result: dict[str, Any],
                   written: set[Path]) -> dict[str, Any]:
    outputs: dict[str, Any] = {}
    for dest in alg_cls.destinations():
        final = values[dest.name]
        if final is None:
            continue
        final_abs = Path(final).expanduser().absolute()
        if final_abs in written:
            outputs[dest.name] = str(final_abs)
        elif dest.name in result:
            raise RuntimeError(f"{alg_cls.id} reported {dest.name} but did not write it")
    declared = {o.name for o in alg_cls.outputs}
    destinations = {d.name for d in alg_cls.destinations()}
    for key, value in result.items():
        if key in declared:
            outputs[key] = value
        elif key not in destinations:
            raise RuntimeError(f"{alg_cls.id} returned undeclared output {key!r}")
    return outputs
