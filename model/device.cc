#include "model/device.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>
#include <variant>

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
  s.camera = device.camera;
  s.distortion = device.distortion;
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
  // On the detection plane, whose sensor is a few mm across: a centre beyond the pose's translation bound is a unit
  // error (a centre of -1e308 rendered 624 spots at NaN).
  if (std::abs(c[0]) > kMaxTranslationMm || std::abs(c[1]) > kMaxTranslationMm) {
    s.Fail(s.Key("centre_mm"),
           fmt::format("must lie within {} mm of the axis in x and y (got [{:g}, {:g}])", kMaxTranslationMm, c[0], c[1]));
  }
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
  if (const auto lens = LensModelFromName(model, LensNaming::kDevice)) {
    LensParams p;
    p.model = *lens;
    p.focal_mm = a_mm;  // a lens model acts on x1 / a: its focal length is the device's a
    const int n = LensParameterCount(*lens);
    const auto k = s.Numbers("k", n);
    for (int i = 0; i < n; ++i) {
      if (std::abs(k[i]) > 100) s.Fail(s.Key("k"), fmt::format("coefficient {} is {}: not a lens", i + 1, k[i]));
      p.k[i] = k[i];
    }
    const Eigen::Vector2d c = CentreMm(s);
    p.centre_x_mm = c.x();
    p.centre_y_mm = c.y();
    s.RejectUnknown();
    return p;
  }
  s.Fail(s.Key("model"), fmt::format("must be \"seidel\" or a lens model ({}) (got \"{}\")",
                                     LensModelNames(", ", LensNaming::kDevice), model.substr(0, 60)));
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
    const auto& b = std::get<LensParams>(device.distortion);
    j["distortion"] = {{"model", LensModelName(b.model, LensNaming::kDevice)},
                       {"k", std::vector<double>(b.k.begin(), b.k.begin() + LensParameterCount(b.model))},
                       {"centre_mm", {b.centre_x_mm, b.centre_y_mm}}};
  }
  const auto& p = device.screen;
  j["screen_pose"] = {{"rx_deg", p.rx_deg}, {"ry_deg", p.ry_deg}, {"rz_deg", p.rz_deg},
                      {"tx_mm", p.tx_mm},   {"ty_mm", p.ty_mm},   {"tz_mm", p.tz_mm},
                      {"radial_scale", p.radial_scale}};
  if (!calibration.is_null()) j["calibration"] = calibration;
  return j.dump(2) + "\n";
}

namespace {

// The device parameter a covariance name stands for; nullptr when the name is not one (or not of this distortion).
double* DeviceParameter(Device* d, const std::string& name) {
  ScreenPose& p = d->screen;
  if (name == "rx_deg") return &p.rx_deg;
  if (name == "ry_deg") return &p.ry_deg;
  if (name == "rz_deg") return &p.rz_deg;
  if (name == "tx_mm") return &p.tx_mm;
  if (name == "ty_mm") return &p.ty_mm;
  if (name == "tz_mm") return &p.tz_mm;
  if (name == "radial_scale") return &p.radial_scale;
  if (name == "principal_point_u_px") return &d->camera.principal_point_px.x();
  if (name == "principal_point_v_px") return &d->camera.principal_point_px.y();
  if (name == "a_mm") return &d->camera.a_mm;
  if (auto* s = std::get_if<SeidelParams>(&d->distortion)) return name == "sigma_per_mm2" ? &s->sigma_per_mm2 : nullptr;
  auto& b = std::get<LensParams>(d->distortion);
  const auto names = LensParameterNames(b.model);
  const auto it = std::find(names.begin(), names.end(), name);
  return it == names.end() ? nullptr : &b.k[static_cast<size_t>(it - names.begin())];
}

}  // namespace

void ShiftDeviceParameter(Device* device, const std::string& name, double delta) {
  double* p = DeviceParameter(device, name);
  if (!p) throw util::InputError(fmt::format("'{}' is not a parameter of this device", name));
  *p += delta;
  if (name == "a_mm") {
    if (auto* b = std::get_if<LensParams>(&device->distortion)) b->focal_mm = device->camera.a_mm;
  }
}

double DeviceParameterOf(const Device& device, const std::string& name) {
  Device copy = device;
  const double* p = DeviceParameter(&copy, name);
  if (!p) throw util::InputError(fmt::format("'{}' is not a parameter of this device", name));
  return *p;
}

std::optional<DeviceCovariance> DeviceCovarianceOf(const json& calibration, const std::string& origin) {
  if (calibration.is_null()) return std::nullopt;
  const std::string key = "calibration.covariance";
  const auto fail = [&](const std::string& what, const std::string& problem) -> void {
    throw util::ConfigError(fmt::format("{}: {}{}: {}", origin, key, what, problem));
  };
  if (!calibration.is_object() || !calibration.contains("covariance")) fail("", "missing");
  const json& c = calibration.at("covariance");
  if (!c.is_object() || !c.contains("parameters") || !c.contains("matrix")) {
    fail("", "must be an object with \"parameters\" and \"matrix\"");
  }
  const json& names = c.at("parameters");
  const json& matrix = c.at("matrix");
  if (!names.is_array() || names.empty()) fail(".parameters", "must be a non-empty array of names");
  DeviceCovariance out;
  // A name is a device parameter if it is one of a Seidel device or of a device of any lens model.
  const auto known = [](const std::string& name) {
    Device probe;
    probe.distortion = SeidelParams{};
    bool found = DeviceParameter(&probe, name) != nullptr;
    ForEachLensModel([&](auto m) {
      LensParams lens;
      lens.model = m;
      probe.distortion = lens;
      found = found || DeviceParameter(&probe, name) != nullptr;
    });
    return found;
  };
  std::set<std::string> seen;
  for (const auto& n : names) {
    if (!n.is_string()) fail(".parameters", fmt::format("{} is not a name", util::QuoteJsonValue(n)));
    const std::string name = n.get<std::string>();
    if (!known(name)) {
      fail(".parameters", fmt::format("'{}' is not a device parameter", name));
    }
    if (!seen.insert(name).second) fail(".parameters", fmt::format("'{}' is given twice", name));
    out.names.push_back(name);
  }
  const auto n = static_cast<Eigen::Index>(out.names.size());
  if (!matrix.is_array() || static_cast<Eigen::Index>(matrix.size()) != n) {
    fail(".matrix", fmt::format("must be {} rows (one per parameter)", n));
  }
  out.matrix.resize(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const json& row = matrix.at(static_cast<size_t>(i));
    if (!row.is_array() || static_cast<Eigen::Index>(row.size()) != n) {
      fail(fmt::format(".matrix[{}]", i), fmt::format("must be {} numbers", n));
    }
    for (Eigen::Index k = 0; k < n; ++k) {
      const json& v = row.at(static_cast<size_t>(k));
      if (!v.is_number() || !std::isfinite(v.get<double>())) {
        fail(fmt::format(".matrix[{}][{}]", i, k), "must be a finite number");
      }
      out.matrix(i, k) = v.get<double>();
    }
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    if (out.matrix(i, i) < 0) fail(fmt::format(".matrix[{}][{}]", i, i), "a variance cannot be negative");
    for (Eigen::Index k = 0; k < i; ++k) {
      const double scale = std::sqrt(out.matrix(i, i) * out.matrix(k, k));
      if (std::abs(out.matrix(i, k) - out.matrix(k, i)) > 1e-9 * scale + 1e-300) {
        fail(fmt::format(".matrix[{}][{}]", i, k), "the matrix is not symmetric");
      }
    }
  }
  return out;
}

}  // namespace topocal::model
