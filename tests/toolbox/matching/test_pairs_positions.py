"""Pairs chosen from approximate positions (toolbox.matching.pairs.neighbour_pairs) and the
positions themselves (toolbox.matching.positions): brute-force distances, hand-built layouts,
and the real ODM frames' EXIF GPS against OpenSfM's own conversion of it (reconstruction.json's
``gps_position``, topocentric metres)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from toolbox.errors import InputDataError
from toolbox.matching.pairs import neighbour_pairs
from toolbox.matching.positions import exif_lonlat, lonlat_to_local, read_positions


def grid(lines: int, per_line: int, forward: float, side: float) -> np.ndarray:
    return np.array([[line * side, k * forward] for line in range(lines)
                     for k in range(per_line)], dtype="float64")


def test_each_photo_gets_its_k_nearest_by_brute_force():
    rng = np.random.default_rng(2)
    xy = grid(5, 12, 100.0, 300.0) + rng.normal(0, 10.0, (60, 2))
    pairs = {(i, j) for i, j, _ in neighbour_pairs(xy, k=6)}
    d = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    for i in range(len(xy)):
        for j in np.argsort(d[i])[:6]:
            assert (min(i, j), max(i, j)) in pairs
    assert all(i < j for i, j in pairs)
    # about 8 pairs a photo, not all 1770
    per_photo = np.bincount(np.array(list(pairs)).ravel(), minlength=len(xy))
    assert per_photo.min() >= 6 and len(pairs) < 6 * len(xy)


def test_strips_are_linked_when_the_nearest_all_lie_along_one_strip():
    # 90 % forward overlap: a photo's 8 nearest are all on its own strip (4 each way)
    xy = grid(3, 20, 50.0, 1000.0)
    strip = np.repeat(np.arange(3), 20)
    knn_only = {(i, j) for i, j, _ in neighbour_pairs(xy[:20], k=8)}
    assert all(strip[i] == strip[j] for i, j in knn_only)
    pairs = neighbour_pairs(xy, k=8)
    across = [(i, j) for i, j, _ in pairs if strip[i] != strip[j]]
    linked = {(strip[i], strip[j]) for i, j in across}
    assert {(0, 1), (1, 2)} <= linked
    # ... but not by the long edges that would join the far ends of an L-shaped block
    corner = np.vstack([grid(1, 20, 50.0, 0.0), grid(1, 20, 50.0, 0.0)[:, ::-1] + [50.0, 0.0]])
    longest = max(np.hypot(*(corner[i] - corner[j])) for i, j, _ in neighbour_pairs(corner, 4))
    assert longest < 300.0


def test_degenerate_layouts():
    assert neighbour_pairs(np.zeros((1, 2))) == []
    assert neighbour_pairs(np.array([[0.0, 0.0], [1.0, 0.0]])) == [(0, 1, None)]
    line = np.column_stack([np.arange(10.0), np.zeros(10)])  # collinear: no triangulation
    # each photo's 2 nearest: both neighbours, or the next two at the ends
    assert {(i, j) for i, j, _ in neighbour_pairs(line, k=2)} == \
        {(i, i + 1) for i in range(9)} | {(0, 2), (7, 9)}


def test_exif_tags_are_read_with_their_hemispheres():
    tags = {"EXIF_GPSLatitude": "(24) (40) (49.0009)", "EXIF_GPSLatitudeRef": "S",
            "EXIF_GPSLongitude": "(120) (57) (6.1257)", "EXIF_GPSLongitudeRef": "W"}
    lon, lat = exif_lonlat(tags)
    assert lat == pytest.approx(-(24 + 40 / 60 + 49.0009 / 3600), abs=1e-12)
    assert lon == pytest.approx(-(120 + 57 / 60 + 6.1257 / 3600), abs=1e-12)
    assert exif_lonlat({}) is None
    assert exif_lonlat({**tags, "EXIF_GPSLatitude": "(0) (0) (0)",
                        "EXIF_GPSLongitude": "(0) (0) (0)"}) is None  # no fix
    assert exif_lonlat({**tags, "EXIF_GPSLatitude": "(24) (40)"}) is None


def test_local_projection_against_pyproj():
    from pyproj import Geod

    lon = np.array([11.30, 11.31, 11.325])
    lat = np.array([43.31, 43.318, 43.305])
    xy = lonlat_to_local(lon, lat)
    geod = Geod(ellps="WGS84")
    for i in range(3):
        for j in range(i + 1, 3):
            _, _, dist = geod.inv(lon[i], lat[i], lon[j], lat[j])
            # the ellipsoid's radii at the mean latitude: 1e-4 over about 2 km
            assert np.hypot(*(xy[i] - xy[j])) == pytest.approx(dist, rel=1e-4)


def test_positions_csv(tmp_path):
    log = tmp_path / "gnss.csv"
    log.write_text("photo,x,y\nb.jpg,10,20\na,1.5,2\n")
    assert read_positions(log, ["a", "b"]).tolist() == [[1.5, 2.0], [10.0, 20.0]]
    degrees = tmp_path / "lonlat.csv"
    degrees.write_text("image;lat;lon\na;43.31;11.30\nb;43.31;11.31\n")
    xy = read_positions(degrees, ["a", "b"])
    assert np.hypot(*(xy[1] - xy[0])) == pytest.approx(810.0, rel=0.01)  # 0.01 deg of longitude
    with pytest.raises(InputDataError, match="no position for 1 photo.*: c"):
        read_positions(log, ["a", "b", "c"])
    bad = tmp_path / "bad.csv"
    bad.write_text("photo,x,y\na,1,north\n")
    with pytest.raises(InputDataError, match="data line 1"):
        read_positions(bad, ["a"])
    with pytest.raises(InputDataError, match="photo"):
        (tmp_path / "nocol.csv").write_text("name,x,y\na,1,2\n")
        read_positions(tmp_path / "nocol.csv", ["a"])


def test_real_exif_positions_agree_with_opensfm(orthority_data):
    """The ODM frames' EXIF GPS, read through GDAL and projected locally, against OpenSfM's
    topocentric conversion of the same tags (its own code): same baselines within 5 cm."""
    from toolbox.matching.images import ImageSource

    odm = orthority_data / "odm"
    shots = json.loads((odm / "opensfm" / "reconstruction.json").read_text())[0]["shots"]
    names = sorted(shots)
    lonlat = np.array([ImageSource.open(odm / "images" / f"{n}.tif").lonlat for n in names])
    ours = lonlat_to_local(lonlat[:, 0], lonlat[:, 1])
    theirs = np.array([shots[n]["gps_position"][:2] for n in names])
    np.testing.assert_allclose(ours - ours[0], theirs - theirs[0], atol=0.05)


def test_a_folder_of_drone_frames_pairs_by_their_exif(orthority_data):
    """The ODM folder (no project, no log): pairs come from the frames' EXIF GPS; with one
    neighbour each, the nearest frame of each is paired (brute force on OpenSfM's positions)."""
    from toolbox.matching.block import TiePointOptions, select_pairs
    from toolbox.matching.inputs import photos_from_folder

    odm = orthority_data / "odm"
    photos = photos_from_folder(odm / "images")
    pairs, how = select_pairs(photos, TiePointOptions(neighbours=1))
    assert how == "neighbours (EXIF GPS)"
    shots = json.loads((odm / "opensfm" / "reconstruction.json").read_text())[0]["shots"]
    xy = np.array([shots[p.id]["gps_position"][:2] for p in photos])
    d = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    nearest = {(min(i, int(j)), max(i, int(j))) for i, j in enumerate(d.argmin(axis=1))}
    assert nearest <= {(i, j) for i, j, _ in pairs}
