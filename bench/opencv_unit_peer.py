#!/usr/bin/env python3
"""The peer of `unit calibrate` in bench/process_timings.sh: OpenCV's calibration of the same target view, as an
OpenCV user would write it. Reads the demo unit's 4000 x 3000 view of the 13 x 13-corner board (0.9 mm squares),
finds and refines its corners (cv2.findChessboardCorners with CALIB_CB_FAST_CHECK off, cv2.cornerSubPix) and fits a
single view with the intrinsics held as topocal's single-view fit holds them (focal length from the nominal 5.2 mm and
1.12 um pixels, principal point at the centre, square pixels, no tangential distortion, k1 only). Prints the RMS
reprojection error and k1; exits 1 when the board is not found.
Usage: /usr/bin/python3 bench/opencv_unit_peer.py TARGET.png"""
import sys

import cv2
import numpy as np


def main():
    image = cv2.imread(sys.argv[1], cv2.IMREAD_GRAYSCALE)
    if image is None:
        sys.exit(f"{sys.argv[1]}: cannot be read")
    if image.dtype != np.uint8:
        image = cv2.convertScaleAbs(image, alpha=255.0 / 65535.0)
    pattern = (13, 13)
    found, corners = cv2.findChessboardCorners(image, pattern, cv2.CALIB_CB_ADAPTIVE_THRESH)
    if not found:
        sys.exit(f"{sys.argv[1]}: no 13 x 13 board found")
    corners = cv2.cornerSubPix(image, corners, (11, 11), (-1, -1),
                               (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 1e-3))
    board = np.zeros((13 * 13, 3), np.float32)
    board[:, :2] = np.mgrid[0:13, 0:13].T.reshape(-1, 2) * 0.9
    h, w = image.shape
    focal_px = 5.2e-3 / 1.12e-6
    k = np.array([[focal_px, 0, (w - 1) / 2], [0, focal_px, (h - 1) / 2], [0, 0, 1]])
    flags = (cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_FIX_FOCAL_LENGTH | cv2.CALIB_FIX_PRINCIPAL_POINT |
             cv2.CALIB_FIX_ASPECT_RATIO | cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3)
    rms, k, dist, _, _ = cv2.calibrateCamera([board], [corners], (w, h), k, None, flags=flags)
    print(f"rms {rms:.4f} px, k1 {dist[0][0]:.5g}")


if __name__ == "__main__":
    main()
