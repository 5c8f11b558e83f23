#!/usr/bin/env python3
"""topocal export / import checked by each consumer's own library, never by topocal reading its own output.

  OpenCV (cv2)     writes the OpenCV calibration that `topocal import --from opencv` reads, and reads every
                   calibration file topocal writes;
  PyYAML           reads the ROS camera_info and the Kalibr camchain (what ROS' and Kalibr's loaders use);
  mrcal            loads the .cameramodel and projects through it: mrcal.project must equal cv2.projectPoints.

usage: exchange_test.py TOPOCAL_EXE WORK_DIR
"""
import os
import shutil
import subprocess
import sys

import cv2
import mrcal
import numpy as np
import yaml

TOPOCAL, WORK = os.path.abspath(sys.argv[1]), sys.argv[2]
# Numbers go through text with 17 significant digits: they come back to the last bit but for the decimal rounding.
REL = 1e-15
failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print("FAIL:", what, file=sys.stderr)


def close(a, b, what, rel=REL):
    a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
    ok = a.shape == b.shape and np.all(np.abs(a - b) <= rel * np.maximum(1.0, np.abs(b)))
    check(ok, f"{what}: {a} != {b}")


def topocal(*args, expect=0):
    r = subprocess.run([TOPOCAL, *args], cwd=WORK, capture_output=True, text=True)
    check(r.returncode == expect, f"topocal {' '.join(args)}: exit {r.returncode}, expected {expect}: {r.stderr}")
    return r


def write_opencv(name, k, d, w, h):
    fs = cv2.FileStorage(os.path.join(WORK, name), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", w)
    fs.write("image_height", h)
    fs.write("camera_matrix", k)
    fs.write("distortion_coefficients", d)
    fs.release()


def read_opencv(name):
    fs = cv2.FileStorage(os.path.join(WORK, name), cv2.FILE_STORAGE_READ)
    check(fs.isOpened(), f"cv2 cannot open {name}")
    out = (fs.getNode("camera_matrix").mat(), fs.getNode("distortion_coefficients").mat(),
           int(fs.getNode("image_width").real()), int(fs.getNode("image_height").real()))
    fs.release()
    return out


shutil.rmtree(WORK, ignore_errors=True)
os.makedirs(WORK)

# A camera with five distinct coefficients, so that any swapped order shows.
W, H = 1600, 1200
K = np.array([[1510.25, 0, 801.5], [0, 1508.75, 597.25], [0, 0, 1]])
D5 = np.array([[-0.231, 0.0917, 0.00113, -0.00071, -0.0195]])
D4 = D5[:, :4].copy()
rng = np.random.default_rng(13)
# Points in front of the camera, within the image, for projection comparisons.
points = np.column_stack([rng.uniform(-0.45, 0.45, 50), rng.uniform(-0.35, 0.35, 50), np.ones(50)])


def cv_project(k, d):
    px, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), k, d)
    return px.reshape(-1, 2)


# ---- OpenCV in: cv2 writes, topocal imports, cv2 reads topocal's file --------------------------------------------
write_opencv("opencv5.yaml", K, D5, W, H)
topocal("import", "--from", "opencv", "opencv5.yaml", "--out", "cal5.yaml")
k, d, w, h = read_opencv("cal5.yaml")
close(k, K, "import opencv: camera_matrix")
close(d, D5, "import opencv: distortion_coefficients")
check((w, h) == (W, H), "import opencv: image size")
# Four coefficients (k3 = 0) and the 8-coefficient rational form with k4..k6 = 0 are OpenCV files too.
write_opencv("opencv8.yaml", K, np.hstack([D5, np.zeros((1, 3))]), W, H)
topocal("import", "--from", "opencv", "opencv8.yaml", "--out", "cal8.yaml")
close(read_opencv("cal8.yaml")[1], D5, "import opencv (8 coefficients): distortion_coefficients")
write_opencv("rational.yaml", K, np.hstack([D5, [[0.1, 0, 0]]]), W, H)
r = topocal("import", "--from", "opencv", "rational.yaml", "--out", "rational-cal.yaml", expect=2)
check("distortion_coefficients" in r.stderr and "rational" in r.stderr, f"rational model refused with why: {r.stderr}")
check(not os.path.exists(os.path.join(WORK, "rational-cal.yaml")), "refused import leaves no file")

# ---- ROS camera_info: PyYAML reads it as ROS' camera_calibration_parsers does ------------------------------------
topocal("export", "--calibration", "cal5.yaml", "--to", "ros", "--out", "camera.yaml", "--camera-name", "topo_cam")
with open(os.path.join(WORK, "camera.yaml")) as f:
    ros = yaml.safe_load(f)
check(ros["image_width"] == W and ros["image_height"] == H, "ros: image size")
check(ros["camera_name"] == "topo_cam", "ros: camera_name")
check(ros["distortion_model"] == "plumb_bob", "ros: distortion_model")
for key, rows, cols in [("camera_matrix", 3, 3), ("distortion_coefficients", 1, 5), ("rectification_matrix", 3, 3),
                        ("projection_matrix", 3, 4)]:
    check(ros[key]["rows"] == rows and ros[key]["cols"] == cols and len(ros[key]["data"]) == rows * cols,
          f"ros: {key} shape")
    check(all(isinstance(v, float) for v in ros[key]["data"]), f"ros: {key} holds floats for YAML 1.1 readers")
close(np.reshape(ros["camera_matrix"]["data"], (3, 3)), K, "ros: camera_matrix")
close(ros["distortion_coefficients"]["data"], D5, "ros: distortion_coefficients")
close(np.reshape(ros["rectification_matrix"]["data"], (3, 3)), np.eye(3), "ros: rectification_matrix")
close(np.reshape(ros["projection_matrix"]["data"], (3, 4)), np.hstack([K, np.zeros((3, 1))]), "ros: projection_matrix")

# ---- Kalibr camchain: PyYAML reads it as Kalibr's loader does; radtan has no k3 ----------------------------------
r = topocal("export", "--calibration", "cal5.yaml", "--to", "kalibr", "--out", "camchain5.yaml", expect=2)
check("k3" in r.stderr, f"kalibr export of a camera with k3 says why: {r.stderr}")
check(not os.path.exists(os.path.join(WORK, "camchain5.yaml")), "refused export leaves no file")
write_opencv("opencv4.yaml", K, D4, W, H)
topocal("import", "--from", "opencv", "opencv4.yaml", "--out", "cal4.yaml")
topocal("export", "--calibration", "cal4.yaml", "--to", "kalibr", "--out", "camchain.yaml")
with open(os.path.join(WORK, "camchain.yaml")) as f:
    kal = yaml.safe_load(f)
cam0 = kal["cam0"]
check(cam0["camera_model"] == "pinhole" and cam0["distortion_model"] == "radtan", "kalibr: pinhole radtan")
close(cam0["intrinsics"], [K[0, 0], K[1, 1], K[0, 2], K[1, 2]], "kalibr: intrinsics fu fv pu pv")
close(cam0["distortion_coeffs"], D4, "kalibr: distortion_coeffs k1 k2 r1 r2")
check(cam0["resolution"] == [W, H], "kalibr: resolution")

# ---- Kalibr in: a two-camera camchain as kalibr_calibrate_cameras writes it --------------------------------------
with open(os.path.join(WORK, "kalibr-camchain.yaml"), "w") as f:
    f.write("""cam0:
  cam_overlaps: [1]
  camera_model: pinhole
  distortion_coeffs: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
  distortion_model: radtan
  intrinsics: [458.654, 457.296, 367.215, 248.375]
  resolution: [752, 480]
  rostopic: /cam0/image_raw
cam1:
  T_cn_cnm1:
  - [0.9999972564779, 0.0023125068, 0.0003760709, -0.1100738245]
  - [-0.0023138383, 0.9999722269, 0.0069685703, 0.0003991224]
  - [-0.0003599522, -0.0069694215, 0.9999756483, -0.0008537475]
  - [0.0, 0.0, 0.0, 1.0]
  cam_overlaps: [0]
  camera_model: pinhole
  distortion_coeffs: [-0.28368365, 0.07451284, -0.00010473, -3.555907e-05]
  distortion_model: radtan
  intrinsics: [457.587, 456.134, 379.999, 255.238]
  resolution: [752, 480]
  rostopic: /cam1/image_raw
""")
topocal("import", "--from", "kalibr", "kalibr-camchain.yaml", "--camera", "cam1", "--out", "euroc-cam1.yaml")
k, d, w, h = read_opencv("euroc-cam1.yaml")
close(k, [[457.587, 0, 379.999], [0, 456.134, 255.238], [0, 0, 1]], "import kalibr: camera_matrix")
close(d, [-0.28368365, 0.07451284, -0.00010473, -3.555907e-05, 0], "import kalibr: distortion_coefficients")
check((w, h) == (752, 480), "import kalibr: image size")
# Kalibr out and back in gives the same camera (each step checked by the other library above).
topocal("import", "--from", "kalibr", "camchain.yaml", "--out", "cal4-again.yaml")
close(read_opencv("cal4-again.yaml")[1], np.hstack([D4, [[0]]]), "kalibr round trip: distortion_coefficients")
with open(os.path.join(WORK, "fisheye.yaml"), "w") as f:
    f.write("cam0:\n  camera_model: pinhole\n  distortion_model: equidistant\n  intrinsics: [1, 1, 1, 1]\n"
            "  distortion_coeffs: [0, 0, 0, 0]\n  resolution: [10, 10]\n")
r = topocal("import", "--from", "kalibr", "fisheye.yaml", "--out", "fisheye-cal.yaml", expect=2)
check("distortion_model" in r.stderr and "equidistant" in r.stderr, f"equidistant refused with why: {r.stderr}")
r = topocal("import", "--from", "kalibr", "kalibr-camchain.yaml", "--camera", "cam2", "--out", "x.yaml", expect=2)
check("cam2" in r.stderr, f"missing camera named: {r.stderr}")

# ---- mrcal: mrcal.cameramodel loads it and projects exactly as OpenCV does ---------------------------------------
topocal("export", "--calibration", "cal5.yaml", "--to", "mrcal", "--out", "cam.cameramodel")
model = mrcal.cameramodel(os.path.join(WORK, "cam.cameramodel"))
lensmodel, intrinsics = model.intrinsics()
check(lensmodel == "LENSMODEL_OPENCV5", f"mrcal: lens model {lensmodel}")
close(intrinsics, [K[0, 0], K[1, 1], K[0, 2], K[1, 2], *D5.ravel()], "mrcal: intrinsics")
check(list(model.imagersize()) == [W, H], "mrcal: imagersize")
# Same formula evaluated by two libraries: agreement to rounding (1e-9 px is far above double rounding at 1000 px).
close(mrcal.project(points, lensmodel, intrinsics), cv_project(K, D5), "mrcal.project vs cv2.projectPoints", rel=1e-12)

# ---- a calibration topocal fitted itself (topocal's own keys, not a plain OpenCV file) --------------------------
with open(os.path.join(WORK, "board.yaml"), "w") as f:
    f.write("target_type: checkerboard\ntargetCols: 9\ntargetRows: 7\nrowSpacingMeters: 0.002\ncolSpacingMeters: 0.002\n")
topocal("render-target", "--target", "board.yaml", "--width", "800", "--height", "600", "--focal-mm", "5.2",
        "--pixel-pitch-um", "3", "--sigma", "6.3e-5", "--distance-mm", "70", "--supersampling", "2", "--out", "view.png")
topocal("calibrate", "--target", "board.yaml", "--images", "view.png", "--model", "seidel", "--single-view",
        "--focal-mm", "5.2", "--pixel-pitch-um", "3", "--distance-mm", "70", "--out", "fitted.yaml")
k, d, w, h = read_opencv("fitted.yaml")
topocal("export", "--calibration", "fitted.yaml", "--to", "mrcal", "--out", "fitted.cameramodel")
fitted = mrcal.cameramodel(os.path.join(WORK, "fitted.cameramodel"))
close(fitted.intrinsics()[1], [k[0, 0], k[1, 1], k[0, 2], k[1, 2], *d.ravel()], "mrcal (fitted): intrinsics")
# k1 = -6.2 folds well inside this sensor: mrcal gets the valid region as its valid_intrinsics_region contour.
fs = cv2.FileStorage(os.path.join(WORK, "fitted.yaml"), cv2.FILE_STORAGE_READ)
valid_radius_px = fs.getNode("valid_radius_px").real()
check(fs.getNode("valid_region_covers_sensor").real() == 0, "fitted: the valid region does not cover the sensor")
fs.release()
region = fitted.valid_intrinsics_region()
check(region is not None and region.shape[0] >= 4, "mrcal (fitted): valid_intrinsics_region present")
if region is not None:
    close(np.hypot(region[:, 0] - k[0, 2], region[:, 1] - k[1, 2]), np.full(region.shape[0], valid_radius_px),
          "mrcal (fitted): valid_intrinsics_region is the valid circle", rel=1e-12)
fs = cv2.FileStorage(os.path.join(WORK, "cal5.yaml"), cv2.FILE_STORAGE_READ)
covers5 = fs.getNode("valid_region_covers_sensor").real() == 1
fs.release()
check((model.valid_intrinsics_region() is None) == covers5, "mrcal: a valid region only where the model folds")
topocal("export", "--calibration", "fitted.yaml", "--to", "ros", "--out", "fitted-ros.yaml")
with open(os.path.join(WORK, "fitted-ros.yaml")) as f:
    close(yaml.safe_load(f)["distortion_coefficients"]["data"], d, "ros (fitted): distortion_coefficients")

if failures:
    print(f"{len(failures)} check(s) failed", file=sys.stderr)
    sys.exit(1)
shutil.rmtree(WORK, ignore_errors=True)
print("all exchange checks passed")
