"""What a run reads and writes: every input path (sidecars, a VRT's sources, a project's photos
and the files it names included), the files the outputs plan, and the checks that no output
replaces an input."""

from __future__ import annotations

import logging
import stat
from functools import lru_cache
from pathlib import Path
from typing import Any

from toolbox.algorithm import Algorithm
from toolbox.errors import OutputExistsError, ParameterError
from toolbox.io.staging import SIDECAR_SUFFIXES, STYLE_SIDECARS, protected_paths
from toolbox.parameters import File, Folder, OutputFolder, String

REPORT = "--run-report"  # the run report, as messages name it

def _flatten(value: Any):
    if isinstance(value, (list, tuple)):
        for item in value:
            yield from _flatten(item)
    elif value is not None:
        yield value


def _named(p: Any, path: Any) -> list[str]:
    """The paths a value names: itself; for a text parameter that is no existing path, each
    part of a comma-separated list (``IMAGES``, ``orientation:convert``'s ``INPUT``)."""
    text = str(path)
    try:
        whole = Path(text).expanduser().exists()
    except (OSError, ValueError):  # a string that is no path (too long, NUL...)
        return []
    if isinstance(p, String) and "," in text and not whole:
        return [part.strip() for part in text.split(",") if part.strip()]
    return [text]


def input_paths(alg_cls: type[Algorithm], values: dict[str, Any]) -> dict[Path, str]:
    """Every file the inputs name (whatever the parameter type) and their sidecars, resolved ->
    parameter name; the files of an input folder (a :class:`Folder`, or a text parameter naming
    a folder or a comma-separated list of files and folders) too."""
    out: dict[Path, str] = {}
    for p in alg_cls.parameters:
        if p.is_output:
            continue
        for item in _flatten(values.get(p.name)):
            path = getattr(item, "path", item)
            if not isinstance(path, (str, Path)) or not str(path).strip():
                continue
            for named_path in _named(p, path):
                _add_input(out, p, named_path)
    return out


def _add_input(out: dict[Path, str], p: Any, path: str) -> None:
    """``path`` (its sidecars, a folder's files, a project's files) into ``out`` as ``p``'s."""
    try:
        candidate = Path(path.split("|", 1)[0]).expanduser()
        if isinstance(p, (Folder, String)) and candidate.is_dir():  # an input folder's files
            for named in (f for f in candidate.iterdir() if f.is_file()):
                for protected in protected_paths(named):
                    out.setdefault(protected, p.name)
        elif candidate.is_file():
            for named in [candidate, *_referenced_files(candidate), *_project_files(p, candidate)]:
                for protected in protected_paths(named):
                    out.setdefault(protected, p.name)
    except (OSError, ValueError):  # a string that is no path (too long, NUL...)
        return


def _referenced_files(path: Path) -> list[Path]:
    """Existing files an input reads besides itself: a VRT's sources, or those a small
    YAML/JSON input names (a project's photos and orientation files) relative to its folder."""
    if path.suffix.lower() == ".vrt":
        return _vrt_sources(path)
    if path.suffix.lower() not in (".yaml", ".yml", ".json") or path.stat().st_size > 1 << 20:
        return []
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
        if path.suffix.lower() == ".json":  # (YAML holds JSON, but PyYAML reads it 50x slower)
            import json

            doc = json.loads(text)
        else:
            import yaml

            doc = yaml.safe_load(text)
    except Exception:  # noqa: BLE001 - unreadable: its reader reports it
        return []
    found, stack = [], [doc]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            stack.extend(item.values())
        elif isinstance(item, list):
            stack.extend(item)
        elif isinstance(item, str) and 0 < len(item) < 1024 and "\n" not in item:
            try:
                target = path.parent / Path(item).expanduser()
                if target.is_file():
                    found.append(target)
            except (OSError, ValueError):
                continue
    return found


def _vrt_sources(vrt: Path) -> list[Path]:
    """The files a VRT reads, those of nested VRTs too."""
    found: list[Path] = []
    todo, seen = [vrt], {vrt.resolve()}
    while todo:
        for name in _vrt_files(todo.pop()):
            if name.is_file() and name.resolve() not in seen:
                seen.add(name.resolve())
                found.append(name)
                if name.suffix.lower() == ".vrt":
                    todo.append(name)
    return found


def _vrt_files(vrt: Path) -> list[Path]:
    """The files one VRT names: GDAL's file list of a raster VRT, the ``SrcDataSource`` of an
    OGR VRT (``relativeToVRT="1"``: relative to the VRT's folder; GDAL reads both
    case-insensitively)."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(vrt).getroot()
        if root.tag != "OGRVRTDataSource":
            import rasterio

            with rasterio.open(vrt) as dataset:
                return [Path(name) for name in dataset.files]
    except Exception:  # noqa: BLE001 - unreadable: its reader reports it
        return []
    out = []
    for element in root.iter():
        text = (element.text or "").strip()
        if str(element.tag).lower() != "srcdatasource" or not text:
            continue
        relative = {k.lower(): v.strip() for k, v in element.attrib.items()}.get("relativetovrt")
        out.append(vrt.parent / text if relative == "1" else Path(text))
    return out


def _project_files(p: Any, path: Path) -> list[Path]:
    """For a PROJECT input: the photos its reader resolves (another program's file names them
    by stem, found in its folder) and the camera files it may read beside it."""
    if not isinstance(p, File):  # (a vector or raster layer: the tables module not imported)
        return []
    from toolbox.photogrammetry.tables import PROJECT_EXTENSIONS

    if p.extensions != PROJECT_EXTENSIONS:
        return []
    st = path.stat()
    return list(_project_photos(path.resolve(), st.st_mtime_ns, st.st_size,
                                path.parent.stat().st_mtime_ns))


@lru_cache(maxsize=4)
def _project_photos(path: Path, *state: int) -> tuple[Path, ...]:
    """The existing photos (and camera files) of the project ``path``; cached by the ``state``
    of the file and its folder (a run asks several times)."""
    from toolbox.exchange import CAMERA_FILES
    from toolbox.photogrammetry.tables import load_project_parameter

    logger = logging.getLogger("toolbox.exchange")  # its warnings are the run's, not ours
    level = logger.level
    logger.setLevel(logging.CRITICAL + 1)
    try:
        project = load_project_parameter(path)
    except Exception:  # noqa: BLE001 - unreadable: its reader reports it
        return ()
    finally:
        logger.setLevel(level)
    found = [Path(photo.image) for photo in project.photos.values() if photo.image is not None]
    if path.suffix.lower() not in (".yaml", ".yml"):
        found += [f for pattern in CAMERA_FILES for f in path.parent.glob(pattern)]
    return tuple(f for f in found if f.is_file())


def check_outputs_against_inputs(alg_cls: type[Algorithm], values: dict[str, Any],
                                 inputs: dict[Path, str]) -> None:
    """No output path is an input file (``inputs``: the run's :func:`input_paths`)."""
    for dest in alg_cls.destinations():
        final = values.get(dest.name)
        if final is None:
            continue
        resolved = Path(final).expanduser().resolve()
        if resolved in inputs:
            raise ParameterError(dest.name, f"'{final}' is the input {inputs[resolved]} (or one "
                                 "of its files); an input is never overwritten: choose another "
                                 "output path")


#: input files GDAL, QGIS or SQLite may write themselves while a run reads, the data staying the
#: same (statistics into a PAM file, overviews or a spatial index QGIS builds, its metadata, a
#: reader's journals, a style QGIS saves as the layer's default): not watched by
#: :func:`input_stamps`
_SELF_WRITTEN = (*(s for s in SIDECAR_SUFFIXES if s != ".msk"), ".qix", ".sbn", ".sbx", ".qmd",
                 *STYLE_SIDECARS)


def input_stamps(inputs: dict[Path, str]) -> dict[Path, tuple[int, int, int]]:
    """(inode, size, modification time in ns) of every existing input file (``input_paths``),
    the sidecars GDAL or SQLite may write themselves aside: what tells, at the end of a run,
    that another program wrote an input meanwhile."""
    stamps = {}
    for path in inputs:
        if path.name.lower().endswith(_SELF_WRITTEN):
            continue
        try:
            st = path.stat()
        except OSError:
            continue
        if stat.S_ISREG(st.st_mode) and not _is_sqlite(path):  # (no second stat: is_file())
            stamps[path] = (st.st_ino, st.st_size, st.st_mtime_ns)
    return stamps


def _is_sqlite(path: Path) -> bool:
    """Whether ``path`` is an SQLite database (a GeoPackage...): its readers see one consistent
    state per query, and the last to close one in WAL mode writes the log into it (a new
    modification time, the same content), so it is not watched."""
    try:
        with open(path, "rb") as f:
            return f.read(16) == b"SQLite format 3\x00"
    except OSError:
        return False


def check_inputs_unchanged(inputs: dict[Path, str], stamps: dict[Path, tuple[int, int, int]]
                           ) -> None:
    """Refuse to commit when an input file was written, replaced or removed during the run
    (QGIS saving an edit, another job writing it): what the run read may mix its old and new
    content, so its outputs would be neither's."""
    for path, stamp in stamps.items():
        try:
            st = path.stat()
            now = (st.st_ino, st.st_size, st.st_mtime_ns)
        except OSError:
            now = None
        if now != stamp:
            what = "was removed" if now is None else "was written by another program"
            raise ParameterError(inputs[path], f"'{path}' {what} while the run read it: the "
                                 "outputs could mix its old and new content, so nothing was "
                                 "written; run again once it is no longer being changed")


_GLOB = set("*?[")


def planned_paths(alg_cls: type[Algorithm], values: dict[str, Any]) -> dict[str, list[Path]]:
    """Every file the destinations will write besides their own path (see
    :meth:`Algorithm.planned_files`), as final paths; glob patterns are expanded to the files
    that exist now. Names leaving their folder (``..``, absolute) are refused."""
    plan = alg_cls().planned_files(values) or {}
    out: dict[str, list[Path]] = {}
    for dest in alg_cls.destinations():
        final = values.get(dest.name)
        if final is None:
            continue
        if isinstance(dest, OutputFolder) and dest.name not in plan:
            raise RuntimeError(f"{alg_cls.id} plans no file for its output folder {dest.name}")
        folder = Path(final).expanduser().absolute()
        if not isinstance(dest, OutputFolder):
            folder = folder.parent
        paths: list[Path] = []
        for name in plan.get(dest.name, []):
            relative = Path(str(name))
            if relative.is_absolute() or ".." in relative.parts or not relative.parts:
                raise ParameterError(dest.name, f"would write {str(name)!r}, which is not a file "
                                     f"name inside '{folder}' (check the ids the file names "
                                     "come from)")
            if _GLOB & set(str(name)):
                paths += sorted(folder.glob(str(name)))
            else:
                paths.append(folder / relative)
        out[dest.name] = paths + [p for p in declared_style_files(dest, final)
                                  if p not in paths]
    return out


def declared_style_files(dest: Any, final: Any) -> list[Path]:
    """The default style files (``<stem>.qml``/``.sld``) the runner writes beside each layer
    file of a one-layer-per-file vector output whose declared layer has a style of
    :data:`toolbox.styles.layers.STYLES` (:func:`toolbox.styles.layers.write_declared_style_files`
    ); none for a GeoPackage (its ``layer_styles`` table), a raster or a folder."""
    layers = list(getattr(dest, "layers", []))
    if dest.type_name != "output_vector" or not any(layer.style for layer in layers):
        return []
    from toolbox.io.vector import is_multi_layer, sibling_layer_path
    from toolbox.styles.layers import STYLES, style_file_names

    final = Path(final).expanduser().absolute()
    if is_multi_layer(final):
        return []
    return [p for i, layer in enumerate(layers) if layer.style in STYLES
            for p in style_file_names(final if i == 0 else sibling_layer_path(final, layer.name))]


def declared_layer_files(dest: Any, final: Any) -> list[Path]:
    """The files beside ``final`` that ``dest``'s declared layers go to in a one-layer-per-file
    vector format (``<stem>_<layer><ext>``: :func:`toolbox.io.vector_write.layer_paths`); none
    for a GeoPackage, a raster or a folder."""
    layers = [layer.name for layer in getattr(dest, "layers", [])]
    if len(layers) < 2 or dest.type_name != "output_vector":
        return []
    from toolbox.io.vector import is_multi_layer, sibling_layer_path

    final = Path(final)
    if is_multi_layer(final):
        return []
    return [sibling_layer_path(final, name) for name in layers[1:]]  # the first: ``final``


def check_planned_files(alg_cls: type[Algorithm], values: dict[str, Any],
                        overwrite: bool, inputs: dict[Path, str]) -> None:
    """Each planned file is checked as an output path: not an input (by path, sidecars and the
    files a project names included, or by inode; ``inputs``: the run's :func:`input_paths`),
    not another output, not a folder, and not existing without ``overwrite``."""
    plan = planned_paths(alg_cls, values)
    if not any(plan.values()):
        return
    inodes = {}
    for path, name in inputs.items():
        try:
            st = path.stat()
        except OSError:
            continue
        inodes[(st.st_dev, st.st_ino)] = name
    seen = {Path(values[d.name]).expanduser().resolve(): d.name
            for d in alg_cls.destinations() if values.get(d.name) is not None}
    for dest_name, paths in plan.items():
        for path in paths:
            resolved = path.resolve()
            victim = inputs.get(resolved)
            if victim is None and path.exists():
                st = path.stat()
                victim = inodes.get((st.st_dev, st.st_ino))
            if victim is not None:
                raise ParameterError(dest_name, f"would write '{path}', which is the input "
                                     f"{victim} (or one of its files); an input is never "
                                     "overwritten: choose another output folder or name")
            if resolved in seen:
                raise ParameterError(dest_name, f"would write '{path}' twice (also "
                                     f"{seen[resolved]}): choose another output folder")
            seen[resolved] = dest_name
            if path.is_dir():
                raise ParameterError(dest_name, f"would write '{path}', which is a folder")
            if path.exists() and not overwrite:
                raise OutputExistsError(dest_name, f"would replace '{path}', which exists; "
                                        "pass --overwrite (OVERWRITE=True in Python) to "
                                        "replace it")


def check_report(report: str | Path, alg_cls: type[Algorithm], values: dict[str, Any],
                  overwrite: bool, inputs: dict[Path, str]) -> Path:
    """The run report's path, checked like an output's (``inputs``: the run's
    :func:`input_paths`)."""
    path = Path(report).expanduser()
    resolved = path.resolve()
    if resolved in inputs:
        raise ParameterError(REPORT, f"'{report}' is the input {inputs[resolved]} (or one of its "
                             "files); an input is never overwritten: choose another report path")
    for dest in alg_cls.destinations():
        final = values.get(dest.name)
        if final is not None and Path(final).expanduser().resolve() == resolved:
            raise ParameterError(REPORT, f"'{report}' is also the output {dest.name}")
    for name, paths in planned_paths(alg_cls, values).items():
        if any(p.resolve() == resolved for p in paths):
            raise ParameterError(REPORT, f"'{report}' is also one of the files of {name}")
    if path.is_dir():
        raise ParameterError(REPORT, f"'{report}' is a folder, expected a file path")
    if path.exists() and not overwrite:
        raise OutputExistsError(REPORT, f"'{report}' exists; pass --overwrite to replace it")
    return path

