#include "model/device.h"

#include <fmt/format.h>

#include <cmath>
#include <set>

#include "util/io.h"
#include "util/json_section.h"

namespace topocal::model {

using nlohmann::json;

ScreenPose ScreenPose::FromArray(const double* p, double radial_scale) {
  return {p[kRx], p[kRy], p[kRz], p[kTx], p[kTy], p[kTz], radial_scale};
}

bool ScreenPose::IsNominal() const noexcept {
  return rx_deg == 0 && ry_deg == 0 && rz_deg == 0 && tx_mm == 0 && ty_mm == 0 && tz_mm == 0 && radial_scale == 1.0;
}

Eigen::Vector3d ScreenPose::Apply(const Eigen::Vector3d& designed_mm, double pivot_z_mm) const noexcept {
  const auto pose = AsArray();
  Eigen::Vector3d out;
  Apply(pose.data(), radial_scale, pivot_z_mm, designed_mm.data(), out.data());
  return out;
}

TopographerParams Device::AsBuilt(const TopographerParams& design) const {
  TopographerParams p = design;
  p.a_mm = camera.a_mm;
  return p;
}

std::vector<TargetPoint> Device::PlaceTargets(const std::vector<TargetPoint>& designed,
                                              const TopographerParams& design) const {
  std::vector<TargetPoint> placed = designed;
  if (screen.IsNominal()) return placed;
  for (auto& t : placed) t.on_cone_mm = screen.Apply(t.on_cone_mm, -design.b_mm);
  return placed;
}

Eigen::Vector2d Device::PixelOf(const Eigen::Vector2d& undistorted_mm) const noexcept {
  return camera.PixelFromDetectionPlane(Distort(distortion, undistorted_mm));
}

std::optional<Eigen::Vector2d> Device::UndistortedOf(const Eigen::Vector2d& pixel) const noexcept {
  return Undistort(distortion, camera.DetectionPlaneFromPixel(pixel));
}

Device NominalDevice(const TopographerCamera& camera) {
  Device d;
  d.camera = camera;
  return d;
}

DeviceProjectionSetup ProjectionSetupOf(const Device& device, const TopographerParams& design) {
  DeviceProjectionSetup s;
  s.b_mm = design.b_mm;
  s.pixel_pitch_mm = device.camera.PitchMm();
  s.orientation = device.camera.Orientation();
  if (const auto* seidel = std::get_if<SeidelParams>(&device.distortion)) {
    s.brown = false;
    s.magnification = seidel->magnification;
    s.distortion_centre_mm = {seidel->centre_x_mm, seidel->centre_y_mm};
  } else {
    const auto& b = std::get<BrownParams>(device.distortion);
    s.brown = true;
    s.distortion_centre_mm = {b.centre_x_mm, b.centre_y_mm};
  }
  return s;
}

SyntheticImage SynthesizeImage(const Surface& surface, const Device& device, const TopographerParams& design,
                               const std::vector<TargetPoint>& designed_targets) {
  return SynthesizeImage(surface, Topographer{device.AsBuilt(design)}, device.PlaceTargets(designed_targets, design));
}

// ---------------------------------------------------------------------------------------------------------------
// Device file.

namespace {

// Limits of a plausible as-built device, far outside any assembly tolerance; a value beyond them is a wrong unit or
// a wrong sign convention, not a device.
constexpr double kMaxRotationDeg = 10.0;
constexpr double kMaxTranslationMm = 10.0;
constexpr double kMaxRadialScaleError = 0.1;
constexpr int kFormatVersion = 1;
constexpr const char* kFormat = "topocal-device";

// The distortion centre, optional in both models.
Eigen::Vector2d CentreMm(util::JsonSection& s) {
  if (!s.Has("centre_mm")) return Eigen::Vector2d::Zero();
  const auto c = s.Numbers("centre_mm", 2);
  return {c[0], c[1]};
}

Distortion ParseDistortion(util::JsonSection s, double a_mm) {
  const std::string model = s.String("model");
  if (model == "seidel") {
    SeidelParams p;
    // |sigma| beyond 1e-2 mm^-2 folds the paper's field many times over: a unit error, not a lens.
    p.sigma_per_mm2 = s.InRange("sigma_per_mm2", 0.0, -1e-2, 1e-2);
    p.magnification = s.Number("magnification", p.magnification);
    if (!(p.magnification < 0 && p.magnification > -1)) {
      s.Fail(s.Key("magnification"), fmt::format("must be in (-1, 0): the image is inverted (got {})", p.magnification));
    }
    const Eigen::Vector2d c = CentreMm(s);
    p.centre_x_mm = c.x();
    p.centre_y_mm = c.y();
    s.RejectUnknown();
    return p;
  }
  if (model == "brown") {
    BrownParams p;
    p.focal_mm = a_mm;  // Brown acts on x1 / a: its focal length is the device's a
    const auto k = s.Numbers("k", 5);
    for (int i = 0; i < 5; ++i) {
      if (std::abs(k[i]) > 100) s.Fail(s.Key("k"), fmt::format("coefficient {} is {}: not a lens", i + 1, k[i]));
      p.k[i] = k[i];
    }
    const Eigen::Vector2d c = CentreMm(s);
    p.centre_x_mm = c.x();
    p.centre_y_mm = c.y();
    s.RejectUnknown();
    return p;
  }
  s.Fail(s.Key("model"), fmt::format("must be \"seidel\" or \"brown\" (got \"{}\")", model.substr(0, 60)));
}

ScreenPose ParseScreenPose(util::JsonSection s) {
  ScreenPose p;
  p.rx_deg = s.InRange("rx_deg", 0.0, -kMaxRotationDeg, kMaxRotationDeg);
  p.ry_deg = s.InRange("ry_deg", 0.0, -kMaxRotationDeg, kMaxRotationDeg);
  p.rz_deg = s.InRange("rz_deg", 0.0, -kMaxRotationDeg, kMaxRotationDeg);
  p.tx_mm = s.InRange("tx_mm", 0.0, -kMaxTranslationMm, kMaxTranslationMm);
  p.ty_mm = s.InRange("ty_mm", 0.0, -kMaxTranslationMm, kMaxTranslationMm);
  p.tz_mm = s.InRange("tz_mm", 0.0, -kMaxTranslationMm, kMaxTranslationMm);
  p.radial_scale = s.InRange("radial_scale", 1.0, 1.0 - kMaxRadialScaleError, 1.0 + kMaxRadialScaleError);
  s.RejectUnknown();
  return p;
}

}  // namespace

std::optional<std::string> Device::Invalid() const {
  if (auto why = camera.Invalid()) return "camera." + *why;
  if (std::abs(screen.rx_deg) > kMaxRotationDeg || std::abs(screen.ry_deg) > kMaxRotationDeg ||
      std::abs(screen.rz_deg) > kMaxRotationDeg) {
    return fmt::format("screen_pose: rotations must be within +-{} deg", kMaxRotationDeg);
  }
  if (std::abs(screen.tx_mm) > kMaxTranslationMm || std::abs(screen.ty_mm) > kMaxTranslationMm ||
      std::abs(screen.tz_mm) > kMaxTranslationMm) {
    return fmt::format("screen_pose: translations must be within +-{} mm", kMaxTranslationMm);
  }
  if (!(std::abs(screen.radial_scale - 1.0) <= kMaxRadialScaleError)) {
    return fmt::format("screen_pose.radial_scale: must be within 1 +- {}", kMaxRadialScaleError);
  }
  return std::nullopt;
}

DeviceFile ParseDevice(const std::string& json_text, const std::string& origin) {
  const json j = util::ParseJsonStrict(json_text, origin);
  util::JsonSection top(j, origin, "");
  if (top.String("format") != kFormat) top.Fail("format", fmt::format("must be \"{}\"", kFormat));
  const json& version = top.Get("format_version");
  if (!version.is_number_integer() || version.get<long long>() != kFormatVersion) {
    top.Fail("format_version",
             fmt::format("this topocal reads version {} (got {})", kFormatVersion, util::QuoteJsonValue(version)));
  }
  DeviceFile out;
  out.device.camera = CameraFromJson(top.Get("camera"), origin, "camera");
  out.device.distortion = top.Has("distortion") ? ParseDistortion(top.Child("distortion"), out.device.camera.a_mm)
                                                : Distortion{SeidelParams{}};
  if (top.Has("screen_pose")) out.device.screen = ParseScreenPose(top.Child("screen_pose"));
  if (top.Has("calibration")) {
    out.calibration = top.Get("calibration");
    if (!out.calibration.is_object()) top.Fail("calibration", "must be a JSON object");
  }
  top.RejectUnknown();
  if (const auto why = out.device.Invalid()) throw util::InputError(fmt::format("{}: {}", origin, *why));
  return out;
}

DeviceFile LoadDevice(const std::string& path) { return ParseDevice(util::ReadFile(path), path); }

std::string DeviceToJson(const Device& device, const json& calibration) {
  json j;
  j["format"] = kFormat;
  j["format_version"] = kFormatVersion;
  j["camera"] = CameraToJson(device.camera);
  if (const auto* s = std::get_if<SeidelParams>(&device.distortion)) {
    j["distortion"] = {{"model", "seidel"},
                       {"sigma_per_mm2", s->sigma_per_mm2},
                       {"magnification", s->magnification},
                       {"centre_mm", {s->centre_x_mm, s->centre_y_mm}}};
  } else {
    const auto& b = std::get<BrownParams>(device.distortion);
    j["distortion"] = {{"model", "brown"},
                       {"k", {b.k[0], b.k[1], b.k[2], b.k[3], b.k[4]}},
                       {"centre_mm", {b.centre_x_mm, b.centre_y_mm}}};
  }
  const auto& p = device.screen;
  j["screen_pose"] = {{"rx_deg", p.rx_deg}, {"ry_deg", p.ry_deg}, {"rz_deg", p.rz_deg},
                      {"tx_mm", p.tx_mm},   {"ty_mm", p.ty_mm},   {"tz_mm", p.tz_mm},
                      {"radial_scale", p.radial_scale}};
  if (!calibration.is_null()) j["calibration"] = calibration;
  return j.dump(2) + "\n";
}

}  // namespace topocal::model
