"""A synthetic OpenSfM reconstruction with known truth: three brown (distortion-free) cameras
over a topocentric frame 2 degrees west of UTM zone 51's central meridian (meridian convergence
-0.86 deg), and ground points each camera sees, with their OpenCV pixels."""

import json

import cv2
import numpy as np
from pyproj import Transformer
from scipy.spatial.transform import Rotation

LAT, LON, ALT = 24.68, 120.95, 30.0
W, H, FOCAL, CX, CY = 1200, 800, 0.8, 0.01, -0.02
SIZE = max(W, H)
K = np.array([[FOCAL * SIZE, 0, CX * SIZE + (W - 1) / 2],   # OpenSfM: pixel = n·size - 0.5 + w/2
              [0, FOCAL * SIZE, CY * SIZE + (H - 1) / 2], [0, 0, 1]])
CENTRES = np.array([[0.0, 0.0, 120.0], [160.0, 40.0, 118.0], [-140.0, 180.0, 125.0]])
#: camera -> topocentric rotations (OpenCV axes): nadir (x east, y south, z down), then tilted
NADIR = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])
ATTITUDES = [Rotation.from_euler("zyx", a, degrees=True).as_matrix() @ NADIR
             for a in ([0.0, 0.0, 0.0], [35.0, 4.0, -3.0], [-120.0, -8.0, 6.0])]


def reconstruction(path, reference=True, projection_type="brown", gps=True):
    shots = {}
    for k, (c, r) in enumerate(zip(CENTRES, ATTITUDES, strict=True)):
        r_w2c = r.T
        shot = {"rotation": cv2.Rodrigues(r_w2c)[0].ravel().tolist(),
                "translation": (-r_w2c @ c).tolist(), "camera": "v2 test cam"}
        if gps:
            shot["gps_position"] = (c + [0.02, -0.01, 0.03]).tolist()
        shots[f"IMG_{k}.JPG"] = shot
    doc = {"cameras": {"v2 test cam": {"projection_type": projection_type, "width": W,
                                       "height": H, "focal_x": FOCAL, "focal_y": FOCAL,
                                       "c_x": CX, "c_y": CY, "k1": 0.0, "k2": 0.0, "p1": 0.0,
                                       "p2": 0.0, "k3": 0.0}},
           "shots": shots}
    if reference:
        doc["reference_lla"] = {"latitude": LAT, "longitude": LON, "altitude": ALT}
    path.write_text(json.dumps([doc]))
    return path


def ground_points(k, n=5):
    """Points seen by camera k (topocentric), and their OpenCV pixels (top-left centre (0, 0))."""
    g = np.linspace(-0.35, 0.35, n)
    rays = np.array([[x, y, 1.0] for x in g for y in g])
    depth = 100.0 + 20.0 * rays[:, 0]
    points = CENTRES[k] + (ATTITUDES[k] @ (rays * depth[:, None]).T).T
    r_w2c = ATTITUDES[k].T
    pixels = cv2.projectPoints(points, cv2.Rodrigues(r_w2c)[0], -r_w2c @ CENTRES[k], K,
                               np.zeros(5))[0].reshape(-1, 2)
    return points, pixels


def topocentric_to_utm(points):
    """Topocentric ENU -> UTM 51N, one PROJ pipeline (independent of the reader's route)."""
    t = Transformer.from_pipeline(
        f"+proj=pipeline +step +inv +proj=topocentric +ellps=WGS84 +lat_0={LAT} +lon_0={LON} "
        f"+h_0={ALT} +step +inv +proj=cart +ellps=WGS84 +step +proj=utm +zone=51 +ellps=WGS84")
    return np.column_stack(t.transform(points[:, 0], points[:, 1], points[:, 2]))
