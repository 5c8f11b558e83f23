// topocal device calibrate: the whole device (screen pose, principal point, a, distortion) from reference-ball images.
#include <fmt/format.h>

#include <memory>

#include "imageio/image_file.h"
#include "model/config.h"
#include "model/device.h"
#include "pipeline/device_calibration.h"
#include "tools/commands.h"
#include "util/io.h"
#include "util/sha256.h"
#include "util/version.h"

namespace topocal::tools {
namespace {

struct DeviceArgs {
  std::string config, device, out;
  std::vector<std::string> balls;
  std::vector<double> radii_mm;
  calib::DeviceFitOptions options;
  int datum = 1;
  bool quiet = false;
};

void Calibrate(DeviceArgs a) {
  if (a.balls.empty()) throw util::InputError("--balls: at least one reference-ball image is needed");
  if (a.radii_mm.size() != a.balls.size()) {
    throw util::InputError(
        fmt::format("--radii-mm: {} radii for {} ball images (one certified radius per image, in "
                    "the same order)",
                    a.radii_mm.size(), a.balls.size()));
  }
  for (size_t i = 0; i < a.radii_mm.size(); ++i) {
    // Checked before any image is read (pipeline::CalibrateDevice checks it too).
    if (!(a.radii_mm[i] >= pipeline::kMinBallRadiusMm && a.radii_mm[i] <= pipeline::kMaxBallRadiusMm)) {
      throw util::InputError(fmt::format("--radii-mm: {} for {} is not a reference-ball radius ({}-{} mm)",
                                         a.radii_mm[i], a.balls[i], pipeline::kMinBallRadiusMm,
                                         pipeline::kMaxBallRadiusMm));
    }
  }
  if (a.datum < 1 || a.datum > static_cast<int>(a.balls.size())) {
    throw util::InputError(
        fmt::format("--datum: must name one of the {} balls (1..{})", a.balls.size(), a.balls.size()));
  }
  a.options.datum_ball = a.datum - 1;
  std::string why;
  if (!a.options.IsValid(&why)) throw util::InputError(why);
  const auto cfg = model::LoadConfig(a.config);
  const auto nominal = model::LoadDevice(a.device);
  std::vector<pipeline::BallImage> images;
  for (size_t i = 0; i < a.balls.size(); ++i) {
    pipeline::BallImage b{a.balls[i], imageio::ReadImage(a.balls[i], imageio::Channels::kAsStored), a.radii_mm[i]};
    const auto& cam = nominal.device.camera;
    imageio::RequireSize(b.image, a.balls[i], cam.width_px, cam.height_px, a.device);
    images.push_back(std::move(b));
  }
  pipeline::DeviceCalibration result;
  try {
    result = pipeline::CalibrateDevice(images, nominal.device, cfg, a.options);
  } catch (const std::invalid_argument& e) {
    throw util::InputError(e.what());
  }
  const auto& fit = result.fit;
  if (!fit.ok) throw std::runtime_error(fmt::format("device calibration failed: {}", fit.message));
  auto report = pipeline::DeviceCalibrationJson(result);
  report["tool"] = fmt::format("topocal {}", kVersion);
  report["inputs"] = {{"configuration", {{"path", a.config}, {"sha256", util::Sha256HexOfFile(a.config)}}},
                      {"nominal_device", {{"path", a.device}, {"sha256", util::Sha256HexOfFile(a.device)}}}};
  for (size_t i = 0; i < a.balls.size(); ++i) {
    report["balls"][i]["sha256"] = util::Sha256HexOfFile(a.balls[i]);
  }
  report["spot_sigma_px"] = a.options.spot_sigma_px;
  util::WriteFileAtomic(a.out, model::DeviceToJson(fit.device, report));

  if (!a.quiet) {
    fmt::print("device calibration: {}\n", fit.message);
    for (size_t b = 0; b < result.detections.size(); ++b) {
      const auto& d = result.detections[b];
      const auto& v = fit.ball_vertex_mm[b];
      fmt::print("  {} (R {} mm): {} spots, rms {:.4f} px, vertex ({:+.4f}, {:+.4f}, {:+.4f}) mm\n", d.view.name,
                 d.view.radius_mm, d.view.spots_px.size(), fit.ball_rms_px[b], v.x(), v.y(), v.z());
    }
    for (const auto& p : fit.parameters) {
      fmt::print("  {:<22} {:>14.7g} +- {:<10.3g} (nominal {:.7g})\n", p.name, p.value, p.stddev, p.nominal);
    }
    fmt::print("  gauge: {}\n", fit.gauge);
    for (const auto& n : fit.notes) fmt::print("  note: {}\n", n);
    fmt::print("-> {}\n", a.out);
  }
  if (!fit.model_adequate) {
    throw VerdictFailed(fmt::format("{}: chi2/dof = {:.3g} > {}: the device model does not describe these images "
                                    "(the device file is written, flagged model_adequate = false)",
                                    a.out, fit.chi2_per_dof, a.options.max_chi2_per_dof));
  }
}

}  // namespace

void AddDeviceCommand(CLI::App& app) {
  auto* device = app.add_subcommand("device", "Calibrate the whole device (screen pose, camera, distortion)");
  device->require_subcommand(1);
  auto* cmd = device->add_subcommand(
      "calibrate",
      "Fit the null screen's pose, the principal point, a and the distortion from reference-ball images");
  auto a = std::make_shared<DeviceArgs>();
  cmd->add_option("--config", a->config, "Topographer design (JSON)")->required();
  cmd->add_option("--device", a->device, "Nominal device file (JSON, docs/device.md): the starting point and priors' centre")
      ->required();
  cmd->add_option("--balls", a->balls, "Raw images of the reference balls (space separated)")->required();
  cmd->add_option("--radii-mm", a->radii_mm, "Certified radius of each ball, in the order of --balls, mm")->required();
  cmd->add_option("--out", a->out, "Calibrated device file (JSON)")->required();
  cmd->add_option("--datum", a->datum, "The ball whose vertex defines z = 0 (the axial gauge), 1-based")
      ->capture_default_str();
  cmd->add_option("--spot-sigma-px", a->options.spot_sigma_px, "Noise of one spot centre per axis, px")
      ->capture_default_str();
  cmd->add_option("--tol-tilt-deg", a->options.priors.tilt_deg, "Prior: screen tilt tolerance (1 sigma), deg")
      ->capture_default_str();
  cmd->add_option("--tol-roll-deg", a->options.priors.roll_deg, "Prior: screen roll tolerance, deg")->capture_default_str();
  cmd->add_option("--tol-lateral-mm", a->options.priors.lateral_mm, "Prior: screen decentration tolerance, mm")
      ->capture_default_str();
  cmd->add_option("--tol-axial-mm", a->options.priors.axial_mm, "Prior: screen axial position tolerance, mm")
      ->capture_default_str();
  cmd->add_option("--tol-principal-point-mm", a->options.priors.principal_point_mm,
                  "Prior: principal point tolerance on the sensor, mm")
      ->capture_default_str();
  cmd->add_option("--tol-a-relative", a->options.priors.a_relative, "Prior: relative tolerance of a")
      ->capture_default_str();
  cmd->add_flag("--fit-radial-scale", a->options.fit_radial_scale,
                "Also fit the screen's radial scale (cone-angle or print-scale error)");
  cmd->add_option("--max-chi2-per-dof", a->options.max_chi2_per_dof,
                  "Above this chi2/dof the model is flagged as not describing the images (exit 3)")
      ->capture_default_str();
  cmd->add_flag("--quiet", a->quiet, "Print nothing but errors");
  cmd->callback([a] { Calibrate(*a); });
}

}  // namespace topocal::tools
