"""Metashape camera XML and OPK text, ODM gcp_list, PAT-B, and orientation files turned into the
product's project object (images matched by file stem)."""

import logging
import shutil

import cv2
import numpy as np
import pytest
from pyproj import Transformer
from scipy.spatial.transform import Rotation

from tests.toolbox.exchange import exchange_synthetic as syn
from toolbox.errors import InputDataError, ParameterError, ToolboxError
from toolbox.exchange import formats, metashape, odm_gcp, patb, project_from_file
from toolbox.exchange.geodesy import require_projected
from toolbox.exchange.model import OrientationSet, PhotoOrientation
from toolbox.exchange.project import project_from_orientations
from toolbox.photogrammetry.tables import ground_points, image_measurements

TM = "+proj=tmerc +lat_0=0 +lon_0=11 +k=1 +x_0=500000 +y_0=0 +ellps=WGS84 +units=m +no_defs"
W, H, F, CX, CY = 1000, 800, 900.0, 5.0, -3.0


def _enu_to_ecef(lon, lat):
    lo, la = np.radians([lon, lat])
    east = [-np.sin(lo), np.cos(lo), 0]
    north = [-np.sin(la) * np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la)]
    up = [np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)]
    return np.column_stack([east, north, up])


def metashape_xml(path, distortion=""):
    """One sensor, two cameras 300 m above (lon 11.3, lat 43.3), a scaled, rotated chunk."""
    to_ecef = Transformer.from_crs(4979, 4978, always_xy=True)
    r0 = Rotation.from_euler("xyz", [20, -35, 70], degrees=True).as_matrix()
    t0 = np.array(to_ecef.transform(11.3, 43.3, 0.0))
    s0 = 1.7
    cams, truth = [], []
    for k, (lon, tilt) in enumerate([(11.3, [0, 0, 0]), (11.302, [25, 5, -4])]):
        centre = np.array(to_ecef.transform(lon, 43.3, 300.0))
        local = Rotation.from_euler("zyx", tilt, degrees=True).as_matrix()
        r_e = _enu_to_ecef(lon, 43.3) @ local @ np.diag([1.0, -1.0, -1.0])  # OpenCV cam -> ECEF
        t = np.eye(4)
        t[:3, :3], t[:3, 3] = r0.T @ r_e, r0.T @ (centre - t0) / s0
        cams.append(f'<camera id="{k}" sensor_id="0" label="DSC_{k}.JPG"><transform>'
                    + " ".join(f"{v:.17g}" for v in t.ravel()) + "</transform></camera>")
        truth.append((centre, r_e))
    cams.append('<camera id="9" sensor_id="0" label="DSC_9.JPG"/>')
    path.write_text(f"""<?xml version="1.0" encoding="UTF-8"?>
<document version="1.5.0"><chunk label="Chunk 1">
 <sensors><sensor id="0" label="test sensor" type="frame"><resolution width="{W}" height="{H}"/>
  <calibration type="frame" class="adjusted"><resolution width="{W}" height="{H}"/>
   <f>{F}</f><cx>{CX}</cx><cy>{CY}</cy>{distortion}</calibration></sensor></sensors>
 <cameras>{''.join(cams)}</cameras>
 <transform><rotation>{' '.join(f'{v:.17g}' for v in r0.ravel())}</rotation>
  <translation>{' '.join(f'{v:.17g}' for v in t0)}</translation><scale>{s0}</scale></transform>
 <reference>GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],
  PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4326"]]</reference>
</chunk></document>""")
    return truth


def test_metashape_xml_projects_like_opencv(tmp_path):
    """Ground points projected with OpenCV in geocentric coordinates (camera from the chunk and
    camera transforms, K from the calibration) and through the converted orientation on a
    k = 1 transverse Mercator grid agree to 0.02 px; the unaligned camera is listed without
    orientation."""
    truth = metashape_xml(tmp_path / "cams.xml")
    oset = metashape.read_xml(tmp_path / "cams.xml", crs=TM)
    assert not oset.photos["DSC_9"].oriented
    project = project_from_orientations(oset)
    k = np.array([[F, 0, W / 2 + CX - 0.5], [0, F, H / 2 + CY - 0.5], [0, 0, 1]])
    to_grid = Transformer.from_crs(4978, TM, always_xy=True)
    for n, (centre, r_e) in enumerate(truth):
        g = np.linspace(-0.3, 0.3, 4)
        ground = centre + (r_e @ (np.array([[x, y, 1.0] for x in g for y in g]) * 280.0).T).T
        cv = cv2.projectPoints(ground, cv2.Rodrigues(r_e.T)[0], -r_e.T @ centre, k,
                               np.zeros(5))[0].reshape(-1, 2)
        grid = np.column_stack(to_grid.transform(*ground.T))
        ours = project.photo(f"DSC_{n}").ground_to_pixel(grid)
        assert np.abs(ours - (cv + 0.5)).max() < 0.02


def test_metashape_components_compose(tmp_path):
    """A component transform between cameras and chunk (Metashape >= 1.6) gives the same
    orientations as the same cameras written in chunk coordinates."""
    metashape_xml(tmp_path / "flat.xml")
    text = (tmp_path / "flat.xml").read_text()
    comp = Rotation.from_euler("xyz", [10, 20, -30], degrees=True).as_matrix()
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = 2.0 * comp, [3.0, -4.0, 5.0]
    inverse = np.linalg.inv(m)
    cams = text[text.index("<cameras>"):text.index("</cameras>")]
    new = cams
    for k in range(2):
        block = cams.split("<transform>")[k + 1].split("</transform>")[0]
        t = inverse @ np.array([float(v) for v in block.split()]).reshape(4, 4)
        new = new.replace(block, " ".join(f"{v:.17g}" for v in t.ravel()))
    new = new.replace('sensor_id="0"', 'sensor_id="0" component_id="0"')
    component = ('<components><component id="0"><transform><rotation>'
                 + " ".join(f"{v:.17g}" for v in comp.ravel()) + "</rotation><translation>"
                 "3 -4 5</translation><scale>2</scale></transform></component></components>")
    (tmp_path / "comp.xml").write_text(text.replace(cams, component + new))
    flat = metashape.read_xml(tmp_path / "flat.xml", crs=TM)
    composed = metashape.read_xml(tmp_path / "comp.xml", crs=TM)
    for pid in ("DSC_0", "DSC_1"):
        assert np.allclose(flat.photos[pid].xyz, composed.photos[pid].xyz, atol=1e-6, rtol=0)
        assert np.allclose(flat.photos[pid].opk, composed.photos[pid].opk, atol=1e-9, rtol=0)


def test_metashape_tangential_terms_follow_opencv(tmp_path):
    """Metashape's P1/P2 (manual, appendix C) are OpenCV's p2/p1: the manual's formula and
    cv2.projectPoints with the converted spec give the same pixels."""
    k1, p1, p2 = -0.08, 0.0012, -0.0007
    metashape_xml(tmp_path / "d.xml", f"<k1>{k1}</k1><p1>{p1}</p1><p2>{p2}</p2>")
    spec = metashape.read_xml(tmp_path / "d.xml", crs=TM).cameras["test sensor"]
    xy = np.array([[0.3, -0.2], [-0.25, 0.15], [0.05, 0.3]])
    x, y = xy.T
    r2 = x * x + y * y
    xd = x * (1 + k1 * r2) + p1 * (r2 + 2 * x * x) + 2 * p2 * x * y
    yd = y * (1 + k1 * r2) + p2 * (r2 + 2 * y * y) + 2 * p1 * x * y
    manual = np.column_stack([W / 2 + CX + xd * F, H / 2 + CY + yd * F])
    m = max(W, H)
    k = np.array([[spec["focal_len"] * m, 0, W / 2 + spec["cx"] * m - 0.5],
                  [0, spec["focal_len"] * m, H / 2 + spec["cy"] * m - 0.5], [0, 0, 1]])
    cv = cv2.projectPoints(np.column_stack([xy, np.ones(3)]), np.zeros(3), np.zeros(3), k,
                           np.array([spec["k1"], spec["k2"], spec["p1"], spec["p2"],
                                     spec["k3"]]))[0].reshape(-1, 2)
    assert np.abs(cv + 0.5 - manual).max() < 1e-9


def test_metashape_refuses_what_the_schema_cannot_hold(tmp_path):
    metashape_xml(tmp_path / "s.xml", "<b2>3.0</b2>")
    with pytest.raises(InputDataError, match="skew"):
        metashape.read_xml(tmp_path / "s.xml", crs=TM)


def test_metashape_opk_text(tmp_path):
    (tmp_path / "opk.txt").write_text(
        "# Cameras (1)\n# PhotoID, X, Y, Z, Omega, Phi, Kappa\n"
        "DSC_1.JPG\t500000.5\t4800000.25\t450.0\t1.5\t-2.0\t90.0\n")
    assert formats.detect(tmp_path / "opk.txt") == "metashape_opk"
    oset = formats.read_orientations([tmp_path / "opk.txt"], crs="EPSG:32632")
    assert np.degrees(oset.photos["DSC_1"].opk) == pytest.approx([1.5, -2.0, 90.0])


def test_odm_gcp_list_to_measurements(tmp_path):
    """Ground coordinates to the CRS asked (pyproj), names kept or given, ODM pixels + 0.5; the
    written tables read back with the product's readers."""
    (tmp_path / "gcp_list.txt").write_text(
        "EPSG:4326\n11.30 43.30 300.0 100 200 IMG_1.JPG gcp_a\n"
        "11.30\t43.30\t300.0\t150.5\t220.5\tIMG_2.JPG\tgcp_a\n11.31 43.31 310.0 500 400 IMG_1.JPG\n")
    assert formats.detect(tmp_path / "gcp_list.txt") == "gcp"
    control = odm_gcp.read_gcp_list(tmp_path / "gcp_list.txt", "EPSG:32632")
    odm_gcp.write_control(control, tmp_path / "m.csv", tmp_path / "p.csv")
    ids, photos, xy, kind = image_measurements(tmp_path / "m.csv", None, "auto")
    assert kind == "pixel" and ids == ["gcp_a", "gcp_a", "gcp1"]
    assert photos == ["IMG_1", "IMG_2", "IMG_1"]
    assert xy.tolist() == [[100.5, 200.5], [151.0, 221.0], [500.5, 400.5]]
    pid, xyz, _ = ground_points(tmp_path / "p.csv")
    expected = Transformer.from_crs(4326, 32632, always_xy=True).transform(11.31, 43.31)
    assert pid == ["gcp_a", "gcp1"]
    assert xyz[1, :2] == pytest.approx(expected, abs=1e-3) and xyz[1, 2] == 310.0


def test_patb_records(tmp_path):
    """PAT-B's three fixed-column records (I16,16x,3F16.5 / 5F16.12 / 4F16.12) read as centre
    and R (image -> ground); written back in the same columns."""
    from toolbox.photogrammetry.rotation import rotation_matrix

    angles = (0.012, -0.034, 1.234)
    a = rotation_matrix(*angles).ravel()
    text = (f"{101:16d}{'':16}" + "".join(f"{v:16.5f}" for v in (1000.5, 2000.25, 1500.0))
            + "\n" + "".join(f"{v:16.12f}" for v in a[:5]) + "\n"
            + "".join(f"{v:16.12f}" for v in a[5:]) + "\n-99\n")
    (tmp_path / "a.ori").write_text(text)
    assert formats.detect(tmp_path / "a.ori") == "patb"
    oset = patb.read_patb(tmp_path / "a.ori", "EPSG:3003")
    assert oset.photos["101"].xyz == (1000.5, 2000.25, 1500.0)
    assert oset.photos["101"].opk == pytest.approx(angles, abs=1e-11)
    patb.write_patb(oset, tmp_path / "b.ori")
    assert (tmp_path / "b.ori").read_text() == text.removesuffix("-99\n")
    (tmp_path / "c.ori").write_text(text.replace(f"{a[8]:16.12f}", f"{-a[8]:16.12f}"))
    with pytest.raises(InputDataError, match="reflection|orthonormal"):
        patb.read_patb(tmp_path / "c.ori")
    with pytest.raises(ParameterError, match="does not apply"):
        formats.write_orientations(oset, "patb", tmp_path / "d.ori", "deg")

def test_orientation_file_as_project_with_image_folder(tmp_path, caplog):
    """An exterior GeoJSON + its interior YAML beside it become a project; images are matched by
    file stem, an image without orientation is listed and skipped with a warning."""
    oset = OrientationSet(crs=require_projected("EPSG:32632", "test"))
    oset.cameras["cam"] = {"type": "pinhole", "im_size": [400, 300], "focal_len": 0.9}
    for k in range(2):
        oset.add_photo(PhotoOrientation(f"P{k}", "cam", None, (500000.0 + k, 5e6, 100.0),
                                        (0.0, 0.0, 0.0)))
    formats.write_orientations(oset, "orthority", tmp_path / "block_ext_param.geojson")
    images = tmp_path / "images"
    images.mkdir()
    for name in ("P0.tif", "P1.JPG", "extra.tif"):
        (images / name).write_bytes(b"")
    with caplog.at_level(logging.WARNING, logger="toolbox.exchange"):
        project = project_from_file(tmp_path / "block_ext_param.geojson")
    assert "extra" in caplog.text and "skipped" in caplog.text
    assert project.photo("P1").image == (images / "P1.JPG").absolute()
    assert set(project.photos) == {"P0", "P1"}
    with pytest.raises(InputDataError, match="no image file"):
        project_from_file(tmp_path / "block_ext_param.geojson", images=tmp_path / "none")


def test_damaged_files_fail_with_one_line_errors(tmp_path):
    """Empty, binary, truncated and non-finite versions of each format raise a toolbox error
    (one line, naming the file), never another exception nor a non-finite orientation."""
    good = tmp_path / "good"
    good.mkdir()
    syn.reconstruction(good / "reconstruction.json")
    metashape_xml(good / "cams.xml")
    (good / "gcp_list.txt").write_text("EPSG:4326\n11.30 43.30 300.0 100 200 IMG_1.JPG a\n")
    (good / "x.ori").write_text("101 1000.0 2000.0 1500.0\n1 0 0 0 1\n0 0 0 1\n")
    oset = formats.read_orientations([good / "reconstruction.json"])
    formats.write_orientations(oset, "orthority", good / "b_ext_param.geojson")
    formats.write_orientations(oset, "csv", good / "b.csv")
    for src in sorted(good.iterdir()):
        if src.suffix == ".prj":
            continue
        data = src.read_bytes()
        variants = {"empty": b"", "binary": b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4,
                    "text": b"hello world\n", "nan": data.replace(b"1", b"nan", 3),
                    **{f"cut{k}": data[:len(data) * k // 10] for k in (1, 3, 5, 8)}}
        for name, content in variants.items():
            bad = tmp_path / name / src.name
            bad.parent.mkdir(exist_ok=True)
            bad.write_bytes(content)
            if src.with_suffix(".prj").exists():
                shutil.copy(src.with_suffix(".prj"), bad.with_suffix(".prj"))
            try:
                if formats.detect(bad) == "gcp":
                    odm_gcp.read_gcp_list(bad)
                    continue
                out = formats.read_orientations([bad], crs="EPSG:32632", angle_unit="gon")
            except ToolboxError as exc:
                assert "\n" not in str(exc)
                continue
            values = [v for p in out.photos.values() for v in (p.xyz or ()) + (p.opk or ())]
            assert np.isfinite(values).all(), bad
