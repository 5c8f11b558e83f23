#include "pipeline/render_spots_command.h"

#include <fmt/format.h>

#include <Eigen/SVD>
#include <algorithm>
#include <stdexcept>
#include <string_view>
#include <utility>

#include "correct/spot_render.h"
#include "correct/spot_truth.h"
#include "imageio/image_file.h"
#include "model/device.h"
#include "util/io.h"
#include "pipeline/simulation_surface.h"

namespace topocal::pipeline {
namespace {

void RequirePng(const std::string& path, const char* option) {
  if (path.size() < 4 || path.substr(path.size() - 4) != ".png") {
    throw util::InputError(fmt::format("{}: {}: the output must be a .png file", option, path));
  }
}

// The request's numbers that need no file, checked before any is read.
void Validate(const RenderSpotsRequest& a) {
  RequirePng(a.out_path, "--out");
  if (a.sigma_per_mm2 && !std::isfinite(*a.sigma_per_mm2)) throw util::InputError("--sigma: must be a finite number");
  if (!(a.drop_fraction >= 0 && a.drop_fraction < 1)) {
    throw util::InputError(fmt::format("--drop: must be in [0, 1) (got {})", a.drop_fraction));
  }
  for (const auto& [name, v] :
       {std::pair{"--upper-lid", a.upper_lid_fraction}, std::pair{"--lower-lid", a.lower_lid_fraction}}) {
    if (!(v >= 0 && v < 1)) throw util::InputError(fmt::format("{}: must be in [0, 1) (got {})", name, v));
  }
  if (a.glints < 0) throw util::InputError(fmt::format("--glints: must be >= 0 (got {})", a.glints));
  if (a.device_path.empty()) throw util::InputError("render-spots: give --device");
}

// The device, with the configuration's Seidel distortion at sigma in place of its own when --sigma is given (the
// configuration's Seidel model assumes its a, which the device must then have).
model::Device DeviceOf(const RenderSpotsRequest& a, const model::Config& cfg) {
  model::Device device = model::LoadDevice(a.device_path).device;
  if (!a.sigma_per_mm2) return device;
  if (std::abs(device.camera.a_mm - cfg.topographer.a_mm) > 1e-9) {
    throw util::InputError(fmt::format("{}: a_mm: {} differs from the configuration's topographer.a_mm = {} ({})",
                                       a.device_path, device.camera.a_mm, cfg.topographer.a_mm, a.config_path));
  }
  RequireFoldFreeSigma(*a.sigma_per_mm2, cfg, a.config_path);
  device.distortion = cfg.distortion.SeidelAt(*a.sigma_per_mm2);
  return device;
}

// The sensor's options: spot model, bit depth and, by bit depth unless given, a well-exposed frame (spots at ~60 %
// of full scale) with realistic read and shot noise.
correct::SpotRenderOptions SensorOptions(const RenderSpotsRequest& a) {
  correct::SpotRenderOptions o;
  o.shape = a.spot == "psf" ? correct::SpotShape::kPsf : correct::SpotShape::kEllipse;
  o.psf_sigma_px = a.psf_px;
  o.bits = a.bits;
  const bool b16 = a.bits == 16;
  o.background_dn = std::isnan(a.background_dn) ? (b16 ? 1000.0 : 4.0) : a.background_dn;
  o.peak_dn = std::isnan(a.peak_dn) ? (b16 ? 40000.0 : 160.0) : a.peak_dn;
  o.read_noise_dn = std::isnan(a.read_noise_dn) ? (b16 ? 60.0 : 1.0) : a.read_noise_dn;
  o.gain_e_per_dn = std::isnan(a.gain_e_per_dn) ? (b16 ? 4.0 : 0.0) : a.gain_e_per_dn;
  o.seed = a.seed;
  std::string why;
  if (!o.IsValid(&why)) throw util::InputError("render-spots: " + why);
  return o;
}

// The spots as captured: drops and glints, defocus, tear-film break-up and the lids over the truth. Glints keep
// clear of every spot by its largest semi-axis plus 8 px (the above-threshold radius of the widest, brightest glint,
// PSF 3 px at 1.5x the spot level, is ~6 px), so that no glint merges with a spot.
std::vector<correct::SpotToRender> CapturedSpots(const RenderSpotsRequest& a,
                                                 const std::vector<correct::SpotToRender>& truth,
                                                 correct::SpotRenderOptions* o) {
  double largest_px = 0;
  for (const auto& s : truth) {
    largest_px = std::max(largest_px, Eigen::JacobiSVD<Eigen::Matrix2d>(s.shape_px).singularValues()(0));
  }
  const double clearance = (o->shape == correct::SpotShape::kEllipse ? largest_px : 3.0 * a.psf_px) + 8.0;
  o->lids = correct::LidsOver(truth, a.upper_lid_fraction, a.lower_lid_fraction);
  o->skin_dn = a.lid_skin_dn;
  o->skin_texture_dn = 0.25 * o->skin_dn;
  o->artefacts.lashes = a.lashes;
  o->artefacts.iris_dn = a.iris_dn;
  o->artefacts.motion_blur_px = a.motion_blur_px;
  o->artefacts.motion_blur_deg = a.motion_blur_deg;
  std::string why;
  if (!o->IsValid(&why)) throw util::InputError("render-spots: " + why);
  auto spots = correct::DropAndAddGlints(truth, a.drop_fraction, a.glints, clearance, a.seed + 1);
  if (a.defocus_rim_px > 0) spots = correct::GrowDefocus(spots, o->lids, a.psf_px, a.defocus_rim_px);
  if (a.tear_film_patches > 0)
    spots = correct::BreakTearFilm(spots, o->lids, a.tear_film_patches, a.psf_px, a.seed + 2);
  return correct::HideUnderLids(spots, o->lids);
}

}  // namespace

void RunRenderSpots(const RenderSpotsRequest& a, std::ostream& out) {
  Validate(a);
  const auto cfg = model::LoadConfig(a.config_path);
  const model::Surface surface = SurfaceToImage(cfg, a.sphere_radius_mm, a.ball_at_mm);
  const model::Device device = DeviceOf(a, cfg);
  const auto& camera = device.camera;
  correct::SpotRenderOptions o = SensorOptions(a);
  const auto truth = correct::SpotsOnSensor(surface, cfg.ideal_image, cfg.topographer, device);
  if (truth.spots.empty()) throw std::runtime_error(fmt::format("{}: the surface images no spot", a.config_path));
  for (const auto& f : truth.failures) {
    util::Log(a.log, fmt::format("spot ({}, {}): {}", f.id.ring, f.id.index, f.reason));
  }
  const auto spots = CapturedSpots(a, truth.spots, &o);
  int off_sensor = 0;
  for (const auto& s : spots) off_sensor += !camera.OnSensor(s.centre_px);
  if (off_sensor > 0) util::Log(a.log, fmt::format("{} spots fall off the sensor", off_sensor));

  const cv::Mat image = correct::RenderSpotImage(spots, camera.width_px, camera.height_px, o);
  const auto png = imageio::EncodePng(image, a.out_path);
  const std::string csv = a.truth_path.empty() ? std::string() : correct::SpotTruthCsv(spots, camera);
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out_path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  if (!a.truth_path.empty()) outputs.AddFile(a.truth_path, csv);
  outputs.Commit();
  const int glints =
      static_cast<int>(std::count_if(spots.begin(), spots.end(), [](const auto& s) { return s.id.ring == 0; }));
  out << fmt::format("rendered {} spots ({} dropped or under a lid, {} not imaged) and {} glints, {}-bit {}x{} -> {}\n",
                     spots.size() - glints, truth.spots.size() - (spots.size() - glints), truth.failures.size(), glints,
                     a.bits, camera.width_px, camera.height_px, a.out_path);
}

}  // namespace topocal::pipeline
