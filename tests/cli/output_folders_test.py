#!/usr/bin/env python3
"""No verb that writes a folder leaves one behind when it fails (a failed `unit calibrate --out
units/SN/` left an empty folder that made every rerun fail). Each verb fails here after its output folder could
have been made; the folder is given with a trailing slash and relative to the working directory, two levels deep,
so that neither `new/` nor `new/out/` may remain. A rerun after the failure must not be refused because of it.

usage: output_folders_test.py TOPOCAL_EXE SOURCE_DIR WORK_DIR
"""
import os
import shutil
import subprocess
import sys

import cv2
import numpy as np

TOPOCAL, SOURCE, WORK = os.path.abspath(sys.argv[1]), sys.argv[2], sys.argv[3]
failures = []


def check(condition, what):
    if not condition:
        failures.append(what)
        print("FAIL:", what, file=sys.stderr)


def fails_without_folder(args, expect):
    shutil.rmtree(os.path.join(WORK, "new"), ignore_errors=True)
    r = subprocess.run([TOPOCAL, *args], cwd=WORK, capture_output=True, text=True)
    name = " ".join(args[:2])
    check(r.returncode == expect, f"{name}: exit {r.returncode}, expected {expect}: {r.stdout}{r.stderr}")
    check(not os.path.exists(os.path.join(WORK, "new")), f"{name}: left a folder behind")
    return r


shutil.rmtree(WORK, ignore_errors=True)
os.makedirs(WORK)
data = os.path.join(SOURCE, "data")
with open(os.path.join(WORK, "bad.json"), "w") as f:
    f.write("{ not json")
with open(os.path.join(WORK, "h.json"), "w") as f:
    f.write('{"design": "%s/paper.json", "distortion": {"seidel_sigma_per_mm2": [1e-5]}, "noise_px": [0.01], '
            '"calibration_errors": [0], "limits": {"dk": 0.05, "dP_D": -1}}' % data)  # non-physical limit
# A blank sensor-sized image: nothing to detect, so the calibration fails after its work has begun.
cv2.imwrite(os.path.join(WORK, "blank.png"), np.full((3000, 4000), 128, np.uint8))

fails_without_folder(["harness", "--config", "h.json", "--out", "new/out/"], 2)
fails_without_folder(["harness", "--config", "bad.json", "--out", "new/out/"], 2)
fails_without_folder(["harness", "merge", "--out", "new/out/", "missing-shards/"], 2)
fails_without_folder(["sweep", "--config", "bad.json", "--maps", "new/out/"], 2)
fails_without_folder(["reconstruct", "--config", f"{data}/paper.json", "--spots", "missing.csv", "--maps",
                      "new/out/"], 2)
for _ in range(2):  # the rerun meets the same error, not "exists and is not a unit record"
    r = fails_without_folder(["unit", "calibrate", "--serial", "SN-0001", "--target",
                              f"{data}/target-topographer.yaml", "--images", "blank.png", "--out", "new/SN-0001/"], 1)
    check("not a unit record" not in r.stderr, f"unit calibrate rerun refused: {r.stderr}")
os.makedirs(os.path.join(WORK, "inputs", "SN-0002"))
with open(os.path.join(WORK, "inputs", "SN-0002", "unit-inputs.json"), "w") as f:
    f.write("{ not json")
fails_without_folder(["unit", "calibrate-batch", "inputs/", "--out", "new/out/", "--quiet"], 2)  # a unit with bad input only: exit 2

if failures:
    print(f"{len(failures)} check(s) failed", file=sys.stderr)
    sys.exit(1)
shutil.rmtree(WORK, ignore_errors=True)
print("no folder left by any failing verb")
