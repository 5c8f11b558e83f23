#include "pipeline/device_command.h"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <stdexcept>

#include "calib/detect.h"
#include "calib/target.h"
#include "imageio/image_file.h"
#include "model/config.h"
#include "model/device.h"
#include "pipeline/device_calibration.h"
#include "util/file_glob.h"
#include "util/io.h"
#include "util/sha256.h"
#include "util/verdict.h"
#include "util/version.h"

namespace topocal::pipeline {
namespace {

// The checks that need no file: one radius per ball, each a reference ball's, the datum one of the balls.
void RequireConsistent(const DeviceCalibrateRequest& a) {
  if (a.balls.empty()) throw util::InputError("--balls: at least one reference-ball image is needed");
  if (a.ball_radii_mm.size() != a.balls.size()) {
    throw util::InputError(
        fmt::format("--radii-mm: {} radii for {} ball images (one certified radius per image, in "
                    "the same order)",
                    a.ball_radii_mm.size(), a.balls.size()));
  }
  for (size_t i = 0; i < a.ball_radii_mm.size(); ++i) {
    // Checked before any image is read (CalibrateDevice checks it too).
    if (!(a.ball_radii_mm[i] >= kMinBallRadiusMm && a.ball_radii_mm[i] <= kMaxBallRadiusMm)) {
      throw util::InputError(fmt::format("--radii-mm: {} for {} is not a reference-ball radius ({}-{} mm)",
                                         a.ball_radii_mm[i], a.balls[i], kMinBallRadiusMm, kMaxBallRadiusMm));
    }
  }
  if (!a.options.ball_steps_mm.empty() && a.options.ball_steps_mm.size() != a.balls.size()) {
    throw util::InputError(fmt::format("--ball-steps-mm: {} steps for {} ball images (one per ball, in their order)",
                                       a.options.ball_steps_mm.size(), a.balls.size()));
  }
  if (a.target.empty() != a.targets.empty()) {
    throw util::InputError("--target and --targets go together: the target description and its views");
  }
  if (a.datum_ball_number < 1 || a.datum_ball_number > static_cast<int>(a.balls.size())) {
    throw util::InputError(
        fmt::format("--datum: must name one of the {} balls (1..{})", a.balls.size(), a.balls.size()));
  }
}

// The device file's report: the fit's, with the tool and the digests of every input.
nlohmann::json ReportOf(const DeviceCalibration& result, const DeviceCalibrateRequest& a,
                        const calib::DeviceFitOptions& options) {
  auto report = DeviceCalibrationJson(result);
  report["tool"] = fmt::format("topocal {}", kVersion);
  report["inputs"] = {
      {"configuration", {{"path", a.config}, {"sha256", util::Sha256HexOfFile(a.config)}}},
      {"nominal_device", {{"path", a.nominal_device}, {"sha256", util::Sha256HexOfFile(a.nominal_device)}}}};
  for (size_t i = 0; i < a.balls.size(); ++i) {
    report["balls"][i]["sha256"] = util::Sha256HexOfFile(a.balls[i]);
  }
  for (size_t i = 0; i < result.view_names.size(); ++i) {
    report["target_views"][i]["sha256"] = util::Sha256HexOfFile(result.view_names[i]);
  }
  if (!a.target.empty()) report["inputs"]["target"] = {{"path", a.target}, {"sha256", util::Sha256HexOfFile(a.target)}};
  if (!result.view_names.empty()) report["corner_sigma_px"] = options.corner_sigma_px;
  report["spot_sigma_px"] = options.spot_sigma_px;
  return report;
}

void PrintFit(std::ostream& out, const DeviceCalibration& result, const std::string& out_path) {
  const auto& fit = result.fit;
  fmt::print(out, "device calibration: {}\n", fit.message);
  for (size_t b = 0; b < result.detections.size(); ++b) {
    const auto& d = result.detections[b];
    const auto& v = fit.ball_vertex_mm[b];
    fmt::print(out, "  {} (R {} mm): {} spots, rms {:.4f} px, vertex ({:+.4f}, {:+.4f}, {:+.4f}) mm\n", d.view.name,
               d.view.radius_mm, d.view.spots_px.size(), fit.ball_rms_px[b], v.x(), v.y(), v.z());
  }
  for (size_t v = 0; v < result.view_names.size(); ++v) {
    fmt::print(out, "  {} (target): {} corners, rms {:.4f} px\n", result.view_names[v], fit.view_corners[v],
               fit.view_rms_px[v]);
  }
  for (const auto& p : fit.parameters) {
    fmt::print(out, "  {:<22} {:>14.7g} +- {:<10.3g} (nominal {:.7g})\n", p.name, p.value, p.stddev, p.nominal);
  }
  fmt::print(out, "  gauge: {}\n", fit.gauge);
  for (const auto& n : fit.notes) fmt::print(out, "  note: {}\n", n);
  fmt::print(out, "-> {}\n", out_path);
}

// The target views' corners, every view named by --targets required: a view without the target is bad input here
// (the user chose it for this unit), not a view to skip.
std::vector<calib::ViewObservations> DetectTargetViews(const DeviceCalibrateRequest& a) {
  if (a.targets.empty()) return {};
  const auto target = calib::LoadTargetDescription(a.target);
  std::vector<calib::ViewObservations> views;
  for (auto& f : calib::DetectTargetInFiles(target, util::Glob(a.targets, "--targets"), {})) {
    if (!f.skipped.empty()) throw util::InputError(fmt::format("{}: {}", f.path, f.skipped));
    if (!f.detection.view) {
      throw util::InputError(fmt::format("{}: no target found (target description {}){}", f.path, a.target,
                                         f.detection.message.empty() ? "" : ": " + f.detection.message));
    }
    views.push_back(std::move(*f.detection.view));
  }
  return views;
}

}  // namespace

void RunDeviceCalibrate(const DeviceCalibrateRequest& a, std::ostream& out) {
  RequireConsistent(a);
  calib::DeviceFitOptions options = a.options;
  options.datum_ball = a.datum_ball_number - 1;
  std::string why;
  if (!options.IsValid(&why)) throw util::InputError(why);
  const auto cfg = model::LoadConfig(a.config);
  const auto nominal = model::LoadDevice(a.nominal_device);
  const auto target_views = DetectTargetViews(a);
  std::vector<BallImage> images;
  for (size_t i = 0; i < a.balls.size(); ++i) {
    BallImage b{a.balls[i], imageio::ReadImage(a.balls[i], imageio::Channels::kAsStored), a.ball_radii_mm[i]};
    const auto& cam = nominal.device.camera;
    imageio::RequireSize(b.image, a.balls[i], cam.width_px, cam.height_px, a.nominal_device);
    images.push_back(std::move(b));
  }
  // An image the spot detector cannot use is bad input (util::InputError, exit 2).
  const DeviceCalibration result = CalibrateDevice(images, nominal.device, cfg, options, target_views);
  const auto& fit = result.fit;
  if (!fit.ok) throw std::runtime_error(fmt::format("device calibration failed: {}", fit.message));
  util::WriteFileAtomic(a.out, model::DeviceToJson(fit.device, ReportOf(result, a, options)));
  if (!a.quiet) PrintFit(out, result, a.out);
  if (!fit.model_adequate) {
    throw util::VerdictFailed(fmt::format("{}: chi2/dof = {:.3g} > {}: the device model does not describe these "
                                          "images (the device file is written, flagged model_adequate = false)",
                                          a.out, fit.chi2_per_dof, options.max_chi2_per_dof));
  }
}

}  // namespace topocal::pipeline
