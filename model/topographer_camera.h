#pragma once
// The topographer's camera: how millimetres on the detection plane (the paper's frame) map to sensor pixels.
// Shared by calibration, rendering and reconstruction. Conventions drawn and argued in docs/camera-conventions.md.
//
//   detection plane (paper frame, mm)              pixel (OpenCV, px)
//   x1 = -a X / (b + Z), y1 = -a Y / (b + Z)       u right, v down, centre of the top-left pixel = (0, 0)
//   (the physical image is inverted: M_T < 0)
//
//   default (rotated_180 = false):  u = c_u + x1 / pitch,  v = c_v + y1 / pitch
//   rotated_180 = true:             u = c_u - x1 / pitch,  v = c_v - y1 / pitch
//
// With the default the pixel image is the eye as seen from the camera, upright (a corneal point at +Y appears above
// the centre), and the OpenCV camera frame is the paper's frame turned by 180 deg about z — so OpenCV's normalised
// coordinates are exactly x1 / a and a calibration's camera matrix and distortion coefficients apply to the
// detection-plane millimetres with no sign change (fx = a / pitch).
#include <optional>
#include <string>

#include <Eigen/Core>

namespace topocal::model {

struct TopographerCamera {
  double pixel_pitch_um = 1.12;
  int width_px = 4000;
  int height_px = 3000;
  Eigen::Vector2d principal_point_px{1999.5, 1499.5};  // where the optical axis meets the sensor
  double a_mm = 5.2;          // pinhole to detection plane (config topographer.a_mm)
  bool rotated_180 = false;   // camera rolled by 180 deg about its axis (the pixel image shows the eye upside down)

  double PitchMm() const noexcept { return pixel_pitch_um * 1e-3; }
  // +1 for the default orientation, -1 when rotated by 180 deg.
  double Sign() const noexcept { return rotated_180 ? -1.0 : 1.0; }
  // Focal length in pixels, a / pitch: the fx = fy of the equivalent OpenCV camera matrix.
  double FocalPx() const noexcept { return a_mm / PitchMm(); }

  Eigen::Vector2d PixelFromDetectionPlane(const Eigen::Vector2d& point_mm) const noexcept {
    return principal_point_px + (Sign() / PitchMm()) * point_mm;
  }
  Eigen::Vector2d DetectionPlaneFromPixel(const Eigen::Vector2d& point_px) const noexcept {
    return (Sign() * PitchMm()) * (point_px - principal_point_px);
  }
  // True if the pixel centre lies on the sensor (OpenCV convention: [-0.5, width - 0.5) x [-0.5, height - 0.5)).
  bool OnSensor(const Eigen::Vector2d& point_px) const noexcept {
    return point_px.x() >= -0.5 && point_px.y() >= -0.5 && point_px.x() < width_px - 0.5 &&
           point_px.y() < height_px - 0.5;
  }
  // Empty when valid; otherwise why not (key: problem).
  std::optional<std::string> Invalid() const;
};

// Strict loading of the camera file (JSON, docs/camera-conventions.md): unknown, missing or mistyped keys and
// non-physical values throw InputError "FILE: key: problem".
TopographerCamera LoadTopographerCamera(const std::string& path);
TopographerCamera ParseTopographerCamera(const std::string& json_text, const std::string& origin);
std::string TopographerCameraToJson(const TopographerCamera& camera);

}  // namespace topocal::model
