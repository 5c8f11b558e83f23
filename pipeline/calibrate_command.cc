#include "pipeline/calibrate_command.h"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "calib/calibration_file.h"
#include "calib/cross_validation.h"
#include "calib/detect.h"
#include "calib/parameter_range.h"
#include "calib/target.h"
#include "model/device.h"
#include "pipeline/lens_device.h"
#include "util/file_glob.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

// Above this many images, each detection reports its progress.
constexpr size_t kProgressFromImages = 5;

// The summary: the fit, every free parameter with its standard deviation, what is undetermined.
void PrintCalibration(std::ostream& out, const calib::CalibrationResult& result, const CalibrateRequest& a,
                      const std::optional<calib::CrossValidationResult>& cross) {
  const auto& c = result.camera;
  fmt::print(out, "{} {} calibration from {} view(s), {} corners: rms {:.4f} px, {} outlier(s)\n",
             calib::ToString(result.model), result.single_view ? "single-view" : "multi-view",
             result.views_used.size(), result.corners_used, result.rms_px, result.outliers.size());
  fmt::print(out, "  fx {:.4f} fy {:.4f} cx {:.4f} cy {:.4f} px\n", c.fx_px, c.fy_px, c.cx_px, c.cy_px);
  for (const auto& p : result.parameters) {
    if (!p.fixed) fmt::print(out, "  {:>2} = {:<14.8g} +- {:.3g}\n", p.name, p.value, p.stddev);
  }
  if (const auto undetermined = calib::UndeterminedParameters(result); !undetermined.empty()) {
    fmt::print(out, "  warning: undetermined: {}\n", calib::UndeterminedMessage(undetermined));
  }
  if (result.fixed_aspect_ratio > 0) {
    fmt::print(out, "  fx / fy held at {} (one focal degree of freedom)\n", result.fixed_aspect_ratio);
  }
  if (result.seidel) {
    fmt::print(out, "  Seidel sigma = {:.6g} +- {:.2g} mm^-2 (M_T = {}, f = {:.4g} mm)\n", result.seidel->sigma_per_mm2,
               result.seidel->sigma_stddev_per_mm2, result.seidel->magnification, result.seidel->focal_mm);
  }
  if (result.board_warp) {
    const auto& w = *result.board_warp;
    fmt::print(out, "  board warp: sag_x = {:.4f} +- {:.4f} mm, sag_y = {:.4f} +- {:.4f} mm (middle of the board vs its "
               "edges, + = away from the camera)\n",
               w.sag_x_mm, w.sag_x_stddev_mm, w.sag_y_mm, w.sag_y_stddev_mm);
  }
  fmt::print(out, "  -> {}\n", a.out);
  if (!a.device_out.empty()) fmt::print(out, "  -> {} (the lens calibration applied to {})\n", a.device_out, a.device);
  if (cross) {
    fmt::print(out, "cross-validation: halves of {} and {} views differ by RMS {:.4f} px, max {:.4f} px over the image "
               "(homography removed) -> {}\n",
               cross->half_views[0].size(), cross->half_views[1].size(), cross->rms_px, cross->max_px,
               a.cross_validate_svg);
  }
}

// Options the fit does not check itself: which of them go together.
void RequireCompatible(const CalibrateRequest& a) {
  if (a.single_view && !(a.focal_mm > 0 && a.pixel_pitch_um > 0 && a.distance_mm > 0)) {
    throw util::InputError("--single-view needs --focal-mm, --pixel-pitch-um and --distance-mm (all > 0)");
  }
  if (a.single_view && a.fixed_aspect_ratio > 0) {
    throw util::InputError("--fix-aspect applies to multi-view fits; --single-view already holds fx = fy");
  }
  if (a.single_view && a.board_warp) {
    throw util::InputError("--board-warp needs several views; it does not apply to --single-view");
  }
  if (a.single_view && !a.cross_validate_svg.empty()) {
    throw util::InputError("--cross-validate needs several views; it does not apply to --single-view");
  }
}

// The fit's options from the request, checked against each other.
calib::CalibrationOptions OptionsOf(const CalibrateRequest& a) {
  const auto model = calib::ParseDistortionModel(a.model);
  if (!model) {
    throw util::InputError(fmt::format("--model: '{}' is not one of {}", a.model, calib::DistortionModelNames()));
  }
  calib::CalibrationOptions options;
  options.model = *model;
  options.fixed = {a.fixed.begin(), a.fixed.end()};
  options.fit_distortion_centre = a.fit_centre;
  options.fixed_aspect_ratio = a.fixed_aspect_ratio;
  options.fit_board_warp = a.board_warp;
  options.focal_mm = a.focal_mm;
  options.pixel_pitch_um = a.pixel_pitch_um;
  options.distance_mm = a.distance_mm;
  options.magnification = a.magnification;
  if (a.robust) {
    const auto loss = calib::ParseRobustLoss(a.loss);
    if (!loss || *loss == calib::RobustLoss::kNone) {
      throw util::InputError(fmt::format("--loss: '{}' is not huber or cauchy", a.loss));
    }
    options.loss = *loss;
    options.loss_scale_px = a.loss_scale_px;
    options.reject_outliers = true;
    options.outlier_threshold = a.outlier_threshold_sigmas;
  }
  RequireCompatible(a);
  std::string why;
  if (!options.IsValid(&why)) throw util::InputError(why);
  return options;
}

// The views in which the target was found, with their images' paths.
struct DetectedViews {
  std::vector<calib::ViewObservations> views;
  std::vector<std::string> view_paths;
};

DetectedViews DetectViews(const calib::TargetDescription& target, const std::vector<std::string>& paths,
                          const CalibrateRequest& a) {
  calib::FileSetOptions detect;
  detect.jobs = a.jobs;
  if (paths.size() > kProgressFromImages && a.log) {
    detect.on_done = [&, done = size_t{0}](size_t, const calib::FileDetection& f) mutable {
      a.log(fmt::format("[{}/{}] {}: {}", ++done, paths.size(), f.path,
                        f.skipped.empty() ? f.detection.message : f.skipped));
    };
  }
  DetectedViews d;
  for (auto& f : calib::DetectTargetInFiles(target, paths, detect)) {
    if (!f.skipped.empty()) {
      util::Log(a.log, fmt::format("skipping {}: {}", f.path, f.skipped));
      continue;
    }
    for (const auto& reason : f.detection.reasons) util::Log(a.log, fmt::format("{}: {}", f.path, reason));
    if (!f.detection.view) {
      util::Log(a.log, fmt::format("skipping {}: no target found{}", f.path,
                                   f.detection.message.empty() ? "" : ": " + f.detection.message));
      continue;
    }
    d.views.push_back(std::move(*f.detection.view));
    d.view_paths.push_back(f.path);
  }
  return d;
}

// The fit, single- or multi-view; the views it left out and the outliers it rejected are logged.
calib::CalibrationResult Calibrate(const DetectedViews& d, const std::vector<std::string>& paths,
                                   const CalibrateRequest& a, const calib::CalibrationOptions& options) {
  calib::CalibrationResult result;
  if (a.single_view) {
    if (d.views.empty()) {
      throw std::runtime_error(
          fmt::format("{}: no target found, nothing to calibrate (target description {})", paths[0], a.target));
    }
    result = calib::CalibrateSingleView(d.views[0], options);
  } else {
    result = calib::CalibrateMultiView(d.views, options);
  }
  for (const auto& s : result.skipped_views) {
    util::Log(a.log, fmt::format("not used {}: {}", d.view_paths[static_cast<size_t>(s.view)], s.reason));
  }
  if (!result.ok()) {
    throw std::runtime_error(fmt::format("calibration failed ({}): {}", calib::ToString(result.status), result.message));
  }
  for (const auto& o : result.outliers) {
    util::Log(a.log, fmt::format("outlier {} corner {}: residual {:.3f} px", d.view_paths[static_cast<size_t>(o.view)],
                                 o.corner_id, o.residual_px.norm()));
  }
  return result;
}

}  // namespace

void RunCalibrate(const CalibrateRequest& a, std::ostream& out) {
  const calib::CalibrationOptions options = OptionsOf(a);
  if (a.device.empty() != a.device_out.empty()) {
    throw util::InputError("--device and --device-out go together: the nominal device the lens calibration is "
                           "applied to, and the device file to write");
  }
  const std::optional<model::Device> nominal =
      a.device.empty() ? std::nullopt : std::optional<model::Device>(model::LoadDevice(a.device).device);
  const auto target = calib::LoadTargetDescription(a.target);
  const auto paths = util::Glob(a.images);
  if (a.single_view && paths.size() != 1) {
    throw util::InputError(fmt::format("--single-view takes one image; '{}' matches {}", a.images, paths.size()));
  }
  const DetectedViews d = DetectViews(target, paths, a);
  const calib::CalibrationResult result = Calibrate(d, paths, a, options);
  std::optional<calib::CrossValidationResult> cross;
  std::string cross_svg;
  if (!a.cross_validate_svg.empty()) {
    // Only the views the full calibration used (an unusable view would fail a half for no reason of its own).
    std::vector<calib::ViewObservations> used;
    for (const int v : result.views_used) used.push_back(d.views[static_cast<size_t>(v)]);
    cross = calib::CrossValidate(used, options);
    if (!cross->ok) throw std::runtime_error(cross->message);
    cross_svg = calib::CrossValidationSvg(*cross, result.camera.height_px);
  }
  const calib::CalibrationProvenance provenance{a.target, d.view_paths, {}};
  // All texts are complete before any file is written, so a failure leaves none behind.
  const std::string cal_text = calib::CalibrationFileText(result, provenance);
  const std::string json_text = a.json.empty() ? std::string() : calib::CalibrationReportJson(result, provenance);
  std::string device_text;
  if (nominal) {
    const model::DeviceFile device = LensCalibratedDevice(result, *nominal, a.out);
    device_text = model::DeviceToJson(device.device, device.calibration);
  }
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out, cal_text);
  if (!a.json.empty()) outputs.AddFile(a.json, json_text);
  if (cross) outputs.AddFile(a.cross_validate_svg, cross_svg);
  if (nominal) outputs.AddFile(a.device_out, device_text);
  outputs.Commit();
  PrintCalibration(out, result, a, cross);
}

}  // namespace topocal::pipeline
