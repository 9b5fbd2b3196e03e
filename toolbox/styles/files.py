"""Style files of a code table: one QML and one SLD per code, and one categorised pair per
geometry kind (for a layer holding every code of that kind)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

from toolbox.io.code_file import CodeTable
from toolbox.styles.model import layer_style
from toolbox.styles.qml import qml_document
from toolbox.styles.sld import sld_document

KIND_LAYERS = {"point": "points", "line": "lines", "polygon": "polygons"}


def write_code_styles(folder: str | Path, table: CodeTable,
                      colours: dict[str, tuple[int, int, int]] | None) -> list[Path]:
    """Write ``<code>.qml``/``.sld`` for every code (drawn as its declared kind, lines when
    none) and ``points``/``lines``/``polygons`` categorised styles. Returns the files."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    by_kind: dict[str, list[str]] = {}
    for code, entry in table.entries.items():
        kind = entry.kind or "line"
        by_kind.setdefault(kind, []).append(code)
        written += _write(folder, code, layer_style(code, kind, [code], table, colours))
    for kind, codes in by_kind.items():
        name = KIND_LAYERS[kind]
        written += _write(folder, name, layer_style(name, kind, sorted(codes), table, colours))
    return written


def _write(folder: Path, name: str, style) -> list[Path]:
    qml, sld = folder / f"{name}.qml", folder / f"{name}.sld"
    qml.write_text(qml_document(style), encoding="utf-8")
    sld.write_text(sld_document(style), encoding="utf-8")
    return [qml, sld]


def write_style_files(stem: Path, qml: str, sld: str | None) -> None:
    """``<stem>.qml`` and, when given, ``<stem>.sld`` (UTF-8): the default style QGIS loads with
    a one-layer file ``<stem>.shp`` (or ``.fgb``, ``.geojson``...)."""
    stem.with_name(f"{stem.name}.qml").write_text(qml, encoding="utf-8")
    if sld:
        stem.with_name(f"{stem.name}.sld").write_text(sld, encoding="utf-8")


def write_layer_style_files(target: Path, qml: str, sld: str | None,
                            fields: Sequence[str] | None = None,
                            referenced: Iterable[str | None] = ()) -> None:
    """The style ``qml``/``sld`` beside the one-layer file ``target`` (``<stem>.qml``/``.sld``,
    :func:`write_style_files`). A Shapefile holds its field names cut to 10 characters (and
    made unique: ``quadrati_1``): its style names them as the file holds them, read from the
    file (:func:`toolbox.io.vector_write.shapefile_renames`): by the order ``fields`` were
    written when the writer knows it (exact), else each ``referenced`` field by its cut when
    the file holds that. The one writer of attribution's styles and the runner's declared
    ones."""
    from toolbox.io.vector import vector_driver
    from toolbox.io.vector_write import rename_style_fields, shapefile_renames

    if target.is_file() and vector_driver(target) == "ESRI Shapefile" and (fields or referenced):
        renames = shapefile_renames(target, fields, referenced)
        qml, sld = rename_style_fields(qml, renames), rename_style_fields(sld, renames)
    write_style_files(target.with_suffix(""), qml, sld)
