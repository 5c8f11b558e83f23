#include "tools/unit_workflow.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <tuple>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "calib/calibrate.h"
#include "calib/calibration_file.h"
#include "calib/detect.h"
#include "calib/target.h"
#include "model/config.h"
#include "model/io.h"
#include "model/json_section.h"
#include "model/sha256.h"
#include "model/topographer_camera.h"
#include "model/version.h"
#include "model/device.h"
#include "pipeline/detection_plane.h"
#include "pipeline/device_calibration.h"
#include "pipeline/device_verification.h"
#include "pipeline/unit_verification.h"
#include "report/unit_record_writer.h"
#include "tools/file_glob.h"
#include "tools/map_output.h"

namespace topocal::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr size_t kMaxSerialLength = 64;

// The record's date: SOURCE_DATE_EPOCH when set (the reproducible-builds convention, so that a rerun can be
// compared byte for byte), otherwise now. ISO 8601 UTC.
std::string RecordDateUtc() {
  std::time_t t = std::time(nullptr);
  if (const char* epoch = std::getenv("SOURCE_DATE_EPOCH"); epoch && *epoch) {
    char* end = nullptr;
    errno = 0;
    const long long v = std::strtoll(epoch, &end, 10);
    if (errno != 0 || *end != '\0' || v < 0) {
      throw model::InputError(fmt::format("SOURCE_DATE_EPOCH '{}': not a non-negative integer", epoch));
    }
    t = static_cast<std::time_t>(v);
  }
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

json Numbers(const pipeline::ClinicalNumbers& n) {
  json j = {{"spots", n.spots},
            {"rx_mm", n.rx_mm},
            {"ry_mm", n.ry_mm},
            {"kx", n.kx},
            {"ky", n.ky},
            {"alpha_deg", n.alpha_deg},
            {"radius_mm", n.radius_mm},
            {"central_axial_power_D", n.central_axial_power_D},
            {"pv_tangential_D", n.pv_tangential_D},
            {"pv_axial_D", n.pv_axial_D}};
  if (n.height_pv_um) j["height_pv_um"] = *n.height_pv_um;
  if (n.height_rms_um) j["height_rms_um"] = *n.height_rms_um;
  return j;
}

json Uncertainty(const std::optional<pipeline::ClinicalUncertainty>& u, const pipeline::CheckOptions& o) {
  if (!u) return nullptr;
  json q = json::object();
  for (const auto& [name, v] : u->quantities) q[name] = {{"mean", v.mean}, {"U", v.expanded_k2}};
  return {{"samples", u->samples},         {"seed", o.seed},          {"failed_samples", u->failed_samples},
          {"undistort_failures", u->undistort_failures},
          {"draws_with_undistort_failures", u->draws_with_undistort_failures},
          {"drawn", u->drawn},             {"correlated", u->correlated}, {"coverage_factor", 2},
          {"quantities", q}};
}

// Largest displacement (um on the detection plane, and px) the calibrated distortion gives a point within
// `radius_mm` of the axis, sampled on a polar grid.
std::pair<double, double> MaxDisplacement(const model::Distortion& d, double radius_mm, double pitch_mm) {
  constexpr int kRings = 20, kMeridians = 72;
  double max_mm = 0;
  for (int i = 1; i <= kRings; ++i) {
    const double r = radius_mm * i / kRings;
    for (int j = 0; j < kMeridians; ++j) {
      const double t = 2 * M_PI * j / kMeridians;
      const Eigen::Vector2d p(r * std::cos(t), r * std::sin(t));
      max_mm = std::max(max_mm, (model::Distort(d, p) - p).norm());
    }
  }
  return {max_mm * 1000.0, max_mm / pitch_mm};
}

// The inputs, read and checked before any work, with their digests for the record.
struct LoadedInputs {
  model::Config config;
  model::TopographerCamera camera;
  calib::TargetDescription target;
  calib::CalibrationOptions options;
  cv::Mat sphere_image;  // empty without a reference sphere
  model::Device nominal_device;
  std::vector<pipeline::BallImage> balls;  // empty: no device stage
  json provenance = json::array();
};

void CheckImageSize(const cv::Mat& image, const std::string& path, const LoadedInputs& in, const UnitRequest& r) {
  if (image.cols != in.camera.width_px || image.rows != in.camera.height_px) {
    throw model::InputError(fmt::format("{}: the image is {} x {} px but {} says {} x {} px", path, image.cols,
                                        image.rows, r.camera, in.camera.width_px, in.camera.height_px));
  }
}

LoadedInputs LoadInputs(const UnitRequest& r) {
  if (!IsValidSerial(r.serial)) {
    throw model::InputError(fmt::format("--serial '{}': use 1-{} characters of A-Z a-z 0-9 . _ - (not starting with .)",
                                        r.serial, kMaxSerialLength));
  }
  if (r.out.empty()) throw model::InputError("--out: the record directory is required");
  if (r.reference_sphere.empty() != (r.sphere_radius_mm == 0)) {
    throw model::InputError("--reference-sphere and --sphere-radius-mm go together");
  }
  if (r.uncertainty_samples != 0 && (r.uncertainty_samples < 2 || r.uncertainty_samples > kMaxUncertaintySamples)) {
    throw model::InputError(fmt::format("--uncertainty {}: 0 (none) or 2 to {} draws", r.uncertainty_samples,
                                        kMaxUncertaintySamples));
  }
  if (r.images.empty()) throw model::InputError("--images: no image given");
  if (r.balls.size() != r.ball_radii_mm.size()) {
    throw model::InputError(fmt::format("--radii-mm: {} radii for {} ball images (one certified radius per image)",
                                        r.ball_radii_mm.size(), r.balls.size()));
  }
  if (!r.device.empty() && r.balls.empty()) throw model::InputError("--device: goes with --balls (the device stage)");
  if (fs::exists(r.out) && !fs::exists(fs::path(r.out) / "unit.json")) {
    throw model::InputError(fmt::format("--out {}: exists and is not a unit record; not overwriting it", r.out));
  }
  LoadedInputs in;
  in.config = model::LoadConfig(r.config);
  in.camera = model::LoadTopographerCamera(r.camera);
  if (!r.device.empty()) {
    in.nominal_device = model::LoadDevice(r.device).device;
    if (in.nominal_device.camera.width_px != in.camera.width_px ||
        in.nominal_device.camera.height_px != in.camera.height_px) {
      throw model::InputError(fmt::format("{}: the device's sensor is {} x {} px but {} says {} x {} px", r.device,
                                          in.nominal_device.camera.width_px, in.nominal_device.camera.height_px,
                                          r.camera, in.camera.width_px, in.camera.height_px));
    }
  } else {
    in.nominal_device = model::NominalDevice(in.camera);
  }
  in.target = calib::LoadTargetDescription(r.target);

  const auto model_kind = calib::ParseDistortionModel(r.model);
  if (!model_kind) throw model::InputError(fmt::format("--model: '{}' is not seidel or brown5", r.model));
  auto& o = in.options;
  o.model = *model_kind;
  o.fit_distortion_centre = r.fit_centre;
  o.fixed = {r.fixed.begin(), r.fixed.end()};
  // The topographer's geometry: the lens and sensor from the camera description, the target at the cornea position.
  o.focal_mm = in.camera.a_mm;
  o.pixel_pitch_um = in.camera.pixel_pitch_um;
  o.distance_mm = in.config.topographer.b_mm;
  o.magnification = in.config.distortion.magnification;
  for (const auto& f : r.fixed) {
    if (std::find(std::begin(calib::kParameterNames), std::end(calib::kParameterNames), f) ==
        std::end(calib::kParameterNames)) {
      throw model::InputError(fmt::format("--fix: '{}' is not a camera parameter (fx fy cx cy k1 k2 p1 p2 k3 ex ey)", f));
    }
  }
  std::string why;
  if (!o.IsValid(&why)) throw model::InputError(why);

  const auto add = [&](const std::string& role, const std::string& path) {
    in.provenance.push_back({{"role", role}, {"path", path}, {"sha256", model::Sha256HexOfFile(path)}});
  };
  add("config", r.config);
  add("camera", r.camera);
  add("target", r.target);
  for (const auto& path : r.images) add("image", path);
  if (!r.reference_sphere.empty()) {
    add("reference_sphere", r.reference_sphere);
    in.sphere_image = cv::imread(r.reference_sphere, cv::IMREAD_UNCHANGED);
    if (in.sphere_image.empty()) {
      throw model::InputError(fmt::format("{}: not an image OpenCV can read", r.reference_sphere));
    }
    CheckImageSize(in.sphere_image, r.reference_sphere, in, r);
  }
  if (!r.device.empty()) add("device", r.device);
  for (size_t i = 0; i < r.balls.size(); ++i) {
    // Reference balls for a topographer: radii of human corneas and a little beyond.
    if (!(r.ball_radii_mm[i] >= 3.0 && r.ball_radii_mm[i] <= 20.0)) {
      throw model::InputError(fmt::format("--radii-mm: {} for {} is not a reference-ball radius (3-20 mm)",
                                          r.ball_radii_mm[i], r.balls[i]));
    }
    add("ball", r.balls[i]);
    pipeline::BallImage b{r.balls[i], cv::imread(r.balls[i], cv::IMREAD_UNCHANGED), r.ball_radii_mm[i]};
    if (b.image.empty()) throw model::InputError(fmt::format("{}: not an image OpenCV can read", r.balls[i]));
    CheckImageSize(b.image, r.balls[i], in, r);
    in.balls.push_back(std::move(b));
  }
  return in;
}

// The device stage: the device fitted to the balls, and what it is worth beside the lens-only calibration.
struct DeviceStage {
  pipeline::DeviceCalibration calibration;
  model::Device lens_only;
  std::optional<pipeline::HeldOutBall> held_out;
  pipeline::ThreeWay paper;
};

std::optional<DeviceStage> CalibrateDeviceStage(const UnitRequest& r, const LoadedInputs& in,
                                                const model::Distortion& lens) {
  if (in.balls.empty()) return std::nullopt;
  DeviceStage d;
  try {
    d.calibration = pipeline::CalibrateDevice(in.balls, in.nominal_device, in.config, {});
  } catch (const std::invalid_argument& e) {
    throw model::InputError(e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: {}", r.serial, e.what()));
  }
  if (!d.calibration.fit.ok) {
    throw std::runtime_error(fmt::format("{}: device calibration failed: {}", r.serial, d.calibration.fit.message));
  }
  d.lens_only = in.nominal_device;
  d.lens_only.distortion = lens;
  const auto& device = d.calibration.fit.device;
  try {
    if (!in.sphere_image.empty()) {
      d.held_out = pipeline::VerifyHeldOutBall(in.sphere_image, r.sphere_radius_mm, in.nominal_device, d.lens_only,
                                               device, in.config);
    }
    d.paper = pipeline::PaperCorneaThroughDevice(in.nominal_device, d.lens_only, device, in.config);
  } catch (const std::invalid_argument& e) {
    throw model::InputError(fmt::format("{}: {}", r.reference_sphere, e.what()));
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: {}", r.serial, e.what()));
  }
  return d;
}

json ThreeWayJson(const pipeline::ThreeWay& t) {
  return {{"uncorrected", Numbers(t.uncorrected.numbers)},
          {"lens_only", Numbers(t.lens_only.numbers)},
          {"device", Numbers(t.device.numbers)}};
}

json DeviceJson(const DeviceStage& d) {
  json j = pipeline::DeviceCalibrationJson(d.calibration);
  j["file"] = "device.json";
  if (d.held_out) {
    const auto& h = *d.held_out;
    j["held_out_ball"] = ThreeWayJson(h.stages);
    j["held_out_ball"]["radius_true_mm"] = h.radius_true_mm;
    j["held_out_ball"]["power_true_D"] = h.power_true_D;
    j["held_out_ball"]["spots_indexed"] = h.spots_indexed;
  }
  j["paper_cornea"] = ThreeWayJson(d.paper);
  return j;
}

struct Calibration {
  calib::CalibrationResult result;
  std::vector<std::string> view_paths;  // parallel to the views the calibration was given
  bool single_view = false;
};

Calibration CalibrateViews(const UnitRequest& r, const LoadedInputs& in,
                           const std::function<void(const std::string&)>& log) {
  Calibration c;
  std::vector<calib::ViewObservations> views;
  for (const auto& path : r.images) {
    const cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
    if (image.empty()) throw model::InputError(fmt::format("{}: not an image OpenCV can read", path));
    CheckImageSize(image, path, in, r);
    const auto found = calib::DetectTargetDetailed(in.target, image);
    if (!found.view) {
      log(fmt::format("{}: skipping {}: no target found{}", r.serial, path,
                      found.message.empty() ? "" : ": " + found.message));
      continue;
    }
    views.push_back(*found.view);
    views.back().image_path = path;
    c.view_paths.push_back(path);
  }
  if (views.empty()) throw std::runtime_error(fmt::format("{}: no target found in any image", r.serial));
  c.single_view = r.images.size() == 1;
  c.result = c.single_view ? calib::CalibrateSingleView(views[0], in.options)
                           : calib::CalibrateMultiView(views, in.options);
  for (const auto& s : c.result.skipped_views) {
    log(fmt::format("{}: not used {}: {}", r.serial, c.view_paths[static_cast<size_t>(s.view)], s.reason));
  }
  if (!c.result.ok()) {
    throw std::runtime_error(fmt::format("{}: calibration failed ({}): {}", r.serial,
                                         calib::ToString(c.result.status), c.result.message));
  }
  return c;
}

// The size of the calibrated distortion over the spot pattern's field on the detection plane.
struct DistortionField {
  double field_radius_mm = 0;  // the outermost spot of the configured cornea
  double max_um = 0, max_px = 0;
};

DistortionField MeasureDistortionField(const calib::CameraModel& calibrated, const LoadedInputs& in,
                                       const std::string& serial) {
  std::string why;
  const auto distortion = pipeline::DistortionOnDetectionPlane(calibrated, in.camera, &why);
  if (!distortion) throw std::runtime_error(fmt::format("{}: {}", serial, why));
  const auto& cfg = in.config;
  const auto design = model::DesignNullScreen(cfg.ideal_image, cfg.topographer);
  const auto ideal =
      model::SynthesizeImage(model::Biconic{cfg.cornea}, model::Topographer{cfg.topographer}, design.targets);
  DistortionField f;
  for (const auto& s : ideal.spots) f.field_radius_mm = std::max(f.field_radius_mm, s.position_mm.norm());
  std::tie(f.max_um, f.max_px) = MaxDisplacement(*distortion, f.field_radius_mm, in.camera.PitchMm());
  return f;
}

json CalibrationJson(const Calibration& c, const DistortionField& field, const model::TopographerCamera& camera) {
  const auto& result = c.result;
  json cal;
  cal["model"] = std::string(calib::ToString(result.model));
  cal["single_view"] = result.single_view;
  cal["image_width_px"] = result.camera.width_px;
  cal["image_height_px"] = result.camera.height_px;
  cal["rms_px"] = result.rms_px;
  cal["corners_used"] = result.corners_used;
  cal["outliers"] = result.outliers.size();
  cal["parameters"] = json::array();
  for (const auto& p : result.parameters) {
    cal["parameters"].push_back({{"name", p.name}, {"value", p.value}, {"stddev", p.stddev}, {"fixed", p.fixed}});
  }
  // The covariance of the free parameters only (the calibration file holds the full 11 x 11).
  std::vector<int> free_index;
  for (int i = 0; i < calib::kNumCameraParameters; ++i) {
    if (!result.parameters[static_cast<size_t>(i)].fixed) free_index.push_back(i);
  }
  json names = json::array(), rows = json::array();
  for (const int i : free_index) {
    names.push_back(result.parameters[static_cast<size_t>(i)].name);
    json row = json::array();
    for (const int j : free_index) row.push_back(result.covariance(i, j));
    rows.push_back(row);
  }
  cal["covariance"] = {{"names", names}, {"matrix", rows}};
  if (result.seidel) {
    cal["seidel"] = {{"sigma_per_mm2", result.seidel->sigma_per_mm2},
                     {"sigma_stddev_per_mm2", result.seidel->sigma_stddev_per_mm2},
                     {"magnification", result.seidel->magnification},
                     {"focal_mm", result.seidel->focal_mm}};
  }
  cal["views"] = json::array();
  for (size_t v = 0; v < result.views_used.size(); ++v) {
    const auto idx = result.views_used[v];
    const auto corners = std::count_if(result.residuals.begin(), result.residuals.end(),
                                       [&](const auto& r) { return r.view == idx && !r.outlier; });
    cal["views"].push_back({{"image", c.view_paths[static_cast<size_t>(idx)]},
                            {"rms_px", result.per_view_rms_px[v]},
                            {"corners", corners}});
  }
  cal["distortion_field"] = {{"max_displacement_um", field.max_um},
                             {"max_displacement_px", field.max_px},
                             {"field_radius_mm", field.field_radius_mm},
                             {"field_radius_px", field.field_radius_mm / camera.PitchMm()}};
  return cal;
}

json VerificationJson(const pipeline::SphereVerification& s, const UnitRequest& r, const pipeline::CheckOptions& check) {
  json v = {{"image", r.reference_sphere},
            {"radius_true_mm", s.radius_true_mm},
            {"power_true_D", s.power_true_D},
            {"keratometric_index", topo::kKeratometricIndex},
            {"central_zone_diameter_mm", 2 * pipeline::kCentralPowerRadiusMm},
            {"spots_indexed", s.spots_indexed},
            {"spots_unassigned", s.spots_unassigned},
            {"spots_missing", s.spots_missing},
            {"undistort_failures", s.undistort_failures},
            // "sphere": centre and radius fitted; kx, ky, alpha_deg are 0 by construction (docs/unit-record.md)
            {"surface_fit", topo::BiconicFitModeName(s.corrected.analysis.surface_fit.mode)}};
  for (const auto& [name, stage] : {std::pair{"uncorrected", &s.uncorrected}, std::pair{"corrected", &s.corrected}}) {
    json n = Numbers(stage->numbers);
    n["spots_indexed"] = s.spots_indexed;  // both stages use the same detected and indexed spots
    n["radius_error_mm"] = s.RadiusErrorMm(*stage);
    n["power_error_D"] = s.PowerErrorD(*stage);
    v[name] = n;
  }
  v["uncertainty"] = Uncertainty(s.uncertainty, check);
  return v;
}

json PaperCorneaJson(const pipeline::SimulatedCornea& paper, const pipeline::CheckOptions& check) {
  const auto& t = paper.truth;
  return {{"truth", {{"rx_mm", t.rx_mm}, {"ry_mm", t.ry_mm}, {"kx", t.kx}, {"ky", t.ky}, {"alpha_deg", t.alpha_deg}}},
          {"max_displacement_um", paper.max_displacement_um},
          {"uncorrected", Numbers(paper.uncorrected.numbers)},
          {"corrected", Numbers(paper.corrected.numbers)},
          {"uncertainty", Uncertainty(paper.uncertainty, check)}};
}

std::string ResidualsCsv(const Calibration& c) {
  std::string csv = "view,image,corner_id,x_px,y_px,dx_px,dy_px,outlier\n";
  for (const auto& r : c.result.residuals) {
    csv += fmt::format("{},{},{},{:.6f},{:.6f},{:.6f},{:.6f},{}\n", r.view, c.view_paths[static_cast<size_t>(r.view)],
                       r.corner_id, r.observed_px.x(), r.observed_px.y(), r.residual_px.x(), r.residual_px.y(),
                       r.outlier ? 1 : 0);
  }
  return csv;
}

void WriteRecordMaps(const std::string& dir, const std::optional<pipeline::SphereVerification>& sphere,
                     const pipeline::SimulatedCornea& paper, const model::Config& config) {
  // The PNGs go in the record, at half the default size (~0.15 MB each; the report embeds them all); the numbers
  // are in unit.json (CSV grids would be ~0.6 MB each).
  constexpr bool kMapCsv = true;  // the numbers behind every picture (~0.6 MB a map, 16 maps)
  constexpr int kMapSizePx = 400;
  // Each case's before/after pair is one set: both stages on the same scales, so that they compare by eye.
  MapSetOptions o;
  o.csv = kMapCsv;
  o.size_px = kMapSizePx;
  if (sphere) {
    const auto truth = pipeline::WithSphere(config, sphere->radius_true_mm).cornea;
    WriteAnalysisMapSet(dir,
                        {{"sphere_uncorrected_", " - reference sphere, uncorrected", &sphere->uncorrected.analysis, &truth, {}},
                         {"sphere_corrected_", " - reference sphere, corrected", &sphere->corrected.analysis, &truth, {}}},
                        o);
  }
  WriteAnalysisMapSet(dir,
                      {{"paper_uncorrected_", " - paper cornea, uncorrected", &paper.uncorrected.analysis, &config.cornea, {}},
                       {"paper_corrected_", " - paper cornea, corrected", &paper.corrected.analysis, &config.cornea, {}}},
                      o);
}

std::vector<std::string> Summary(const UnitRequest& r, const Calibration& c, const DistortionField& field,
                                 const std::optional<pipeline::SphereVerification>& sphere,
                                 const pipeline::SimulatedCornea& paper, const std::optional<DeviceStage>& device) {
  const auto& result = c.result;
  std::vector<std::string> lines;
  lines.push_back(fmt::format("{}: {} {} calibration, {} view(s), {} corners, rms {:.4f} px{}", r.serial,
                              calib::ToString(result.model), c.single_view ? "single-view" : "multi-view",
                              result.views_used.size(), result.corners_used, result.rms_px,
                              result.seidel ? fmt::format(", sigma {:.6g} +- {:.2g} mm^-2 (k=1)",
                                                          result.seidel->sigma_per_mm2,
                                                          result.seidel->sigma_stddev_per_mm2)
                                            : std::string()));
  lines.push_back(fmt::format("  distortion: up to {:.2f} um ({:.1f} px) over the spot field", field.max_um, field.max_px));
  if (sphere) {
    const auto& s = *sphere;
    lines.push_back(fmt::format(
        "  reference sphere R {} mm: radius error {:+.4f} -> {:+.4f} mm, central power error {:+.3f} -> {:+.3f} D",
        s.radius_true_mm, s.RadiusErrorMm(s.uncorrected), s.RadiusErrorMm(s.corrected), s.PowerErrorD(s.uncorrected),
        s.PowerErrorD(s.corrected)));
  }
  const auto u = [&](const char* q) {
    if (!paper.uncertainty || !paper.uncertainty->quantities.count(q)) return std::string();
    return fmt::format(" +- {:.2g}", paper.uncertainty->quantities.at(q).expanded_k2);
  };
  lines.push_back(fmt::format("  paper cornea (simulated): kx {:.4f} -> {:.4f}{}, ky {:.4f} -> {:.4f}{} (truth {}, {})",
                              paper.uncorrected.numbers.kx, paper.corrected.numbers.kx, u("kx"),
                              paper.uncorrected.numbers.ky, paper.corrected.numbers.ky, u("ky"), paper.truth.kx,
                              paper.truth.ky));
  if (device) {
    const auto& f = device->calibration.fit;
    lines.push_back(fmt::format("  device from {} balls: {}", device->calibration.detections.size(), f.message));
    for (const char* name : {"rx_deg", "ry_deg", "principal_point_u_px", "principal_point_v_px", "a_mm"}) {
      if (const auto p = f.Parameter(name)) {
        lines.push_back(fmt::format("    {:<22} {:>12.6g} +- {:.2g}", p->name, p->value, p->stddev));
      }
    }
    if (device->held_out) {
      const auto& h = *device->held_out;
      const auto err = [&](const pipeline::StageResult& st) { return st.numbers.radius_mm - h.radius_true_mm; };
      lines.push_back(fmt::format("  held-out ball R {} mm: radius error {:+.4f} (uncorrected), {:+.4f} (lens only), "
                                  "{:+.4f} mm (device)",
                                  h.radius_true_mm, err(h.stages.uncorrected), err(h.stages.lens_only),
                                  err(h.stages.device)));
    }
    const auto& pc = device->paper;
    lines.push_back(fmt::format("  paper cornea through the unit: kx {:.4f} (uncorrected), {:.4f} (lens only), {:.4f} "
                                "(device); truth {}",
                                pc.uncorrected.numbers.kx, pc.lens_only.numbers.kx, pc.device.numbers.kx, paper.truth.kx));
  }
  lines.push_back(fmt::format("  -> {}", r.out));
  return lines;
}

}  // namespace

bool IsValidSerial(const std::string& serial) {
  if (serial.empty() || serial.size() > kMaxSerialLength || serial.front() == '.') return false;
  return std::all_of(serial.begin(), serial.end(), [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == '-';
  });
}

UnitOutcome CalibrateUnit(const UnitRequest& r, const std::function<void(const std::string&)>& log) {
  const LoadedInputs in = LoadInputs(r);  // everything checked before any work or output
  const Calibration c = CalibrateViews(r, in, log);
  const std::string date = RecordDateUtc();
  const std::string cal_text = calib::CalibrationFileText(c.result, {r.target, c.view_paths, date});

  // The checks use the calibration as the record stores it: the exact model and its full covariance.
  pipeline::UnitCalibration unit;
  unit.camera = c.result.camera;
  unit.covariance.names.assign(std::begin(calib::kParameterNames), std::end(calib::kParameterNames));
  unit.covariance.matrix = c.result.covariance;
  unit.covariance.full = true;
  const pipeline::CheckOptions check{r.uncertainty_samples, r.seed, r.jobs};
  std::optional<pipeline::SphereVerification> sphere;
  if (!in.sphere_image.empty()) {
    try {
      sphere = pipeline::VerifyOnReferenceSphere(in.sphere_image, r.sphere_radius_mm, unit, in.camera, in.config, check);
    } catch (const std::invalid_argument& e) {
      throw model::InputError(fmt::format("{}: {}", r.reference_sphere, e.what()));
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(fmt::format("{}: {}: {}", r.serial, r.reference_sphere, e.what()));
    }
  }
  const auto paper = pipeline::SimulateThroughCalibratedCamera(unit, in.camera, in.config, check);
  const auto field = MeasureDistortionField(c.result.camera, in, r.serial);
  std::optional<DeviceStage> device;
  if (!in.balls.empty()) {
    std::string why;
    const auto lens = pipeline::DistortionOnDetectionPlane(c.result.camera, in.camera, &why);
    if (!lens) throw std::runtime_error(fmt::format("{}: the calibration cannot be put on the detection plane: {}", r.serial, why));
    device = CalibrateDeviceStage(r, in, *lens);
  }

  // The record, staged and committed whole.
  report::UnitRecordWriter writer(r.out);
  const fs::path& dir = writer.staging_dir();
  model::WriteFileAtomic((dir / "calibration.yaml").string(), cal_text);
  model::WriteFileAtomic((dir / "residuals.csv").string(), ResidualsCsv(c));
  WriteRecordMaps((dir / "maps").string(), sphere, paper, in.config);
  if (device) {
    model::WriteFileAtomic((dir / "device.json").string(),
                           model::DeviceToJson(device->calibration.fit.device, pipeline::DeviceCalibrationJson(device->calibration)));
  }

  json record;
  record["serial"] = r.serial;
  record["created_utc"] = date;
  record["settings"] = {{"model", r.model},
                        {"single_view", c.single_view},
                        {"fit_centre", r.fit_centre},
                        {"fixed", r.fixed},
                        {"sphere_radius_mm", r.sphere_radius_mm},
                        {"ball_radii_mm", r.ball_radii_mm},
                        {"uncertainty_samples", r.uncertainty_samples},
                        {"seed", r.seed}};
  record["inputs"] = in.provenance;
  // The design and camera as they were read (canonical form), so that the record says what it was computed with
  // even after the files change; the digests above say whether they still match.
  record["configuration"] = {{"design", json::parse(model::ConfigToJson(in.config))},
                             {"camera", json::parse(model::TopographerCameraToJson(in.camera))}};
  const auto& cam = in.camera;
  record["camera"] = model::CameraToJson(cam);
  record["calibration"] = CalibrationJson(c, field, cam);
  if (sphere) record["verification"] = VerificationJson(*sphere, r, check);
  record["paper_cornea"] = PaperCorneaJson(paper, check);
  if (device) record["device"] = DeviceJson(*device);
  try {
    report::RequireFiniteNumbers(record);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: the result is not usable: {}", r.serial, e.what()));
  }
  writer.Commit(std::move(record));  // adds format, versions and the files' digests
  return {r.serial, r.out, Summary(r, c, field, sphere, paper, device)};
}

UnitRequest ReadUnitInputs(const std::string& path, const UnitRequest& defaults) {
  const json j = model::ParseJsonStrict(model::ReadFile(path), path);
  model::JsonSection s(j, path, "");
  // Unknown keys first: a misspelt key is the likelier cause of whatever would fail next.
  for (const char* key : {"serial", "target", "images", "reference_sphere", "sphere_radius_mm", "model", "fit_centre",
                          "fix", "config", "camera", "uncertainty_samples", "seed"}) {
    s.MarkSeen(key);
  }
  s.RejectUnknown();
  const fs::path base = fs::path(path).parent_path();
  const auto relative = [&](const std::string& p) { return fs::path(p).is_absolute() ? p : (base / p).string(); };
  const auto str = [&](const char* key, bool required) -> std::optional<std::string> {
    if (!s.Has(key)) {
      if (required) s.Get(key);  // fails: missing
      return std::nullopt;
    }
    const std::string v = s.String(key);
    if (v.empty()) s.Fail(key, "expected a non-empty string");
    return v;
  };
  UnitRequest r = defaults;
  r.serial = *str("serial", true);
  r.target = relative(*str("target", true));
  r.images = Glob(relative(*str("images", true)), fmt::format("{}: images", path));
  if (const auto v = str("reference_sphere", false)) r.reference_sphere = relative(*v);
  if (s.Has("sphere_radius_mm")) r.sphere_radius_mm = s.PositiveNumber("sphere_radius_mm", 0);
  if (const auto v = str("model", false)) r.model = *v;
  if (const auto v = str("config", false)) r.config = relative(*v);
  if (const auto v = str("camera", false)) r.camera = relative(*v);
  if (s.Has("fit_centre")) {
    const json& v = s.Get("fit_centre");
    if (!v.is_boolean()) s.Fail("fit_centre", fmt::format("expected true or false (got {})", model::QuoteJsonValue(v)));
    r.fit_centre = v.get<bool>();
  }
  if (s.Has("fix")) {
    const json& v = s.Get("fix");
    const auto bad = [&] { s.Fail("fix", fmt::format("expected a list of parameter names (got {})", model::QuoteJsonValue(v))); };
    if (!v.is_array()) bad();
    r.fixed.clear();
    for (const auto& f : v) {
      if (!f.is_string()) bad();
      r.fixed.push_back(f.get<std::string>());
    }
  }
  // The same range as --uncertainty: 0 (none) or 2 to kMaxUncertaintySamples draws.
  r.uncertainty_samples = s.IntegerInRange("uncertainty_samples", r.uncertainty_samples, 0, kMaxUncertaintySamples);
  if (s.Has("seed")) {
    const json& v = s.Get("seed");
    if (!model::JsonIntegerWithin(v, 0, std::numeric_limits<std::uint32_t>::max())) {
      s.Fail("seed", fmt::format("expected an integer in [0, {}] (got {})", std::numeric_limits<std::uint32_t>::max(),
                                 model::QuoteJsonValue(v)));
    }
    r.seed = static_cast<unsigned>(v.get<unsigned long long>());
  }
  return r;
}

}  // namespace topocal::tools
