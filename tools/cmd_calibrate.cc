// topocal calibrate: detect a planar target in a set of images and fit the camera (calib/calibrate.h).
#include <fmt/format.h>
#include <glog/logging.h>

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "calib/calibrate.h"
#include "calib/calibration_file.h"
#include "calib/cross_validation.h"
#include "calib/detect.h"
#include "calib/parameter_range.h"
#include "calib/target.h"
#include "tools/commands.h"
#include "util/file_glob.h"
#include "util/io.h"
#include "util/parallel.h"

namespace topocal::tools {
namespace {

// Above this many images, each detection reports its progress on stderr.
constexpr size_t kProgressFromImages = 5;

struct CalibrateArgs {
  std::string target, images, model = "brown5", out, json, cross_validate_svg;
  bool single_view = false, robust = false, fit_centre = false, board_warp = false;
  double focal_mm = 0, pixel_pitch_um = 0, distance_mm = 0, magnification = calib::kPaperMagnification;
  double fix_aspect = 0;
  std::vector<std::string> fix;
  std::string loss = "huber";
  double loss_scale_px = 1.0, outlier_threshold = 4.0;
  int jobs = util::AvailableCores();
};

// The summary on standard output: the fit, every free parameter with its standard deviation, what is undetermined.
void PrintCalibration(const calib::CalibrationResult& result, const CalibrateArgs& a,
                      const std::optional<calib::CrossValidationResult>& cross) {
  const auto& c = result.camera;
  fmt::print("{} {} calibration from {} view(s), {} corners: rms {:.4f} px, {} outlier(s)\n", calib::ToString(result.model),
             result.single_view ? "single-view" : "multi-view", result.views_used.size(), result.corners_used,
             result.rms_px, result.outliers.size());
  fmt::print("  fx {:.4f} fy {:.4f} cx {:.4f} cy {:.4f} px\n", c.fx_px, c.fy_px, c.cx_px, c.cy_px);
  for (const auto& p : result.parameters) {
    if (!p.fixed) fmt::print("  {:>2} = {:<14.8g} +- {:.3g}\n", p.name, p.value, p.stddev);
  }
  if (const auto undetermined = calib::UndeterminedParameters(result); !undetermined.empty()) {
    fmt::print("  warning: undetermined: {}\n", calib::UndeterminedMessage(undetermined));
  }
  if (result.fixed_aspect_ratio > 0) fmt::print("  fx / fy held at {} (one focal degree of freedom)\n", result.fixed_aspect_ratio);
  if (result.seidel) {
    fmt::print("  Seidel sigma = {:.6g} +- {:.2g} mm^-2 (M_T = {}, f = {:.4g} mm)\n", result.seidel->sigma_per_mm2,
               result.seidel->sigma_stddev_per_mm2, result.seidel->magnification, result.seidel->focal_mm);
  }
  if (result.board_warp) {
    const auto& w = *result.board_warp;
    fmt::print("  board warp: sag_x = {:.4f} +- {:.4f} mm, sag_y = {:.4f} +- {:.4f} mm (middle of the board vs its "
               "edges, + = away from the camera)\n",
               w.sag_x_mm, w.sag_x_stddev_mm, w.sag_y_mm, w.sag_y_stddev_mm);
  }
  fmt::print("  -> {}\n", a.out);
  if (cross) {
    fmt::print("cross-validation: halves of {} and {} views differ by RMS {:.4f} px, max {:.4f} px over the image "
               "(homography removed) -> {}\n",
               cross->half_views[0].size(), cross->half_views[1].size(), cross->rms_px, cross->max_px,
               a.cross_validate_svg);
  }
}

// The fit's options from the arguments, checked against each other.
calib::CalibrationOptions OptionsOf(const CalibrateArgs& a) {
  const auto model = calib::ParseDistortionModel(a.model);
  if (!model) throw util::InputError(fmt::format("--model: '{}' is not seidel or brown5", a.model));
  calib::CalibrationOptions options;
  options.model = *model;
  options.fixed = {a.fix.begin(), a.fix.end()};
  options.fit_distortion_centre = a.fit_centre;
  options.fixed_aspect_ratio = a.fix_aspect;
  options.fit_board_warp = a.board_warp;
  options.focal_mm = a.focal_mm;
  options.pixel_pitch_um = a.pixel_pitch_um;
  options.distance_mm = a.distance_mm;
  options.magnification = a.magnification;
  if (a.robust) {
    const auto loss = calib::ParseRobustLoss(a.loss);
    if (!loss || *loss == calib::RobustLoss::kNone)
      throw util::InputError(fmt::format("--loss: '{}' is not huber or cauchy", a.loss));
    options.loss = *loss;
    options.loss_scale_px = a.loss_scale_px;
    options.reject_outliers = true;
    options.outlier_threshold = a.outlier_threshold;
  }
  if (a.single_view && !(a.focal_mm > 0 && a.pixel_pitch_um > 0 && a.distance_mm > 0)) {
    throw util::InputError("--single-view needs --focal-mm, --pixel-pitch-um and --distance-mm (all > 0)");
  }
  if (a.single_view && a.fix_aspect > 0) {
    throw util::InputError("--fix-aspect applies to multi-view fits; --single-view already holds fx = fy");
  }
  if (a.single_view && a.board_warp) {
    throw util::InputError("--board-warp needs several views; it does not apply to --single-view");
  }
  if (a.single_view && !a.cross_validate_svg.empty()) {
    throw util::InputError("--cross-validate needs several views; it does not apply to --single-view");
  }
  std::string why;
  if (!options.IsValid(&why)) throw util::InputError(why);
  return options;
}

// The views in which the target was found, with their images' paths.
struct DetectedViews {
  std::vector<calib::ViewObservations> views;
  std::vector<std::string> view_paths;
};

DetectedViews DetectViews(const calib::TargetDescription& target, const std::vector<std::string>& paths, int jobs) {
  calib::FileSetOptions detect;
  detect.jobs = jobs;
  if (paths.size() > kProgressFromImages) {
    detect.on_done = [&, done = size_t{0}](size_t, const calib::FileDetection& f) mutable {
      fmt::print(stderr, "topocal calibrate: [{}/{}] {}: {}\n", ++done, paths.size(), f.path,
                 f.skipped.empty() ? f.detection.message : f.skipped);
    };
  }
  DetectedViews d;
  for (auto& f : calib::DetectTargetInFiles(target, paths, detect)) {
    if (!f.skipped.empty()) {
      fmt::print(stderr, "topocal calibrate: skipping {}: {}\n", f.path, f.skipped);
      continue;
    }
    for (const auto& reason : f.detection.reasons) fmt::print(stderr, "topocal calibrate: {}: {}\n", f.path, reason);
    if (!f.detection.view) {
      fmt::print(stderr, "topocal calibrate: skipping {}: no target found{}\n", f.path,
                 f.detection.message.empty() ? "" : ": " + f.detection.message);
      continue;
    }
    d.views.push_back(std::move(*f.detection.view));
    d.view_paths.push_back(f.path);
  }
  return d;
}

// The fit, single- or multi-view; the views it left out and the outliers it rejected are reported on stderr.
calib::CalibrationResult Calibrate(const DetectedViews& d, const std::vector<std::string>& paths, const CalibrateArgs& a,
                                   const calib::CalibrationOptions& options) {
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
    fmt::print(stderr, "topocal calibrate: not used {}: {}\n", d.view_paths[static_cast<size_t>(s.view)], s.reason);
  }
  if (!result.ok()) {
    throw std::runtime_error(fmt::format("calibration failed ({}): {}", calib::ToString(result.status), result.message));
  }
  for (const auto& o : result.outliers) {
    fmt::print(stderr, "topocal calibrate: outlier {} corner {}: residual {:.3f} px\n",
               d.view_paths[static_cast<size_t>(o.view)], o.corner_id, o.residual_px.norm());
  }
  return result;
}

void Run(const CalibrateArgs& a) {
  // Ceres logs through glog (e.g. a rank-deficient covariance); the calibration's status already says it in one
  // line, so keep glog's lines off the terminal.
  FLAGS_minloglevel = google::GLOG_FATAL;
  const calib::CalibrationOptions options = OptionsOf(a);

  const auto target = calib::LoadTargetDescription(a.target);
  const auto paths = util::Glob(a.images);
  if (a.single_view && paths.size() != 1) {
    throw util::InputError(fmt::format("--single-view takes one image; '{}' matches {}", a.images, paths.size()));
  }
  const DetectedViews d = DetectViews(target, paths, a.jobs);
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
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out, cal_text);
  if (!a.json.empty()) outputs.AddFile(a.json, json_text);
  if (cross) outputs.AddFile(a.cross_validate_svg, cross_svg);
  outputs.Commit();
  PrintCalibration(result, a, cross);
}

}  // namespace

void AddCalibrateCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("calibrate", "Fit the camera's intrinsics and distortion to images of a target");
  auto a = std::make_shared<CalibrateArgs>();
  cmd->add_option("--target", a->target, "Target description (Kalibr-style YAML)")->required();
  cmd->add_option("--images", a->images, "Images, a glob(3) pattern (quote it)")->required();
  cmd->add_option("--model", a->model, "Distortion model: seidel (k1 [+ centre]) or brown5 (k1,k2,p1,p2,k3)");
  cmd->add_flag("--single-view", a->single_view,
                "One image of the target at the cornea position; needs --focal-mm, --pixel-pitch-um, --distance-mm");
  cmd->add_option("--focal-mm", a->focal_mm, "Lens focal distance, mm (single view; Seidel sigma)");
  cmd->add_option("--pixel-pitch-um", a->pixel_pitch_um, "Pixel pitch, um (single view; Seidel sigma)");
  cmd->add_option("--distance-mm", a->distance_mm, "Nominal target distance from the pinhole, mm (single view)");
  cmd->add_option("--magnification", a->magnification, "Transverse magnification M_T for the Seidel sigma")
      ->capture_default_str();
  cmd->add_option("--fix", a->fix, "Parameters to hold fixed (spaces or commas): fx fy cx cy k1 k2 p1 p2 k3 ex ey")
      ->delimiter(',');
  cmd->add_option("--fix-aspect", a->fix_aspect,
                  "Hold fx / fy at this ratio during a multi-view fit (e.g. 1 for square pixels; 0 = free); OpenCV's "
                  "CALIB_FIX_ASPECT_RATIO")
      ->capture_default_str();
  cmd->add_flag("--fit-centre", a->fit_centre, "Fit the radial distortion centre (Seidel; brown5 needs --fix p1,p2)");
  cmd->add_flag("--robust", a->robust, "Robust loss and iterative outlier rejection");
  cmd->add_flag("--board-warp", a->board_warp,
                "Fit the target's parabolic sag with the camera (a printed board that is not flat; multi-view)");
  cmd->add_option("--loss", a->loss, "Robust loss with --robust: huber or cauchy")->capture_default_str();
  cmd->add_option("--loss-scale-px", a->loss_scale_px, "Robust loss scale, px")->capture_default_str();
  cmd->add_option("--outlier-threshold", a->outlier_threshold, "Reject corners beyond this many robust sigmas")
      ->capture_default_str();
  cmd->add_option("--jobs", a->jobs, "Images detected at once (default: the cores available); the result does not depend on it")
      ->capture_default_str()
      ->check(CLI::Range(1, 1024));
  cmd->add_option("--out", a->out, "Calibration file (OpenCV FileStorage YAML)")->required();
  cmd->add_option("--json", a->json, "Also write a JSON report");
  cmd->add_option("--cross-validate", a->cross_validate_svg,
                  "Also fit two interleaved halves of the views and compare them over the image (homography "
                  "removed): the difference as a number, and its map as an SVG to this file");
  cmd->callback([a] { Run(*a); });
}

}  // namespace topocal::tools
