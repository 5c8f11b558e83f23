#!/usr/bin/env python3
"""topocal export / import checked by each consumer's own library, never by topocal reading its own output.

  OpenCV (cv2)     writes the OpenCV calibration that `topocal import --from opencv` reads, and reads every
                   calibration file topocal writes;
  PyYAML           reads the ROS camera_info and the Kalibr camchain (what ROS' and Kalibr's loaders use), and
                   writes the camera_info files that `topocal import --from ros` reads;
  mrcal            loads the .cameramodel and projects through it: mrcal.project must equal cv2.projectPoints;
                   and writes the models (also one from a solve, with its optimization_inputs) that
                   `topocal import --from mrcal` reads.

usage: exchange_test.py TOPOCAL_EXE WORK_DIR
"""
import json
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
# OpenCV's rational model (CALIB_RATIONAL_MODEL) with k4..k6 set is topocal's rational8: all eight come back.
D8 = np.hstack([D5, [[0.1, -0.013, 0.0021]]])
write_opencv("rational.yaml", K, D8, W, H)
topocal("import", "--from", "opencv", "rational.yaml", "--out", "rational-cal.yaml")
close(read_opencv("rational-cal.yaml")[1], D8, "import opencv (rational): distortion_coefficients")
# Twelve coefficients: the thin-prism terms are not a topocal model; refused naming the coefficient.
write_opencv("prism.yaml", K, np.hstack([D8, [[0.001, 0, 0, 0]]]), W, H)
r = topocal("import", "--from", "opencv", "prism.yaml", "--out", "prism-cal.yaml", expect=2)
check("distortion_coefficients" in r.stderr and "coefficient 9" in r.stderr, f"thin prism refused with why: {r.stderr}")
check(not os.path.exists(os.path.join(WORK, "prism-cal.yaml")), "refused import leaves no file")

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
# The rational model out: LENSMODEL_OPENCV8, projecting in mrcal as cv2 projects the source file.
topocal("export", "--calibration", "rational-cal.yaml", "--to", "mrcal", "--out", "rational.cameramodel")
lensmodel, intrinsics = mrcal.cameramodel(os.path.join(WORK, "rational.cameramodel")).intrinsics()
check(lensmodel == "LENSMODEL_OPENCV8", f"mrcal (rational): lens model {lensmodel}")
close(intrinsics, [K[0, 0], K[1, 1], K[0, 2], K[1, 2], *D8.ravel()], "mrcal (rational): intrinsics")
close(mrcal.project(points, lensmodel, intrinsics), cv_project(K, D8), "mrcal.project vs cv2.projectPoints (rational)",
      rel=1e-12)

# ---- mrcal in: mrcal.cameramodel(...).write writes the model, topocal imports it ----------------------------------
def mrcal_write(name, lensmodel, intrinsics, **kwargs):
    mrcal.cameramodel(intrinsics=(lensmodel, np.asarray(intrinsics, dtype=float)), imagersize=(W, H),
                      **kwargs).write(os.path.join(WORK, name))


def five(distortion):
    return np.concatenate([np.ravel(distortion), np.zeros(5)])[:5]


# mrcal writes 10 significant digits; K and D5 have fewer, so every number comes back exactly.
CORE = [K[0, 0], K[1, 1], K[0, 2], K[1, 2]]
for lensmodel, distortion in [("LENSMODEL_OPENCV5", D5.ravel()), ("LENSMODEL_OPENCV4", D4.ravel()),
                              ("LENSMODEL_OPENCV8", [*D5.ravel(), 0, 0, 0]), ("LENSMODEL_PINHOLE", [])]:
    name = lensmodel.split("_")[1].lower()
    mrcal_write(f"mrcal-{name}.cameramodel", lensmodel, [*CORE, *distortion])
    topocal("import", "--from", "mrcal", f"mrcal-{name}.cameramodel", "--out", f"from-mrcal-{name}.yaml")
    k, d, w, h = read_opencv(f"from-mrcal-{name}.yaml")
    close(k, K, f"import mrcal {lensmodel}: camera_matrix")
    close(d, five(distortion), f"import mrcal {lensmodel}: distortion_coefficients")
    check((w, h) == (W, H), f"import mrcal {lensmodel}: image size")
# The imported camera projects as mrcal projects the source model (two libraries, the same formula).
k, d, _, _ = read_opencv("from-mrcal-opencv5.yaml")
source = mrcal.cameramodel(os.path.join(WORK, "mrcal-opencv5.cameramodel"))
close(cv_project(k, d), mrcal.project(points, *source.intrinsics()), "import mrcal: cv2 projects as mrcal", rel=1e-12)
# A model with extrinsics and a valid-intrinsics contour (read over, ignored).
mrcal_write("mrcal-region.cameramodel", "LENSMODEL_OPENCV5", [*CORE, *D5.ravel()],
            extrinsics_rt_fromref=np.array([0.01, -0.02, 0.03, 0.1, 0.2, 0.3]),
            valid_intrinsics_region=np.array([[10.0, 20.0], [1500.0, 20.0], [1500.0, 1100.0], [10.0, 20.0]]))
topocal("import", "--from", "mrcal", "mrcal-region.cameramodel", "--out", "from-mrcal-region.yaml")
close(read_opencv("from-mrcal-region.yaml")[1], D5, "import mrcal (extrinsics, region): distortion_coefficients")


# A model as mrcal-calibrate-cameras writes it: from a solve, with its optimization_inputs (a bytes literal of
# ~30 kB) and icam_intrinsics. A small synthetic, noise-free chessboard solve.
def mrcal_solved_model():
    truth = mrcal.cameramodel(intrinsics=("LENSMODEL_OPENCV5", np.array([*CORE, *D5.ravel()])), imagersize=(W, H))
    np.random.seed(0)
    q, rt_ref_board = mrcal.synthesize_board_observations(
        [truth], object_width_n=10, object_height_n=9, object_spacing=0.1, calobject_warp=None,
        rt_ref_boardcenter=np.array([0, 0, 0, 0, 0, 3.0]),
        rt_ref_boardcenter__noiseradius=np.array([0.3, 0.3, 0.3, 0.5, 0.5, 0.5]), Nframes=12)
    n = q.shape[0]
    inputs = dict(
        intrinsics=truth.intrinsics()[1][None, :].copy(), extrinsics_rt_fromref=np.zeros((0, 6)),
        frames_rt_toref=mrcal.rt_from_Rt(rt_ref_board), points=None,
        observations_board=np.concatenate([q[:, 0], np.ones(q[:, 0].shape[:-1] + (1,))], axis=-1),
        indices_frame_camintrinsics_camextrinsics=np.column_stack(
            [np.arange(n), np.zeros(n), -np.ones(n)]).astype(np.int32),
        observations_point=None, indices_point_camintrinsics_camextrinsics=None, lensmodel="LENSMODEL_OPENCV5",
        imagersizes=np.array([[W, H]], dtype=np.int32), calobject_warp=None, do_optimize_intrinsics_core=True,
        do_optimize_intrinsics_distortions=True, do_optimize_extrinsics=True, do_optimize_frames=True,
        do_optimize_calobject_warp=False, calibration_object_spacing=0.1, verbose=False,
        do_apply_regularization=True, do_apply_outlier_rejection=False)
    mrcal.optimize(**inputs)
    return mrcal.cameramodel(optimization_inputs=inputs, icam_intrinsics=0)


mrcal_solved_model().write(os.path.join(WORK, "mrcal-solved.cameramodel"))
with open(os.path.join(WORK, "mrcal-solved.cameramodel")) as f:
    check("'optimization_inputs': b'" in f.read(), "mrcal wrote the solve's optimization_inputs")
solved = mrcal.cameramodel(os.path.join(WORK, "mrcal-solved.cameramodel")).intrinsics()[1]  # as mrcal reads it
topocal("import", "--from", "mrcal", "mrcal-solved.cameramodel", "--out", "from-mrcal-solved.yaml")
k, d, w, h = read_opencv("from-mrcal-solved.yaml")
close([k[0, 0], k[1, 1], k[0, 2], k[1, 2], *d.ravel()], solved, "import mrcal (a solve): intrinsics")
check((w, h) == (W, H), "import mrcal (a solve): image size")
# OPENCV8 with k5 set: the rational model, all eight coefficients.
mrcal_write("mrcal-rational.cameramodel", "LENSMODEL_OPENCV8", [*CORE, *D5.ravel(), 0, 0.004, 0])
topocal("import", "--from", "mrcal", "mrcal-rational.cameramodel", "--out", "from-mrcal-rational.yaml")
close(read_opencv("from-mrcal-rational.yaml")[1], [[*D5.ravel(), 0, 0.004, 0]], "import mrcal (rational): coefficients")
# Lens models topocal cannot hold: refused naming the model, no file written.
splined = "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=12_fov_x_deg=100"
mrcal_write("mrcal-splined.cameramodel", splined, [*CORE, *np.zeros(mrcal.lensmodel_num_params(splined) - 4)])
mrcal_write("mrcal-stereographic.cameramodel", "LENSMODEL_STEREOGRAPHIC", CORE)
for name, words in [("splined", ["lensmodel", splined]), ("stereographic", ["lensmodel", "LENSMODEL_STEREOGRAPHIC"])]:
    r = topocal("import", "--from", "mrcal", f"mrcal-{name}.cameramodel", "--out", f"from-mrcal-{name}.yaml", expect=2)
    check(all(word in r.stderr for word in [f"mrcal-{name}.cameramodel", *words]) and r.stderr.count("\n") == 1,
          f"import mrcal {name}: one line naming the file, key and model: {r.stderr}")
    check(not os.path.exists(os.path.join(WORK, f"from-mrcal-{name}.yaml")), f"import mrcal {name}: no file written")
# topocal's own export comes back to the last bit (17 significant digits, read correctly rounded).
topocal("import", "--from", "mrcal", "cam.cameramodel", "--out", "cal5-via-mrcal.yaml")
k, d, w, h = read_opencv("cal5-via-mrcal.yaml")
close(k, K, "mrcal round trip: camera_matrix", rel=1e-12)
close(d, D5, "mrcal round trip: distortion_coefficients", rel=1e-12)


# ---- ROS in: PyYAML writes the camera_info, topocal imports it ----------------------------------------------------
def camera_info(k, distortion_model, distortion):
    return {"image_width": W, "image_height": H, "camera_name": "pyyaml_cam",
            "camera_matrix": {"rows": 3, "cols": 3, "data": np.ravel(k).tolist()},
            "distortion_model": distortion_model,
            "distortion_coefficients": {"rows": 1, "cols": len(distortion), "data": [float(v) for v in distortion]},
            "rectification_matrix": {"rows": 3, "cols": 3, "data": np.eye(3).ravel().tolist()},
            "projection_matrix": {"rows": 3, "cols": 4, "data": np.hstack([k, np.zeros((3, 1))]).ravel().tolist()}}


def yaml_write(name, info, **kwargs):
    with open(os.path.join(WORK, name), "w") as f:
        yaml.safe_dump(info, f, **kwargs)


# Block style (PyYAML's default: a list at its key's indentation) and flow style for the lists, as ROS writes them.
for name, distortion_model, distortion, style in [("plumb-bob", "plumb_bob", D5.ravel(), {}),
                                                  ("rational", "rational_polynomial", [*D5.ravel(), 0, 0, 0], {}),
                                                  ("flow", "plumb_bob", D5.ravel(), {"default_flow_style": None})]:
    yaml_write(f"ros-{name}.yaml", camera_info(K, distortion_model, distortion), **style)
    topocal("import", "--from", "ros", f"ros-{name}.yaml", "--out", f"from-ros-{name}.yaml")
    k, d, w, h = read_opencv(f"from-ros-{name}.yaml")
    close(k, K, f"import ros {name}: camera_matrix")
    close(d, D5, f"import ros {name}: distortion_coefficients")
    check((w, h) == (W, H), f"import ros {name}: image size")
for name, info, words in [
        ("equidistant", camera_info(K, "equidistant", [0.1, 0.01, 0.001, 0.0001]), ["distortion_model", "equidistant"]),
        ("nan", camera_info(K, "plumb_bob", [*D5.ravel()[:4], float("nan")]), ["distortion_coefficients.data"]),
        ("cx-outside", camera_info(K + [[0, 0, 900], [0, 0, 0], [0, 0, 0]], "plumb_bob", D5.ravel()),
         ["camera_matrix", "principal point"])]:
    yaml_write(f"ros-{name}.yaml", info)
    r = topocal("import", "--from", "ros", f"ros-{name}.yaml", "--out", f"from-ros-{name}.yaml", expect=2)
    check(all(word in r.stderr for word in [f"ros-{name}.yaml", *words]) and r.stderr.count("\n") == 1,
          f"import ros {name}: one line naming the file and key: {r.stderr}")
    check(not os.path.exists(os.path.join(WORK, f"from-ros-{name}.yaml")), f"import ros {name}: no file written")
# rational_polynomial with k4..k6 set: the rational model, out to ROS and back to the last bit.
yaml_write("ros-rational-k4.yaml", camera_info(K, "rational_polynomial", D8.ravel()))
topocal("import", "--from", "ros", "ros-rational-k4.yaml", "--out", "from-ros-rational-k4.yaml")
close(read_opencv("from-ros-rational-k4.yaml")[1], D8, "import ros rational_polynomial: coefficients")
topocal("export", "--calibration", "rational-cal.yaml", "--to", "ros", "--out", "rational-camera.yaml")
with open(os.path.join(WORK, "rational-camera.yaml")) as f:
    ros8 = yaml.safe_load(f)
check(ros8["distortion_model"] == "rational_polynomial" and ros8["distortion_coefficients"]["cols"] == 8,
      "ros (rational): rational_polynomial, 8 coefficients")
close(ros8["distortion_coefficients"]["data"], D8, "ros (rational): distortion_coefficients", rel=1e-12)
# topocal's own export comes back to the last bit.
topocal("import", "--from", "ros", "camera.yaml", "--out", "cal5-via-ros.yaml")
k, d, w, h = read_opencv("cal5-via-ros.yaml")
close(k, K, "ros round trip: camera_matrix", rel=1e-12)
close(d, D5, "ros round trip: distortion_coefficients", rel=1e-12)

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

# ---- A device file leaves through its OpenCV view (model/opencv_view.h) -------------------------------------------
# A Brown lens with a centre, on a camera rolled by 180 deg with non-square pixels: K and distCoeffs follow from the
# conventions of docs/camera-conventions.md alone (M = -I, P = diag(p, p aspect)): fx = a / p_u, fy = a / p_v,
# c = pp + M centre / P, (p1, p2) turned by M, k1, k2, k3 unchanged.
A_MM, PITCH_UM, ASPECT, PP, CENTRE = 5.23, 1.12, 1.0004, (801.5, 597.25), (0.004, -0.003)
KD = [-0.021, 0.0046, 0.00031, -0.00022, -0.0011]
device = {"format": "topocal-device", "format_version": 1,
          "camera": {"pixel_pitch_um": PITCH_UM, "pixel_aspect": ASPECT, "width_px": W, "height_px": H,
                     "principal_point_px": list(PP), "a_mm": A_MM, "orientation": "rotate_180"},
          "distortion": {"model": "brown", "k": KD, "centre_mm": list(CENTRE)},
          "screen_pose": {"rx_deg": 0.5, "ry_deg": 0, "rz_deg": 0, "tx_mm": 0, "ty_mm": 0, "tz_mm": 0,
                          "radial_scale": 1.0}}
with open(os.path.join(WORK, "lens-device.json"), "w") as f:
    json.dump(device, f)
p_u = PITCH_UM * 1e-3
p_v = p_u * ASPECT
K_DEV = np.array([[A_MM / p_u, 0, PP[0] - CENTRE[0] / p_u], [0, A_MM / p_v, PP[1] - CENTRE[1] / p_v], [0, 0, 1]])
D_DEV = np.array([[KD[0], KD[1], -KD[2], -KD[3], KD[4]]])
r = topocal("export", "--device", "lens-device.json", "--to", "opencv", "--out", "device-cal.yaml")
check("screen pose" in r.stdout, f"export --device says the screen pose stays behind: {r.stdout}")
k_read, d_read, w_read, h_read = read_opencv("device-cal.yaml")
close(k_read, K_DEV, "device -> opencv: camera_matrix")
close(d_read, D_DEV, "device -> opencv: distortion_coefficients")
check((w_read, h_read) == (W, H), f"device -> opencv: image size {w_read} x {h_read}")
topocal("export", "--device", "lens-device.json", "--to", "mrcal", "--out", "device.cameramodel")
lensmodel, intrinsics = mrcal.cameramodel(os.path.join(WORK, "device.cameramodel")).intrinsics()
close(mrcal.project(points, lensmodel, intrinsics), cv_project(K_DEV, D_DEV), "device -> mrcal: projection", rel=1e-12)
# A Seidel device: Brown's k1 = sigma a^2 / M_T^3 (paper Eq. 18), no other coefficient.
DEMO_DEVICE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "data", "demo-unit-device.json")
topocal("export", "--device", DEMO_DEVICE, "--to", "ros", "--out", "demo-ros.yaml")
with open(os.path.join(WORK, "demo-ros.yaml")) as f:
    demo = yaml.safe_load(f)
close(demo["distortion_coefficients"]["data"], [6.3e-05 * 5.23 ** 2 / (-0.065) ** 3, 0, 0, 0, 0],
      "device (seidel) -> ros: k1 = sigma a^2 / M_T^3", rel=1e-12)
close(demo["camera_matrix"]["data"][0], 5.23 / 1.12e-3, "device (seidel) -> ros: fx = a / pitch", rel=1e-12)
r = topocal("export", "--to", "ros", "--out", "neither.yaml", expect=2)
check("--calibration" in r.stderr and "--device" in r.stderr, f"export without a source says what it needs: {r.stderr}")
check(not os.path.exists(os.path.join(WORK, "neither.yaml")), "refused export leaves no file")

if failures:
    print(f"{len(failures)} check(s) failed", file=sys.stderr)
    sys.exit(1)
shutil.rmtree(WORK, ignore_errors=True)
print("all exchange checks passed")
