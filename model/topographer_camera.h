#pragma once
// The topographer's camera: how millimetres on the detection plane (the paper's frame) map to sensor pixels.
// Shared by calibration, rendering and reconstruction. Conventions drawn and argued in docs/camera-conventions.md.
//
//   detection plane (paper frame, mm)              pixel (OpenCV, px)
//   x1 = -a X / (b + Z), y1 = -a Y / (b + Z)       u right, v down, centre of the top-left pixel = (0, 0)
//   (the physical image is inverted: M_T < 0)
//
//   (u, v) = c + P^-1 M (x1, y1),   (x1, y1) = M^T P ((u, v) - c),   P = diag(pitch_u, pitch_v)
//   M, the image orientation, one of the eight axis-aligned orthogonal matrices (ImageOrientation below);
//   identity by default, -I for a camera rolled by 180 deg (the old `rotated_180: true`).
//   pitch_v = pixel_aspect pitch_u: a sensor whose pixels are not square (or a lens whose squeeze makes them look
//   so) is OpenCV's fx != fy, fx / fy = pixel_aspect, held exactly rather than refused.
//
// With the default the pixel image is the eye as seen from the camera, upright (a corneal point at +Y appears above
// the centre), and the OpenCV camera frame is the paper's frame turned by 180 deg about z — so OpenCV's normalised
// coordinates are exactly x1 / a and a calibration's camera matrix and distortion coefficients apply to the
// detection-plane millimetres with no sign change (fx = a / pitch_u, fy = a / pitch_v).
#include <optional>
#include <string>

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>

#include "model/paper_topographer.h"

namespace topocal::model {

// How the delivered image is turned or mirrored relative to the default mapping (u = c_u + x1/pitch_u,
// v = c_v + y1/pitch_v). Each is the matrix M of (u - c_u, v - c_v) = P^-1 M (x1, y1):
//   identity    [ 1  0;  0  1]      rotate_180  [-1  0;  0 -1]
//   rotate_90   [ 0 -1;  1  0]      rotate_270  [ 0  1; -1  0]      (90: a point right of the centre moves down)
//   flip_u      [-1  0;  0  1]      flip_v      [ 1  0;  0 -1]      (mirrored left-right / top-bottom)
//   transpose   [ 0  1;  1  0]      transverse  [ 0 -1; -1  0]
// A mirror (det M = -1) mirrors the eye if it is not declared: the null-screen pattern is mirror-symmetric, so the
// spots alone cannot tell (docs/device.md).
enum class ImageOrientation { kIdentity, kRotate90, kRotate180, kRotate270, kFlipU, kFlipV, kTranspose, kTransverse };

Eigen::Matrix2d OrientationMatrix(ImageOrientation o) noexcept;
const char* OrientationName(ImageOrientation o) noexcept;
std::optional<ImageOrientation> OrientationFromName(const std::string& name) noexcept;

struct TopographerCamera {
  double pixel_pitch_um = kPaperPixelPitchUm;  // along u (image columns)
  double pixel_aspect = 1.0;     // pitch along v / pitch along u = OpenCV's fx / fy
  int width_px = 4000;
  int height_px = 3000;
  Eigen::Vector2d principal_point_px{1999.5, 1499.5};  // where the optical axis meets the sensor
  double a_mm = kPaperAMm;    // pinhole to detection plane (config topographer.a_mm)
  ImageOrientation orientation = ImageOrientation::kIdentity;

  double PitchMm() const noexcept { return pixel_pitch_um * 1e-3; }  // along u
  // (pitch_u, pitch_v) in mm: the pixel's width and height.
  Eigen::Vector2d PitchesMm() const noexcept { return {PitchMm(), PitchMm() * pixel_aspect}; }
  // M of the orientation (see ImageOrientation).
  Eigen::Matrix2d Orientation() const noexcept { return OrientationMatrix(orientation); }
  // Focal length in pixels along u, a / pitch_u: the fx of the equivalent OpenCV camera matrix (fy = fx / aspect).
  double FocalPx() const noexcept { return a_mm / PitchMm(); }

  // The camera's one pixel mapping, for any T (double, or a Ceres jet when the principal point is fitted), with the
  // principal point given: (u, v) = c + P^-1 M x.
  template <typename T>
  void PixelFromDetectionPlane(const T* principal_px, const T* point_mm, T* pixel) const noexcept {
    const Eigen::Matrix2d m = Orientation();
    pixel[0] = principal_px[0] + (m(0, 0) * point_mm[0] + m(0, 1) * point_mm[1]) / PitchMm();
    pixel[1] = principal_px[1] + (m(1, 0) * point_mm[0] + m(1, 1) * point_mm[1]) / (PitchMm() * pixel_aspect);
  }
  Eigen::Vector2d PixelFromDetectionPlane(const Eigen::Vector2d& point_mm) const noexcept {
    Eigen::Vector2d pixel;
    PixelFromDetectionPlane(principal_point_px.data(), point_mm.data(), pixel.data());
    return pixel;
  }
  Eigen::Vector2d DetectionPlaneFromPixel(const Eigen::Vector2d& point_px) const noexcept {
    return Orientation().transpose() * (point_px - principal_point_px).cwiseProduct(PitchesMm());
  }
  // True if the pixel centre lies on the sensor (OpenCV convention: [-0.5, width - 0.5) x [-0.5, height - 0.5)).
  bool OnSensor(const Eigen::Vector2d& point_px) const noexcept {
    return point_px.x() >= -0.5 && point_px.y() >= -0.5 && point_px.x() < width_px - 0.5 &&
           point_px.y() < height_px - 0.5;
  }
  // Empty when valid; otherwise why not (key: problem).
  std::optional<std::string> Invalid() const;
};

// Strict parsing of a camera object (a device file's "camera" section, docs/camera-conventions.md): unknown, missing
// or mistyped keys and non-physical values throw InputError "ORIGIN: key: problem". A whole device file
// (model/device.h) is accepted too: its camera section is returned.
TopographerCamera ParseTopographerCamera(const std::string& json_text, const std::string& origin);
std::string TopographerCameraToJson(const TopographerCamera& camera);
// The camera object itself (a device file's "camera" section); key_prefix names it in errors.
TopographerCamera CameraFromJson(const nlohmann::json& j, const std::string& origin, const std::string& key_prefix);
nlohmann::json CameraToJson(const TopographerCamera& camera);

}  // namespace topocal::model
