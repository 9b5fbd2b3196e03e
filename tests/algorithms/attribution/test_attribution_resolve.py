"""The coding step's geometry checks for all entities at once against a straightforward
per-entity computation (np.unique per entity, Polygon built per entity, np.nanmin/nanmax/nanmean),
on random entities: points, lines, polygons with holes, multi-lines, 2D and 3D, NaN Z, one-vertex
and empty entities, duplicate vertices, outlines open by less and more than the tolerance.
Also: attribute() in blocks of entities as all at once; the two-table reader's coordinates
parsed in chunks."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from toolbox.attribution.resolve import distinct_xy, resolve_geometries, z_statistics

CLOSURE = 0.5


def _distinct(coords):
    return len(np.unique(np.round(coords[:, :2], 9), axis=0)) if len(coords) else 0


def _one(geom, want):
    """(kind, geometry, reason, detail) of one entity, written out entity by entity."""
    if geom is None or geom.is_empty:
        return None, None, "no_vertices", "no coordinates"
    coords = shapely.get_coordinates(geom, include_z=geom.has_z)
    is_point, is_polygon = geom.geom_type == "Point", geom.geom_type == "Polygon"
    want = want or ("point" if is_point else "polygon" if is_polygon else "line")
    if want == "point":
        if is_point:
            return "point", geom, None, ""
        what = "polygon" if is_polygon else f"line with {len(coords)} vertices"
        return None, None, "type_mismatch", f"the code is a point type, the entity a {what}"
    if want == "line":
        if is_polygon:
            return None, None, "type_mismatch", "the code is a line type, the entity a polygon"
        if is_point or _distinct(coords) < 2:
            return None, None, "degenerate", "line with " + (
                "one vertex" if len(coords) == 1 else "zero length")
        return "line", geom, None, ""
    ring = np.asarray(geom.exterior.coords) if is_polygon else coords
    if is_point or _distinct(ring) < 3:
        return None, None, "degenerate", f"polygon with {_distinct(ring)} distinct vertices"
    detail = ""
    if not is_polygon:
        gap = float(np.hypot(*(ring[-1, :2] - ring[0, :2])))
        if gap > CLOSURE:
            return None, None, "unclosed_polygon", (f"ends {gap:.3f} apart (closure tolerance "
                                                    f"{CLOSURE:g})")
        if gap > 0:
            ring = (np.vstack([ring[:-1], ring[:1]]) if _distinct(ring[:-1]) >= 3
                    else np.vstack([ring, ring[:1]]))
            detail = f"closed: ends {gap:.3f} apart"
        geom = shapely.Polygon(ring)
    if shapely.area(shapely.convex_hull(geom)) <= 0:
        return None, None, "degenerate", "polygon of zero area"
    if not geom.is_valid:
        return None, None, "invalid_polygon", shapely.is_valid_reason(geom)
    return "polygon", geom, None, detail


def _random_entities(rng, n):
    """Entities on a coarse grid (so duplicates, collinear and crossing outlines are common)."""
    geoms, wants = [], []
    for _ in range(n):
        k = int(rng.integers(1, 8))
        xy = rng.integers(0, 4, size=(k, 2)).astype(float) + 1.7e6
        z = rng.normal(250.0, 5.0, k)
        z[rng.random(k) < 0.3] = np.nan
        pts = np.column_stack([xy, z]) if rng.random() < 0.7 else xy
        what = rng.random()
        if what < 0.05:
            g = None
        elif what < 0.1:
            g = shapely.from_wkt(rng.choice(["LINESTRING EMPTY", "POINT EMPTY", "POLYGON EMPTY"]))
        elif what < 0.25:
            g = shapely.Point(pts[0])
        elif what < 0.35 and k >= 4:
            g = shapely.Polygon(pts, holes=[[(1.7e6 + 0.2, 1.7e6 + 0.2), (1.7e6 + 0.4, 1.7e6 + 0.2),
                                             (1.7e6 + 0.3, 1.7e6 + 0.4)]] * int(rng.random() < .3))
        elif what < 0.4 and k >= 3:
            g = shapely.MultiLineString([pts[: k // 2 + 1], pts[k // 2:]])
        else:
            if k > 1 and rng.random() < 0.5:  # an outline open by 0, 0.3 or 1.0
                pts[-1] = pts[0]
                pts[-1, 0] += rng.choice([0.0, 0.3, 1.0])
            g = shapely.LineString(pts) if k > 1 else shapely.Point(pts[0])  # one vertex
        geoms.append(g)
        wants.append(rng.choice([None, "point", "line", "polygon"]))
    return np.array(geoms, dtype=object), np.array(wants, dtype=object)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_resolve_geometries_as_entity_by_entity(seed):
    geoms, wants = _random_entities(np.random.default_rng(seed), 3000)
    kind, shape, reason, detail = resolve_geometries(geoms, wants, CLOSURE)
    expected = [_one(g, w) for g, w in zip(geoms, wants, strict=True)]
    assert list(kind) == [e[0] for e in expected]
    assert list(reason) == [e[2] for e in expected]
    assert list(detail) == [e[3] for e in expected]
    got = shapely.to_wkb(shape, include_srid=False)
    want = shapely.to_wkb(np.array([e[1] for e in expected], dtype=object))
    assert list(got) == list(want)
    # every outcome occurs (the random entities cover every branch)
    assert {r for r in reason} >= {None, "no_vertices", "type_mismatch", "degenerate",
                                   "unclosed_polygon", "invalid_polygon"}
    assert any(d.startswith("closed") for d in detail)


@pytest.mark.parametrize("seed", [0, 1])
def test_z_statistics_as_nanmin_nanmax_nanmean(seed):
    geoms, _ = _random_entities(np.random.default_rng(seed), 3000)
    got = z_statistics(list(geoms))
    for i, g in enumerate(geoms):
        z = (shapely.get_coordinates(g, include_z=True)[:, 2] if g is not None and g.has_z
             else np.zeros(0))
        finite = np.isfinite(z).any()
        for key, f in (("z_min", np.nanmin), ("z_max", np.nanmax), ("z_mean", np.nanmean)):
            np.testing.assert_array_equal(got[key][i], f(z) if finite else np.nan)
    assert np.isfinite(got["z_mean"]).sum() > 1000 and np.isnan(got["z_mean"]).sum() > 100


def test_distinct_xy_as_np_unique():
    rng = np.random.default_rng(3)
    xy = rng.integers(0, 3, size=(4000, 2)).astype(float)
    xy[rng.random(4000) < 0.05, 0] = np.nan
    xy[rng.random(4000) < 0.1] *= -0.0  # -0.0 and 0.0 are the same vertex
    xy += rng.choice([0.0, 1e-12, 1e-6], size=(4000, 1))  # under / over the 1e-9 rounding
    index = np.sort(rng.integers(0, 900, 4000))
    index = index[index != 7]  # a geometry without vertices
    xy = xy[: len(index)]
    distinct, last_unique = distinct_xy(xy, index, 901)
    for g in range(901):
        rows = xy[index == g]
        assert distinct[g] == _distinct(rows)
        assert last_unique[g] == (len(rows) > 0 and _distinct(rows[:-1]) == distinct[g] - 1)


@pytest.mark.parametrize("chunk", [1, 2, 3, 1 << 16])
def test_coordinates_table_read_in_chunks(tmp_path, chunk):
    """The coordinates table parsed a chunk of records at a time gives every record, in order
    (np.loadtxt as the oracle), whatever the chunk size."""
    from toolbox.attribution.restitution import _coordinates

    rng = np.random.default_rng(4)
    xyz = np.round(rng.normal(1000.0, 300.0, (7, 3)), 3)
    path = tmp_path / "coordinate.txt"
    path.write_text("colour;E;N;Z\n" + "".join(f";{e:.3f};{n:.3f};{z:.3f}\n" for e, n, z in xyz))
    got = _coordinates(path, "COORDINATES", chunk)
    np.testing.assert_array_equal(got, np.loadtxt(path, delimiter=";", skiprows=1,
                                                  usecols=(1, 2, 3)))
    assert got.shape == (7, 3)


def test_attribute_in_blocks_as_in_one(tmp_path, monkeypatch):
    """Entities checked a few at a time (blocks of 3) give the same layers and unresolved
    entities as all at once (the realistic export of restitution_files: every reason)."""
    import pandas as pd
    from restitution_files import make_files

    import toolbox.attribution.coding as coding
    from toolbox.attribution.restitution import read_ascii
    from toolbox.io.code_file import read_code_file, read_colour_file

    files = make_files(tmp_path)
    entities = read_ascii(files["export"], crs="EPSG:3003")
    table, colours = read_code_file(files["codes"]), read_colour_file(files["colours"])
    whole = coding.attribute(entities, table, colours)
    monkeypatch.setattr(coding, "BLOCK", 3)
    blocks = coding.attribute(entities, table, colours)
    assert blocks.statistics == whole.statistics and list(blocks.layers) == list(whole.layers)
    assert len(whole.unresolved) == 8  # entities 3, 5, 7, 8, 9, 10, 11, 13
    for name in whole.layers:
        pd.testing.assert_frame_equal(blocks.layers[name], whole.layers[name], check_exact=True)
    pd.testing.assert_frame_equal(blocks.unresolved, whole.unresolved, check_exact=True)
