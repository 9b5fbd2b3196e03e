"""Orthority's files: the different files Orthority ships for the SAME photos agree once read
(independent truth: each was written by another program or by hand), round trips, CSV dialects
and angle units."""

import numpy as np
import pytest

from toolbox.errors import InputDataError, ParameterError
from toolbox.exchange import csvtable, exif, formats, geodesy, orthority
from toolbox.exchange.model import OrientationSet, PhotoOrientation, focal_px, opk_from_matrix
from toolbox.exchange.project import model_cameras
from toolbox.photogrammetry.rotation import rotation_matrix


def _same(a: OrientationSet, b: OrientationSet, metres: float, degrees: float) -> None:
    assert set(a.photos) == set(b.photos)
    for pid, p in a.photos.items():
        q = b.photos[pid]
        assert np.abs(np.subtract(p.xyz, q.xyz)).max() <= metres, pid
        assert np.degrees(np.abs(np.subtract(p.opk, q.opk))).max() <= degrees, pid


def test_ngi_geojson_csv_and_legacy_text_agree(orthority_data):
    """ngi_ext_param.geojson (radians), ngi_xyz_opk.csv (degrees, 3 decimals, .prj) and the
    legacy ngi/camera_pos_ori.txt (degrees, 6 decimals, no header) for the same 4 photos."""
    geojson = orthority.read_exterior(orthority_data / "io/ngi_ext_param.geojson")
    table = csvtable.read_csv(orthority_data / "io/ngi_xyz_opk.csv")
    legacy = csvtable.read_csv(orthority_data / "ngi/camera_pos_ori.txt", crs=geojson.crs)
    assert table.crs.equals(geojson.crs)
    _same(geojson, table, 0.0005 + 1e-9, 0.0005 + 1e-9)
    _same(geojson, legacy, 0.0000005 + 1e-9, 0.0000005 + 1e-9)
    cams = orthority.read_interior(orthority_data / "io/ngi_int_param.yaml")
    legacy_cam = orthority.read_interior(orthority_data / "ngi/config.yaml")
    assert cams.cameras == legacy_cam.cameras
    assert {p.camera for p in geojson.photos.values()} == set(cams.cameras)


def test_drone_tags_agree_with_lla_rpy_csv_and_with_sfm(orthority_data):
    """The images' EXIF/XMP (GNSS, gimbal) read as Orthority's odm_lla_rpy.csv lists them (its
    pitch is the gimbal pitch + 90); their attitudes lie within 2 degrees (whole rotation) of the
    structure-from-motion ones (odm_xyz_opk.csv; gimbal angles are good to a degree or so), a
    wrong rpy convention is tens of degrees off."""
    tags = exif.read_images(sorted((orthority_data / "odm/images").glob("*.tif")))
    table = csvtable.read_csv(orthority_data / "io/odm_lla_rpy.csv")
    _same(tags, table, 0.002, 1e-9)
    sfm = csvtable.read_csv(orthority_data / "io/odm_xyz_opk.csv", crs="EPSG:32651")
    for pid, p in tags.photos.items():
        between = rotation_matrix(*p.opk).T @ rotation_matrix(*sfm.photos[pid].opk)
        assert np.degrees(np.arccos(np.clip((np.trace(between) - 1) / 2, -1, 1))) < 2.0
        assert np.hypot(*np.subtract(p.xyz, sfm.photos[pid].xyz)[:2]) < 0.5


def test_roll_pitch_yaw_analytic():
    """On the central meridian (no convergence): level, heading north -> R = I; heading east ->
    kappa = -90 deg (image top toward east); pitch 30 deg with heading north -> the camera looks
    30 deg forward, i.e. north of nadir."""
    crs = "EPSG:32633"
    level = geodesy.rpy_to_grid_rotation(0, 0, 0, 15.0, 45.0, 100.0, crs)
    assert np.allclose(level, np.eye(3), atol=1e-7)
    east = opk_from_matrix(geodesy.rpy_to_grid_rotation(0, 0, np.pi / 2, 15.0, 45.0, 100.0, crs))
    assert np.degrees(east) == pytest.approx([0, 0, -90], abs=1e-5)
    pitched = geodesy.rpy_to_grid_rotation(0, np.radians(30), 0, 15.0, 45.0, 100.0, crs)
    view = pitched @ [0, 0, -1.0]
    assert view == pytest.approx([0, np.sin(np.radians(30)), -np.cos(np.radians(30))], abs=1e-7)


@pytest.fixture
def small_set():
    oset = OrientationSet(crs=geodesy.require_projected("EPSG:32632", "test"))
    oset.cameras["cam a"] = {"type": "brown", "im_size": [4000, 3000], "focal_len": 0.8,
                             "cx": 0.001, "cy": -0.002, "k1": -0.1, "k2": 0.01, "p1": 0.0001,
                             "p2": -0.0002, "k3": 0.001}
    for k in range(3):
        oset.add_photo(PhotoOrientation(f"IMG_{k}", "cam a", f"IMG_{k}.JPG",
                                        (500000.0 + 30 * k, 5000000.0 - 7.5 * k, 120.0 + k),
                                        (0.01 * k, -0.02, 3.1 - k)))
    return oset


@pytest.mark.parametrize("fmt, name", [("orthority", "x_ext_param.geojson"), ("csv", "x.csv"),
                                       ("patb", "x.ori"), ("project", "x.yaml")])
def test_round_trip(tmp_path, small_set, fmt, name):
    """read(write(set)) == set: positions to the 0.1 mm written, angles to 1e-9 deg."""
    written = formats.write_orientations(small_set, fmt, tmp_path / name)
    back = formats.read_orientations([written[0]], "auto",
                                     "EPSG:32632" if fmt == "patb" else None)
    _same(small_set, back, 5e-5, 1e-9)
    if fmt == "orthority":
        back = formats.merge([back, orthority.read_interior(written[1])])
    if fmt == "orthority" or fmt == "project" and model_cameras():
        assert back.cameras == small_set.cameras
    elif fmt == "project":  # no camera models: the pinhole part survives
        (name, spec), = back.cameras.items()
        original = small_set.cameras[name]
        assert focal_px(spec) == pytest.approx(focal_px(original), rel=1e-12)
        assert (spec["cx"], spec["cy"]) == pytest.approx((original["cx"], original["cy"]))
    if fmt in ("orthority", "project"):
        assert back.crs.equals(small_set.crs)


def test_csv_dialects_and_units(tmp_path):
    """Any column order by header, quoted fields with spaces and delimiters, semicolons, a unit
    in the column names; mixed units and contradicting units refused."""
    prj = "EPSG:32632"
    text = ('kappa [rad];"camera";z;omega [rad];x;"filename";phi [rad];y\n'
            '1.5;"cam; one";120.5;0.01;500000.25;"IMG 1.JPG";-0.02;5000000.75\n')
    (tmp_path / "a.csv").write_text(text)
    (tmp_path / "a.prj").write_text(prj)
    oset = csvtable.read_csv(tmp_path / "a.csv")
    photo = oset.photos["IMG 1"]
    assert photo.camera == "cam; one"
    assert photo.xyz == (500000.25, 5000000.75, 120.5)
    assert photo.opk == pytest.approx((0.01, -0.02, 1.5))
    assert any("rad" in n and "not stated" not in n for n in oset.notes)
    with pytest.raises(ParameterError, match="contradicting"):
        csvtable.read_csv(tmp_path / "a.csv", angle_unit="deg")
    (tmp_path / "b.csv").write_text("filename,x,y,z,omega_deg,phi_rad,kappa_deg\n"
                                    "a,1,2,3,0,0,0\n")
    with pytest.raises(InputDataError, match="mixed angle units"):
        csvtable.read_csv(tmp_path / "b.csv", crs=prj)
    (tmp_path / "c.csv").write_text("filename,x,y,z,omega,phi,kappa\na,1,2,3,0,0,0\n")
    with pytest.raises(InputDataError, match="need a CRS"):
        csvtable.read_csv(tmp_path / "c.csv")
    with pytest.raises(ParameterError, match="contradicts"):
        csvtable.read_csv(tmp_path / "a.csv", crs="EPSG:32633")
