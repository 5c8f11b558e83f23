#pragma once
// OpenCV's cv::undistort knows no radial distortion centre. A topocal camera whose radial distortion is centred
// at e != 0 (Seidel with a fitted centre) is written to the OpenCV fields of the calibration file as the Brown
// model (fx, fy, cx, cy, k1, k2, p1, p2, k3, centre 0) closest to it in pixels over the image.
//
// To second order in e the two are the same model: d = e + (u - e)(1 + k1 |u - e|^2) expands to OpenCV's radial
// k1 term plus tangential p1 = -k1 e_y, p2 = -k1 e_x, plus a constant and a linear term that fx, fy, cx, cy absorb
// except for a skew 2 k1 e_x e_y that OpenCV's camera matrix cannot hold in cv::undistort. That is where the
// start comes from; the least-squares fit (Ceres) over a grid of pixels then settles the rest, and the largest
// remaining pixel difference is reported so nobody has to trust the approximation blindly.
#include <optional>

#include "model/camera_model.h"

namespace topocal::calib {

struct OpenCvEquivalent {
  model::CameraModel camera;    // distortion_centre == 0
  double max_error_px = 0;      // over the grid of pixels, |projection(topocal) - projection(OpenCV)|
};

// Exact copy when the centre is zero. Pixels whose ray does not exist (beyond the fold of strong barrel distortion)
// are left out of the fit; nullopt if that is more than half of the image or the fit fails.
std::optional<OpenCvEquivalent> ToOpenCvModel(const model::CameraModel& camera);

}  // namespace topocal::calib
