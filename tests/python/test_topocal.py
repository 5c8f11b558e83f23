"""The Python package against the CLI and OpenCV (ctest Python.*; run by python3 -m pytest with PYTHONPATH=<build>/python).

Environment: TOPOCAL_CLI (the topocal executable), TOPOCAL_DATA (the bundled data directory). The images are rendered
by the CLI itself, so that the same file goes through `topocal <verb>` and through the module: the numbers must agree
bit for bit (the same library calls; the JSON documents decoded by Python's json module).
"""
import json
import os
import subprocess
import sys
import threading
import time

import cv2
import numpy as np
import pytest

import topocal

CLI = os.environ["TOPOCAL_CLI"]
DATA = os.environ["TOPOCAL_DATA"]
PAPER = os.path.join(DATA, "paper.json")
DEMO_DEVICE = os.path.join(DATA, "demo-unit-device.json")
NOMINAL_DEVICE = os.path.join(DATA, "device.json")


def run(*args, expect=0):
    r = subprocess.run([CLI, "--quiet", *args], capture_output=True, text=True)
    assert r.returncode == expect, f"topocal {' '.join(args)}: {r.returncode}\n{r.stdout}\n{r.stderr}"
    return r


def read_image(path):
    return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)


@pytest.fixture(scope="session")
def work(tmp_path_factory):
    return tmp_path_factory.mktemp("topocal")


@pytest.fixture(scope="session")
def eye(work):
    """The paper cornea through the demo unit, rendered by the CLI."""
    path = work / "eye.png"
    run("render-spots", "--config", PAPER, "--device", DEMO_DEVICE, "--out", str(path))
    return path


@pytest.fixture(scope="session")
def balls(work):
    """Three reference balls through the demo unit (the README's placements), then `device calibrate` on them."""
    placements = [(6.5, 0.12, -0.20, 0.00), (7.8, -0.25, 0.10, -0.15), (9.0, 0.20, 0.22, 0.10)]
    paths = []
    for r, x, y, z in placements:
        p = work / f"ball-{r}.png"
        run("render-spots", "--config", PAPER, "--device", DEMO_DEVICE, "--sphere-radius-mm", str(r), "--ball-at",
            str(x), str(y), str(z), "--out", str(p))
        paths.append(p)
    device = work / "unit-device.json"
    run("device", "calibrate", "--config", PAPER, "--device", NOMINAL_DEVICE, "--balls", *map(str, paths),
        "--radii-mm", *(str(p[0]) for p in placements), "--out", str(device))
    return paths, [p[0] for p in placements], device


def test_version_is_the_cli_version():
    out = run("--version").stdout
    assert out.strip() == f"topocal {topocal.__version__} (commit {topocal.__commit__})"


def test_errors_are_python_errors_naming_the_input(tmp_path):
    with pytest.raises(topocal.InputError, match="missing.json"):
        topocal.Device.load(str(tmp_path / "missing.json"))
    assert issubclass(topocal.InputError, ValueError)
    assert issubclass(topocal.MeasurementRefused, topocal.Error)
    assert issubclass(topocal.Error, RuntimeError)
    bad = tmp_path / "bad.json"
    bad.write_text('{"ideal_image": 1}')
    with pytest.raises(topocal.InputError, match="bad.json"):
        topocal.Config.load(bad)
    device = topocal.Device.load(DEMO_DEVICE)
    with pytest.raises(topocal.InputError, match="uint8 or uint16"):
        topocal.detect(np.zeros((3000, 4000), np.float32), device, PAPER)
    with pytest.raises(topocal.InputError, match="image"):
        topocal.detect(np.zeros((300, 400), np.uint8), device, PAPER)
    with pytest.raises(topocal.InputError, match="points_mm"):
        device.pixel_of(np.zeros((4, 3)))


def max_error_against_opencv(device, points_mm, pitch_mm):
    """|pixel_of - cv2.projectPoints| over the points: the undistorted pixel (identity orientation, a pitch per axis)
    as a normalised ray through the device's OpenCV view."""
    K, dist = device.opencv_view()
    undistorted_px = np.asarray(device.principal_point_px) + points_mm / pitch_mm
    rays = np.column_stack([(undistorted_px[:, 0] - K[0, 2]) / K[0, 0], (undistorted_px[:, 1] - K[1, 2]) / K[1, 1],
                            np.ones(len(points_mm))])
    projected, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, dist)
    return np.max(np.abs(projected.reshape(-1, 2) - device.pixel_of(points_mm)))


def test_device_round_trip_and_projection_against_opencv():
    device = topocal.Device.load(DEMO_DEVICE)
    assert (device.width_px, device.height_px) == (4000, 3000)
    again = topocal.Device.from_json(device.to_json())
    assert again.to_json() == device.to_json()
    rng = np.random.default_rng(7)
    points_mm = rng.uniform(-0.3, 0.3, size=(200, 2))
    px = device.pixel_of(points_mm)
    assert px.shape == (200, 2) and px.dtype == np.float64
    # The inverse: back to the same undistorted points (converged inverse; measured 1.0e-12 mm).
    back = device.undistorted_of(px)
    assert np.max(np.abs(back - points_mm)) < 1e-9
    # The OpenCV view maps the same rays to the same pixels: undistorted pixel -> normalised ray -> projectPoints.
    # Measured 4.5e-13 px; acceptance 1e-6 px (an exact view), regression bound 1e-9 px.
    err = max_error_against_opencv(device, points_mm, device.pixel_pitch_um * 1e-3)
    assert err < 1e-6
    assert err < 1e-9


def test_a_rational_lens_device_is_opencvs_rational_model():
    """A device whose lens is OpenCV's rational model (model/lens_rational.h): its OpenCV view carries all eight
    coefficients and maps the same rays to the same pixels as cv2.projectPoints."""
    spec = json.loads(topocal.Device.load(DEMO_DEVICE).to_json())
    k = [-0.02, 0.004, 1e-4, -2e-4, -1e-3, 0.01, 0.002, -5e-4]
    spec["distortion"] = {"model": "rational8", "k": k, "centre_mm": [0.01, -0.02]}
    spec.pop("calibration", None)
    device = topocal.Device.from_json(json.dumps(spec))
    assert topocal.Device.from_json(device.to_json()).to_json() == device.to_json()
    _, dist = device.opencv_view()
    assert np.ravel(dist).shape == (8,)
    assert np.allclose(np.ravel(dist)[[0, 1, 4, 5, 6, 7]], np.array(k)[[0, 1, 4, 5, 6, 7]], rtol=0, atol=1e-15)
    rng = np.random.default_rng(8)
    points_mm = rng.uniform(-0.3, 0.3, size=(200, 2))
    # Acceptance 1e-6 px (an exact view); regression bound 1e-9 px (the Brown device's: measured 4.5e-13 px).
    err = max_error_against_opencv(device, points_mm, device.pixel_pitch_um * 1e-3)
    assert err < 1e-6
    assert err < 1e-9


def test_a_device_with_non_square_pixels_is_opencvs_fx_over_fy():
    spec = json.loads(topocal.Device.load(DEMO_DEVICE).to_json())
    spec["camera"]["pixel_aspect"] = 1.0003
    device = topocal.Device.from_json(json.dumps(spec))
    assert device.pixel_aspect == 1.0003
    assert topocal.Device.from_json(device.to_json()).to_json() == device.to_json()
    K, _ = device.opencv_view()
    assert abs(K[0, 0] / K[1, 1] - 1.0003) < 1e-12
    # The same rays to the same pixels with a pitch per axis. Acceptance 1e-6 px (an exact view); regression bound
    # 1e-9 px, as for square pixels (4.5e-13 px there).
    points_mm = np.random.default_rng(8).uniform(-0.3, 0.3, size=(200, 2))
    err = max_error_against_opencv(device, points_mm, device.pixel_pitch_um * 1e-3 * np.array([1.0, 1.0003]))
    assert err < 1e-6
    assert err < 1e-9


def test_detect_gives_the_cli_rows_and_summary(work, eye):
    csv, summary = work / "eye.csv", work / "eye-detect.json"
    run("detect", "--image", str(eye), "--device", DEMO_DEVICE, "--config", PAPER, "--out", str(csv), "--json",
        str(summary))
    spots, info = topocal.detect(read_image(eye), topocal.Device.load(DEMO_DEVICE), topocal.Config.load(PAPER),
                                 return_summary=True)
    assert spots.dtype == topocal.SPOT_DTYPE
    assert set(spots.dtype.names) == {"ring", "index", "x_mm", "y_mm", "u_px", "v_px", "flags"}
    # The CLI's rows, formatted as the CLI formats them, from the module's numbers: the same text.
    lines = csv.read_text().splitlines()
    assert len(lines) - 1 == len(spots) > 500
    names = {bit: name for name, bit in topocal.SPOT_FLAGS.items()}
    for line, s in zip(lines[1:], spots):
        flags = "|".join(names[b] for b in sorted(names) if s["flags"] & b)
        mine = (f"{s['ring']},{s['index']},{s['x_mm']:.10f},{s['y_mm']:.10f},{s['u_px']:.6f},{s['v_px']:.6f},"
                f"{flags}")
        assert mine == line
    cli = json.loads(summary.read_text())
    cli.pop("image")
    assert info == cli


def test_reconstruct_gives_the_cli_numbers_and_maps(work, eye):
    out, maps = work / "eye.json", work / "eye-maps"
    run("reconstruct", "--config", PAPER, "--image", str(eye), "--device", DEMO_DEVICE, "--truth", "--eye", "OD",
        "--json", str(out), "--maps", str(maps))
    m = topocal.reconstruct(PAPER, device=DEMO_DEVICE, image=read_image(eye), truth=True, eye="OD")
    cli = json.loads(out.read_text())
    cli["image"].pop("device")
    assert m.result == cli  # bit for bit: every double the same
    assert m.result["valid"] is True
    # The paper cornea comes back (acceptance: the capture issue's clean-image limits |dr| 0.005 mm, |dk| 0.005).
    fit = m.surface_fit
    assert abs(fit["rx_mm"] - 8.35) < 0.005 and abs(fit["kx"] + 0.43) < 0.005
    axial = m.maps["axial_power"]
    assert axial.values.shape == (len(axial.y_mm), len(axial.x_mm)) == (241, 241)
    assert axial.unit == "D"
    grid = np.genfromtxt(maps / "axial_power.csv", delimiter=",", skip_header=1)
    values = grid[:, 2].reshape(241, 241)
    both = np.isfinite(values)
    assert np.array_equal(both, np.isfinite(axial.values))
    assert np.array_equal(values[both], axial.values[both])
    assert np.array_equal(grid[:241, 0], axial.x_mm)
    assert set(m.maps) == {"axial_power", "tangential_power", "elevation"}
    assert m.polar["axial_D"].shape == (len(m.polar["theta_deg"]), len(m.polar["rho_mm"]))
    # Every number with its U, as the CLI reports it (the equality above covers the JSON): the U map beside the
    # axial map, positive wherever the axial map is measured.
    assert m.result["uncertainty"]["coverage_factor"] == 2
    u_map = m.polar["axial_expanded_D"]
    assert u_map.shape == m.polar["axial_D"].shape
    measured = np.isfinite(m.polar["axial_D"])
    assert np.all(u_map[measured] > 0)


def test_the_thread_count_does_not_change_the_spots(eye):
    image = read_image(eye)
    before = topocal.get_num_threads()
    try:
        topocal.set_num_threads(1)
        one = topocal.detect(image, DEMO_DEVICE, PAPER)
        topocal.set_num_threads(4)
        four = topocal.detect(image, DEMO_DEVICE, PAPER)
    finally:
        topocal.set_num_threads(before)
    assert one.tobytes() == four.tobytes()


def test_reconstruct_from_spots_of_detect(work, eye):
    spots = topocal.detect(read_image(eye), DEMO_DEVICE, PAPER)
    m = topocal.reconstruct(PAPER, spots=spots)
    left_out = 0
    for name in ("near_blob", "truncated", "flux_outlier", "uneven_background", "surface_outlier"):
        left_out |= topocal.SPOT_FLAGS[name]
    usable = (spots["ring"] > 0) & ((spots["flags"] & left_out) == 0)
    assert m.result["spots_read"] == int(np.count_nonzero(usable))
    assert "surface_fit" in m.result


def test_a_refused_capture_raises_with_its_reasons(work):
    lid = work / "lid70.png"
    run("render-spots", "--config", PAPER, "--device", DEMO_DEVICE, "--upper-lid", "0.7", "--out", str(lid))
    image = read_image(lid)
    with pytest.raises(topocal.MeasurementRefused) as e:
        topocal.reconstruct(PAPER, device=DEMO_DEVICE, image=image)
    assert e.value.reasons and e.value.result["valid"] is False
    assert "clinical" not in e.value.result
    with pytest.raises(topocal.MeasurementRefused, match="spot identification"):
        topocal.detect(image, DEMO_DEVICE, PAPER)


def test_calibrate_device_gives_the_cli_device(balls):
    paths, radii, cli_device = balls
    device = topocal.calibrate_device(PAPER, NOMINAL_DEVICE, [read_image(p) for p in paths], radii)
    cli = json.loads(cli_device.read_text())
    mine = device.to_dict()
    for key in ("camera", "distortion", "screen_pose"):
        assert mine[key] == cli[key], key
    assert mine["calibration"]["parameters"] == cli["calibration"]["parameters"]
    with pytest.raises(topocal.InputError, match="reference-ball radius"):
        topocal.calibrate_device(PAPER, NOMINAL_DEVICE, [read_image(p) for p in paths], [6.5, 7.8, 90.0])


def test_calibrate_from_corners_agrees_with_opencv(tmp_path):
    board = tmp_path / "board.yaml"
    board.write_text("target_type: checkerboard\ntargetCols: 9\ntargetRows: 6\nrowSpacingMeters: 0.02\n"
                     "colSpacingMeters: 0.02\n")
    K = np.array([[800.0, 0, 322.0], [0, 801.0, 238.0], [0, 0, 1]])
    dist = np.array([-0.21, 0.08, 0.001, -0.0007, 0.0])
    grid = np.array([(c * 20.0, r * 20.0, 0.0) for r in range(6) for c in range(9)])
    rng = np.random.default_rng(3)
    views, object_points, image_points = [], [], []
    for _ in range(8):
        rvec = rng.uniform(-0.35, 0.35, 3)
        tvec = np.array([-80.0, -50.0, 420.0]) + rng.uniform(-30, 30, 3)
        px, _ = cv2.projectPoints(grid, rvec, tvec, K, dist)
        px = px.reshape(-1, 2) + rng.normal(0, 0.05, size=(len(grid), 2))
        views.append((grid, px))
        object_points.append(grid.astype(np.float32))
        image_points.append(px.astype(np.float32))
    cal = topocal.calibrate(board, corners=views, image_size=(640, 480))
    _, K_cv, dist_cv, _, _ = cv2.calibrateCamera(object_points, image_points, (640, 480), None, None)
    # The same least-squares problem: topocal and OpenCV agree (measured 2026-12-03: fx differs by 1.2e-7 relative;
    # acceptance 1e-3, regression bound 1e-5), and both find the truth within the noise (fx 798.87 for 800).
    assert abs(cal.camera_matrix[0, 0] / K_cv[0, 0] - 1) < 1e-3
    assert abs(cal.camera_matrix[0, 0] / K_cv[0, 0] - 1) < 1e-5
    assert abs(cal.camera_matrix[0, 0] - 800.0) < 2.0
    assert np.allclose(cal.dist_coeffs[:2], dist_cv.ravel()[:2], atol=1e-3)
    path = tmp_path / "cal.yaml"
    cal.save(path)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert np.allclose(fs.getNode("camera_matrix").mat(), cal.camera_matrix)
    with pytest.raises(topocal.Error, match="calibration failed"):
        topocal.calibrate(board, corners=views[:1], image_size=(640, 480))
    # Other tools' files, as `topocal export` and `topocal import` write them: the same bytes.
    for to in ("mrcal", "ros", "opencv"):
        out = tmp_path / f"cal.{to}"
        run("export", "--calibration", str(path), "--to", to, "--out", str(out))
        assert topocal.export_calibration(path, to) == out.read_text(), to
        if to != "opencv":
            back = tmp_path / f"back-{to}.yaml"
            run("import", "--from", to, str(out), "--out", str(back))
            assert topocal.import_calibration(out, to) == back.read_text(), to
    with pytest.raises(topocal.InputError, match="not kalibr"):
        topocal.import_calibration(path, "matlab")


def test_long_calls_release_the_gil(eye):
    """While one thread measures an eye, another runs Python: with the GIL held it could not."""
    image = read_image(eye)
    calls = []

    def measure():
        for _ in range(2):
            t0 = time.perf_counter()
            topocal.reconstruct(PAPER, device=DEMO_DEVICE, image=image)
            calls.append(time.perf_counter() - t0)

    times = []
    worker = threading.Thread(target=measure)
    start = time.perf_counter()
    worker.start()
    while worker.is_alive():
        times.append(time.perf_counter())
    worker.join()
    gaps = np.diff([start] + times)
    # Held, the main thread would stop for a whole call (a gap as long as the call); released, it waits only for
    # Python's switch interval (5 ms) and the scheduler, even on a loaded machine. Measured 2026-12-03: the largest
    # gap 5-12 ms beside calls of 160-280 ms.
    assert min(calls) > 0.05
    assert gaps.max() < 0.5 * min(calls), (gaps.max(), calls)


@pytest.fixture(scope="session")
def unit_record(work):
    """One unit calibrated by the CLI (the README's unit, full sensor) and ingested into a fleet database."""
    target = os.path.join(DATA, "target-topographer.yaml")
    run("render-target", "--target", target, "--width", "4000", "--height", "3000", "--focal-mm", "5.2",
        "--pixel-pitch-um", "1.12", "--sigma", "6.3e-5", "--distance-mm", "70", "--supersampling", "2", "--noise", "1",
        "--out", str(work / "target.png"))
    run("render-spots", "--config", PAPER, "--device", os.path.join(DATA, "device.json"), "--sigma", "6.3e-5",
        "--sphere-radius-mm", "7.8", "--out", str(work / "sphere.png"))
    record = work / "units" / "SN-0001"
    run("unit", "calibrate", "--serial", "SN-0001", "--target", target, "--images", str(work / "target.png"),
        "--reference-sphere", str(work / "sphere.png"), "--sphere-radius-mm", "7.8", "--out", str(record) + "/")
    run("fleet", "ingest", "--db", str(work / "fleet.sqlite"), "--station", "LINE-1", str(record))
    return record


def test_unit_record_is_read_and_verified(work, unit_record, tmp_path):
    r = topocal.read_unit_record(str(unit_record))
    assert r["serial"] == "SN-0001" and r["unit"]["serial"] == "SN-0001"
    assert len(r["unit_json_sha256"]) == 64 and r["files"]
    # A record whose listed file changed is refused, naming the file.
    import shutil
    copy = tmp_path / "SN-0001"
    shutil.copytree(unit_record, copy)
    name = r["files"][0][0]
    with open(copy / name, "ab") as f:
        f.write(b"\n")
    with pytest.raises(topocal.InputError, match=name.replace(".", r"\.")):
        topocal.read_unit_record(str(copy))


def test_fleet_database_from_python_and_cli_agree(work, unit_record, tmp_path):
    db = topocal.FleetDb(str(tmp_path / "py.sqlite"), create=True)
    assert db.ingest([str(unit_record)], "LINE-1") == (1, 0)
    assert db.ingest([str(unit_record)], "LINE-1") == (0, 1)  # the same digest: not added twice
    cli = topocal.FleetDb(str(work / "fleet.sqlite"))
    (mine,), (theirs,) = db.units(), cli.units()
    assert mine["measurements"] == theirs["measurements"]
    assert mine["unit_json_sha256"] == theirs["unit_json_sha256"]
    table = cli.table("sphere_radius_error_mm")
    assert list(table["serial"]) == ["SN-0001"] and table["value"].dtype == np.float64
    assert table["value"][0] == theirs["measurements"]["sphere_radius_error_mm"][0]
    with pytest.raises(topocal.InputError):
        topocal.FleetDb(str(tmp_path / "none.sqlite"))
    # `fleet check` and `fleet backup` from Python: the copy holds the same units.
    assert db.check() == (1, len(mine["measurements"]))
    db.backup(str(tmp_path / "copy.sqlite"))
    assert topocal.FleetDb(str(tmp_path / "copy.sqlite")).units() == db.units()


def test_the_worked_example_of_the_docs_runs(work, unit_record, tmp_path):
    """docs/python.md's Python blocks, as written, in order, from a directory holding data/ (topocal on PATH)."""
    import re
    docs = os.path.join(os.path.dirname(DATA), "docs", "python.md")
    blocks = re.findall(r"```python\n(.*?)```", open(docs).read(), re.S)
    assert len(blocks) >= 2
    os.symlink(DATA, tmp_path / "data")
    os.symlink(work / "fleet.sqlite", tmp_path / "fleet.sqlite")
    env = dict(os.environ, PATH=os.path.dirname(os.path.abspath(CLI)) + os.pathsep + os.environ["PATH"],
               PYTHONPATH=os.path.dirname(os.path.dirname(topocal.__file__)), MPLBACKEND="Agg")
    r = subprocess.run([sys.executable, "-c", "\n".join(blocks)], cwd=tmp_path, env=env, capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr
    assert "rx = 8.3" in r.stdout and (tmp_path / "axial.png").stat().st_size > 10000
    assert (tmp_path / "unit-device.json").exists()
