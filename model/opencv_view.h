#pragma once
// OpenCV's view of the topographer's camera, the one place the two meet: an OpenCV calibration (camera matrix K and
// distCoeffs of any lens model, in this camera's pixels) as a model::LensParams on the detection plane, so that
// points and images of the topographer can be undistorted in millimetres; and back, a device as the K + distCoeffs
// that OpenCV, ROS, Kalibr and mrcal files hold (calib/camera_exchange.h writes them).
//
// With x_mm = M^T P (u - c_cam) (model/topographer_camera.h; M the image orientation, P = diag(pitch_u, pitch_v))
// and OpenCV's x_n = (u - c_x) / f_x, y_n = (v - c_y) / f_y, the distortion acting on v = x_n - e (e the distortion
// centre, normalised):
//   M^T v = (x_mm - centre_mm) / focal_mm,  focal_mm = f_x pitch_u = f_y pitch_v,  centre_mm = M^T P (c - c_cam + F e)
// with F = diag(f_x, f_y).
// The radial terms are unchanged by M; the tangential ones, r^2 q + 2 (n.q) n with q = (p2, p1), turn with it:
// q_mm = M^T q (for a 180 deg rotation p1, p2 change sign).
// The two focal lengths in mm agree when the camera's pixel_aspect is the calibration's f_x / f_y (what
// a calibration on the detection plane gives it). For any other camera LensParams' one focal length is
// sqrt(f_x pitch_u f_y pitch_v), and the error this makes, |f_x pitch_u / (f_y pitch_v) - 1| / 2 times the distortion
// displacement, is reported as `aspect_error` so callers can refuse it.
#include <optional>
#include <string>

#include "model/camera_model.h"
#include "model/distortion.h"
#include "model/topographer_camera.h"

namespace topocal::model {

struct LensOnDetectionPlane {
  bool ok = false;
  std::string message;  // why not, when !ok
  LensParams lens;
  double aspect_error = 0;  // |f_x pitch_u / (f_y pitch_v) - 1|
};

// !ok with the reason in `message` for a non-positive focal length or a value that
// is not finite (the camera file's content: the caller names the file and turns it into bad input).
LensOnDetectionPlane LensFromOpenCv(const CameraModel& cv_camera, const TopographerCamera& camera);

// The inverse view: a lens distortion on the detection plane as the OpenCV camera (K with fx / fy the camera's pixel
// aspect, the lens model's distCoeffs, no distortion centre) that maps the same undistorted rays to the same pixels.
// Exact.
CameraModel OpenCvFromLens(const LensParams& brown, const TopographerCamera& camera);

struct Device;
// A device's camera and distortion as OpenCV's camera (OpenCvFromLens; a Seidel distortion is its Brown equivalent,
// k1 alone, model::SeidelToBrown at the camera's a). Exact: cv::projectPoints of a ray through the result gives the
// pixel Device::PixelOf gives its undistorted detection-plane point (tests/model/opencv_view_test.cc).
CameraModel OpenCvView(const Device& device);

}  // namespace topocal::model
