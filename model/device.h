#pragma once
// The topographer as built: its camera (pixel pitch, sensor size, image orientation, principal point, pinhole to
// detection plane a), its lens distortion on the detection plane (Seidel, paper Eq. 18, or Brown), and the rigid pose
// of the null screen (the cone) relative to the camera. The nominal device — every offset zero, no distortion — is
// the paper's perfect instrument; everything that images, measures or calibrates takes a Device.
// Frames, pivot, rotation order and signs are drawn in docs/device.md.
//
//   paper frame (mm): pinhole h = (0, 0, -b), detection plane z = -a-b, cornea vertex near the origin, +z to the eye.
//
//   screen pose: a designed target P (model::DesignNullScreen, on the nominal cone) sits on the as-built screen at
//       P' = q + R (S (P - q)) + t,     q = (0, 0, -b)  the pivot: the mount, on the axis at the pinhole plane
//       S = diag(s, s, 1)               s = radial_scale: a cone-angle / print-scale error (1 = nominal)
//       R = Rz(rz) Ry(ry) Rx(rx)        rotations about the paper's axes through q, rx first (right-handed, degrees)
//       t = (tx, ty, tz)                translation in mm (tz > 0: the cone sits further towards the eye)
//
//   spot of a corneal point P2 (Eq. 14-16):  x1 = -a (P2 - h)_xy / (P2 - h)_z  on the detection plane (undistorted),
//       then the distortion (Eq. 18 or Brown) and the camera's pixel mapping (model/topographer_camera.h).
//
// The design's a (configuration topographer.a_mm) defines the ideal image and so the screen; the device's a
// (camera.a_mm) is the as-built distance that images it. They differ on a real unit.
#include <array>
#include <cmath>
#include <optional>
#include <type_traits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "model/config.h"
#include "model/distortion.h"
#include "model/null_screen.h"
#include "model/topographer_camera.h"
#include "util/io.h"
#include "model/paper_topographer.h"

namespace topocal::model {

struct ScreenPose {
  static constexpr int kNumParams = 6;
  enum Index : int { kRx = 0, kRy = 1, kRz = 2, kTx = 3, kTy = 4, kTz = 5 };  // degrees, degrees, degrees, mm x3

  double rx_deg = 0, ry_deg = 0, rz_deg = 0;
  double tx_mm = 0, ty_mm = 0, tz_mm = 0;
  double radial_scale = 1.0;

  std::array<double, kNumParams> AsArray() const { return {rx_deg, ry_deg, rz_deg, tx_mm, ty_mm, tz_mm}; }
  static ScreenPose FromArray(const double* p, double radial_scale);
  bool IsNominal() const noexcept;

  // P' = q + R (S (P - q)) + t for a designed point P (double or Ceres jet parameters).
  template <typename T>
  static void Apply(const T* pose, const T& radial_scale, double pivot_z_mm, const double* designed_mm,
                    T* placed_mm) noexcept {
    using std::cos;
    using std::sin;
    const double kDeg = M_PI / 180.0;
    const T cx = cos(pose[kRx] * kDeg), sx = sin(pose[kRx] * kDeg);
    const T cy = cos(pose[kRy] * kDeg), sy = sin(pose[kRy] * kDeg);
    const T cz = cos(pose[kRz] * kDeg), sz = sin(pose[kRz] * kDeg);
    const T p[3] = {radial_scale * designed_mm[0], radial_scale * designed_mm[1], T(designed_mm[2] - pivot_z_mm)};
    // Rx, then Ry, then Rz.
    const T x1 = p[0], y1 = cx * p[1] - sx * p[2], z1 = sx * p[1] + cx * p[2];
    const T x2 = cy * x1 + sy * z1, y2 = y1, z2 = -sy * x1 + cy * z1;
    const T x3 = cz * x2 - sz * y2, y3 = sz * x2 + cz * y2, z3 = z2;
    placed_mm[0] = x3 + pose[kTx];
    placed_mm[1] = y3 + pose[kTy];
    placed_mm[2] = z3 + pivot_z_mm + pose[kTz];
  }
  Eigen::Vector3d Apply(const Eigen::Vector3d& designed_mm, double pivot_z_mm) const noexcept;
};

struct Device {
  TopographerCamera camera;
  Distortion distortion = SeidelParams{};  // on the detection plane; sigma = 0 is no distortion
  ScreenPose screen;

  // The design's geometry with the as-built a (camera.a_mm): what reconstruction traces rays with.
  TopographerParams AsBuilt(const TopographerParams& design) const;
  // The designed targets where this device's screen puts them (on_cone_mm moved; ideal and on_sphere kept).
  std::vector<TargetPoint> PlaceTargets(const std::vector<TargetPoint>& designed, const TopographerParams& design) const;
  // Undistorted detection-plane mm -> distorted -> pixel.
  Eigen::Vector2d PixelOf(const Eigen::Vector2d& undistorted_mm) const noexcept;
  // Pixel -> detection-plane mm as recorded (distorted).
  Eigen::Vector2d DistortedOf(const Eigen::Vector2d& pixel) const noexcept { return camera.DetectionPlaneFromPixel(pixel); }
  // Pixel -> undistorted detection-plane mm; nullopt outside the distortion's invertible domain.
  std::optional<Eigen::Vector2d> UndistortedOf(const Eigen::Vector2d& pixel) const noexcept;
  // Empty when physical; otherwise "key: problem".
  std::optional<std::string> Invalid() const;
};

// The nominal device of a camera: no distortion, the screen exactly where the design puts it.
Device NominalDevice(const TopographerCamera& camera);

// The spots of any surface through a device (Eq. 14-16 with the placed targets and the as-built a), undistorted
// detection-plane mm; spots that do not form are listed by identity in `failures`.
SyntheticImage SynthesizeImage(const Surface& surface, const Device& device, const TopographerParams& design,
                               const std::vector<TargetPoint>& designed_targets);

// Fixed (not fitted) quantities of the device projection below.
struct DeviceProjectionSetup {
  double b_mm = 70.0;              // pinhole to the nominal corneal vertex: the pivot is (0, 0, -b)
  // The pixel mapping (pitch, pixel aspect, orientation); its principal point and a are the fitted blocks instead.
  TopographerCamera camera;
  // The device's distortion: its model, centre and (Seidel) M_T; its coefficients are the fitted block instead.
  Distortion distortion = SeidelParams{};
  // The distortion block's lens model (model/lens_model.h); empty: Seidel [sigma].
  std::optional<LensModelId> Lens() const noexcept {
    if (const auto* lens = std::get_if<LensParams>(&distortion)) return lens->model;
    return std::nullopt;
  }
};

// The fixed part of a device's projection (b from the design).
DeviceProjectionSetup ProjectionSetupOf(const Device& device, const TopographerParams& design);

// The pixel at which the device's camera images a point (mm, the topographer's frame: pinhole at (0, 0, -b), the
// corneal vertex at the origin): Eq. 14a + 16 onto the detection plane, the distortion (Eq. 18 or the lens model on
// x1 / a), the camera's pixel mapping. Blocks as ProjectBallSpot's below; written once for the balls' spots and the
// target views' corners of the device fit (T = double or ceres::Jet).
template <typename T>
void ProjectPoint(const DeviceProjectionSetup& setup, const T* principal_px, const T* a_mm, const T* distortion,
                  const T* point_mm, T* pixel);

// The pixel at which a reference ball (a sphere of radius_mm, vertex at ball_vertex_mm) images one designed target,
// through a device given as parameter blocks — the model the device calibration fits (calib/device_fit.h), written
// once for simulation (T = double) and autodiff (T = ceres::Jet):
//   pose[6] (ScreenPose order), radial_scale[1], principal_point_px[2], a_mm[1],
//   distortion[1 or the lens model's count] (Seidel sigma per mm^2, or the lens model's coefficients on x1 / a).
// The reflection point is solved by Newton in double (SolveReflectionPointOn) and then moved by one Newton step in
// T, which carries its exact first derivatives (implicit function theorem) without differentiating the iterations.
// `initial_xy_mm`: a start for the reflection point (e.g. the designed point on the reference sphere plus the ball's
// lateral offset). Returns false when the ray misses the ball or the solve fails.
template <typename T>
bool ProjectBallSpot(const DeviceProjectionSetup& setup, const T* pose, const T* radial_scale, const T* principal_px,
                     const T* a_mm, const T* distortion, const T* ball_vertex_mm, double radius_mm,
                     const double* designed_target_mm, const Eigen::Vector2d& initial_xy_mm, T* pixel);

// Device files (JSON, docs/device.md): strict — unknown or missing keys, wrong types and non-physical values throw
// InputError "FILE: key: problem". `calibration` keeps what `device calibrate` reported (uncertainties, chi^2,
// gauge) so that records and reports can show it; it is not needed to measure.
struct DeviceFile {
  Device device;
  nlohmann::json calibration;  // null for a hand-written (nominal or as-designed) device
};
DeviceFile LoadDevice(const std::string& path);
// The covariance of a calibrated device's parameters, as `device calibrate` stores it (calibration.covariance): the
// fit's names (rx_deg, ry_deg, rz_deg, tx_mm, ty_mm, tz_mm, radial_scale, principal_point_u_px,
// principal_point_v_px, a_mm, sigma_per_mm2 or the lens model's k1, k2) and the matrix in their order and units.
struct DeviceCovariance {
  std::vector<std::string> names;
  Eigen::MatrixXd matrix;
};
// nullopt for a device without a calibration block (a hand-written nominal or as-designed device). Throws
// ConfigError "ORIGIN: calibration.covariance...: problem" when the block is malformed: names unknown or repeated,
// the matrix not square over the names, not finite, not symmetric, or a negative variance.
std::optional<DeviceCovariance> DeviceCovarianceOf(const nlohmann::json& calibration, const std::string& origin);
// Adds `delta` to the named parameter of `device` (the names above; a_mm moves Brown's focal length with it: they
// are one distance). Throws util::InputError for a name that is not a device parameter, or a lens model's name on a
// Seidel device and the reverse.
void ShiftDeviceParameter(Device* device, const std::string& name, double delta);
// The named parameter's value (the same names). Throws util::InputError like ShiftDeviceParameter.
double DeviceParameterOf(const Device& device, const std::string& name);

DeviceFile ParseDevice(const std::string& json_text, const std::string& origin);
std::string DeviceToJson(const Device& device, const nlohmann::json& calibration = nullptr);

template <typename T>
bool ProjectBallSpot(const DeviceProjectionSetup& setup, const T* pose, const T* radial_scale, const T* principal_px,
                     const T* a_mm, const T* distortion, const T* ball_vertex_mm, double radius_mm,
                     const double* designed_target_mm, const Eigen::Vector2d& initial_xy_mm, T* pixel) {
  using std::sqrt;
  const auto value = [](const auto& v) -> double {
    if constexpr (std::is_same_v<std::decay_t<decltype(v)>, double>) return v; else return v.a;
  };
  T target[3];
  ScreenPose::Apply(pose, *radial_scale, -setup.b_mm, designed_target_mm, target);
  const T h[3] = {T(0.0), T(0.0), T(-setup.b_mm)};
  const double r = radius_mm;
  // Front cap of the ball: z = z0 + r - sqrt(r^2 - (x - x0)^2 - (y - y0)^2) (model::Sphere with the vertex anywhere).
  const auto ball_sag = [r](const auto* vertex) {
    return [r, vertex](const auto& x, const auto& y, auto* z, auto* zx, auto* zy) {
      return Sphere::CapSagAndGradient(r, vertex, x, y, z, zx, zy);
    };
  };
  const double vertex_d[3] = {value(ball_vertex_mm[0]), value(ball_vertex_mm[1]), value(ball_vertex_mm[2])};
  const Eigen::Vector3d target_d(value(target[0]), value(target[1]), value(target[2]));
  const auto p2 = SolveReflectionPointOn(ball_sag(vertex_d), Eigen::Vector3d(0, 0, -setup.b_mm), target_d, initial_xy_mm);
  if (!p2) return false;
  // One Newton step in T from the converged point: x = x* - J^-1 f(x*; theta), with J = df/dx at x* (double).
  using Jet2 = ceres::Jet<double, 2>;
  const Jet2 h2[3] = {Jet2(0.0), Jet2(0.0), Jet2(-setup.b_mm)};
  const Jet2 t2[3] = {Jet2(target_d.x()), Jet2(target_d.y()), Jet2(target_d.z())};
  const Jet2 v2[3] = {Jet2(vertex_d[0]), Jet2(vertex_d[1]), Jet2(vertex_d[2])};
  Jet2 fj[2];
  if (!ReflectionResidual(ball_sag(v2), h2, t2, Jet2(p2->x(), 0), Jet2(p2->y(), 1), fj)) return false;
  const double det = fj[0].v[0] * fj[1].v[1] - fj[0].v[1] * fj[1].v[0];
  if (!(std::abs(det) > 0)) return false;
  T f[2];
  if (!ReflectionResidual(ball_sag(ball_vertex_mm), h, target, T(p2->x()), T(p2->y()), f)) return false;
  const T x = p2->x() - (fj[1].v[1] * f[0] - fj[0].v[1] * f[1]) / det;
  const T y = p2->y() - (-fj[1].v[0] * f[0] + fj[0].v[0] * f[1]) / det;
  T z, zx, zy;
  if (!ball_sag(ball_vertex_mm)(x, y, &z, &zx, &zy)) return false;
  const T on_ball[3] = {x, y, z};
  ProjectPoint(setup, principal_px, a_mm, distortion, on_ball, pixel);
  return true;
}

template <typename T>
void ProjectPoint(const DeviceProjectionSetup& setup, const T* principal_px, const T* a_mm, const T* distortion,
                  const T* point_mm, T* pixel) {
  // Eq. 14a + 16: the point on the detection plane, undistorted.
  T undistorted[2];
  ImageOfPoint(a_mm[0], setup.b_mm, point_mm, undistorted);
  T distorted[2];
  if (const auto* lens = std::get_if<LensParams>(&setup.distortion)) {
    const double cx = lens->centre_x_mm, cy = lens->centre_y_mm;
    const T normalised[2] = {(undistorted[0] - cx) / a_mm[0], (undistorted[1] - cy) / a_mm[0]};
    DistortNormalized(lens->model, distortion, normalised, distorted);
    distorted[0] = cx + distorted[0] * a_mm[0];
    distorted[1] = cy + distorted[1] * a_mm[0];
  } else {
    const auto& s = std::get<SeidelParams>(setup.distortion);
    const T seidel[SeidelRadial::kNumParams] = {distortion[0], T(s.magnification), T(s.centre_x_mm),
                                                T(s.centre_y_mm)};
    SeidelRadial::Distort(seidel, undistorted, distorted);  // Eq. 18
  }
  setup.camera.PixelFromDetectionPlane(principal_px, distorted, pixel);
}

}  // namespace topocal::model
