// topocal render-spots: the raw sensor image of a measurement (spot pattern of the configured cornea, distorted,
// seen by the topographer's camera), with its truth. Conventions: docs/camera-conventions.md.
#include <fmt/format.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <memory>

#include "correct/spot_render.h"
#include "correct/spot_truth.h"
#include "imageio/image_file.h"
#include "model/config.h"
#include "model/topographer_camera.h"
#include "tools/commands.h"
#include "tools/surface_option.h"
#include "util/io.h"

namespace topocal::tools {
namespace {

struct RenderSpotsArgs {
  std::string config, camera, device, out, truth, spot = "ellipse";
  double sigma = 0, psf_px = 1.0, drop = 0, sphere_radius_mm = 0, upper_lid = 0, lower_lid = 0;
  std::vector<double> ball_at_mm;  // vertex of the reference ball (x, y, z)
  double background = NAN, peak = NAN, noise = NAN, gain = NAN, skin = 0;
  double iris = 0, defocus_rim_px = 0, motion_blur_px = 0, motion_blur_deg = 0;
  int bits = 16, glints = 0, lashes = 0, tear_film = 0;
  uint32_t seed = 1;
};

void RequirePng(const std::string& path, const char* option) {
  if (path.size() < 4 || path.substr(path.size() - 4) != ".png") {
    throw util::InputError(fmt::format("{}: {}: the output must be a .png file", option, path));
  }
}

void Run(const RenderSpotsArgs& a) {
  RequirePng(a.out, "--out");
  if (!std::isfinite(a.sigma)) throw util::InputError("--sigma: must be a finite number");
  if (!(a.drop >= 0 && a.drop < 1)) throw util::InputError(fmt::format("--drop: must be in [0, 1) (got {})", a.drop));
  for (const auto& [name, v] : {std::pair{"--upper-lid", a.upper_lid}, std::pair{"--lower-lid", a.lower_lid}}) {
    if (!(v >= 0 && v < 1)) throw util::InputError(fmt::format("{}: must be in [0, 1) (got {})", name, v));
  }
  if (a.glints < 0) throw util::InputError(fmt::format("--glints: must be >= 0 (got {})", a.glints));
  if (a.camera.empty() == a.device.empty()) throw util::InputError("render-spots: give one of --camera or --device");
  const auto cfg = model::LoadConfig(a.config);
  const model::Surface surface = SurfaceToImage(cfg, a.sphere_radius_mm, a.ball_at_mm);
  model::Device device;
  if (!a.device.empty()) {
    device = model::LoadDevice(a.device).device;
  } else {
    device = model::NominalDevice(model::LoadTopographerCamera(a.camera));
    if (std::abs(device.camera.a_mm - cfg.topographer.a_mm) > 1e-9) {
      throw util::InputError(fmt::format("{}: a_mm: {} differs from the configuration's topographer.a_mm = {} ({})",
                                         a.camera, device.camera.a_mm, cfg.topographer.a_mm, a.config));
    }
    RequireFoldFreeSigma(a.sigma, cfg, a.config);
    device.distortion = cfg.distortion.SeidelAt(a.sigma);
  }
  const auto& camera = device.camera;
  correct::SpotRenderOptions o;
  o.shape = a.spot == "psf" ? correct::SpotShape::kPsf : correct::SpotShape::kEllipse;
  o.psf_sigma_px = a.psf_px;
  o.bits = a.bits;
  // Defaults by bit depth: a well-exposed frame (spots at ~60 % of full scale) with realistic read and shot noise.
  const bool b16 = a.bits == 16;
  o.background_dn = std::isnan(a.background) ? (b16 ? 1000.0 : 4.0) : a.background;
  o.peak_dn = std::isnan(a.peak) ? (b16 ? 40000.0 : 160.0) : a.peak;
  o.read_noise_dn = std::isnan(a.noise) ? (b16 ? 60.0 : 1.0) : a.noise;
  o.gain_e_per_dn = std::isnan(a.gain) ? (b16 ? 4.0 : 0.0) : a.gain;
  o.seed = a.seed;
  std::string why;
  if (!o.IsValid(&why)) throw util::InputError("render-spots: " + why);

  const auto truth = correct::SpotsOnSensor(surface, cfg.ideal_image, cfg.topographer, device);
  if (truth.spots.empty()) throw std::runtime_error(fmt::format("{}: the surface images no spot", a.config));
  for (const auto& f : truth.failures) {
    fmt::print(stderr, "topocal render-spots: spot ({}, {}): {}\n", f.id.ring, f.id.index, f.reason);
  }
  // Glints keep clear of every spot by its largest semi-axis plus 8 px (the above-threshold radius of the widest,
  // brightest glint, PSF 3 px at 1.5x the spot level, is ~6 px), so that no glint merges with a spot.
  double largest_px = 0;
  for (const auto& s : truth.spots) {
    largest_px = std::max(largest_px, Eigen::JacobiSVD<Eigen::Matrix2d>(s.shape_px).singularValues()(0));
  }
  const double clearance = (o.shape == correct::SpotShape::kEllipse ? largest_px : 3.0 * a.psf_px) + 8.0;
  o.lids = correct::LidsOver(truth.spots, a.upper_lid, a.lower_lid);
  o.skin_dn = a.skin;
  o.skin_texture_dn = 0.25 * o.skin_dn;
  o.artefacts.lashes = a.lashes;
  o.artefacts.iris_dn = a.iris;
  o.artefacts.motion_blur_px = a.motion_blur_px;
  o.artefacts.motion_blur_deg = a.motion_blur_deg;
  if (!o.IsValid(&why)) throw util::InputError("render-spots: " + why);
  auto spots = correct::DropAndAddGlints(truth.spots, a.drop, a.glints, clearance, a.seed + 1);
  if (a.defocus_rim_px > 0) spots = correct::GrowDefocus(spots, o.lids, a.psf_px, a.defocus_rim_px);
  if (a.tear_film > 0) spots = correct::BreakTearFilm(spots, o.lids, a.tear_film, a.psf_px, a.seed + 2);
  spots = correct::HideUnderLids(spots, o.lids);
  int off_sensor = 0;
  for (const auto& s : spots) off_sensor += !camera.OnSensor(s.centre_px);
  if (off_sensor > 0) fmt::print(stderr, "topocal render-spots: {} spots fall off the sensor\n", off_sensor);

  const cv::Mat image = correct::RenderSpotImage(spots, camera.width_px, camera.height_px, o);
  const auto png = imageio::EncodePng(image, a.out);
  const std::string csv = a.truth.empty() ? std::string() : correct::SpotTruthCsv(spots, camera);
  util::StagedOutputs outputs;  // published together or not at all
  outputs.AddFile(a.out, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  if (!a.truth.empty()) outputs.AddFile(a.truth, csv);
  outputs.Commit();
  const int glints = static_cast<int>(std::count_if(spots.begin(), spots.end(), [](const auto& s) { return s.id.ring == 0; }));
  fmt::print("rendered {} spots ({} dropped or under a lid, {} not imaged) and {} glints, {}-bit {}x{} -> {}\n",
             spots.size() - glints, truth.spots.size() - (spots.size() - glints), truth.failures.size(), glints, a.bits,
             camera.width_px, camera.height_px, a.out);
}

}  // namespace

void AddRenderSpotsCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("render-spots", "Render the raw sensor image of the configured cornea's spot pattern");
  auto a = std::make_shared<RenderSpotsArgs>();
  cmd->add_option("--config", a->config, "Topographer configuration (JSON)")->required();
  auto* camera = cmd->add_option("--camera", a->camera, "Topographer camera (JSON, docs/camera-conventions.md)");
  auto* device = cmd->add_option("--device", a->device,
                                 "As-built device (JSON, docs/device.md): camera, distortion and screen pose");
  camera->excludes(device);
  auto* sigma = cmd->add_option("--sigma", a->sigma, "Seidel distortion coefficient sigma, mm^-2 (paper Eq. 18), "
                                                     "with --camera");
  sigma->excludes(device);
  cmd->add_option("--out", a->out, "Output image (.png)")->required();
  cmd->add_option("--sphere-radius-mm", a->sphere_radius_mm,
                  "Image a reference sphere of this radius instead of the configured cornea, mm");
  cmd->add_option("--ball-at", a->ball_at_mm, "Vertex of the reference sphere: x y z, mm (default 0 0 0)")
      ->expected(3);
  cmd->add_option("--truth", a->truth, "Truth CSV: ring,index,x_px,y_px,x_mm,y_mm (distorted; ring 0 = glint)");
  cmd->add_option("--spot", a->spot, "Spot model: ellipse (image of the null-screen spot) or psf (point source)")
      ->check(CLI::IsMember({"ellipse", "psf"}));
  cmd->add_option("--psf-px", a->psf_px, "Gaussian PSF standard deviation, px")->check(CLI::PositiveNumber);
  cmd->add_option("--bits", a->bits, "PNG bit depth (8 or 16)")->check(CLI::IsMember({8, 16}));
  cmd->add_option("--background", a->background, "Background level, DN (default 1000 / 4 for 16 / 8 bits)");
  cmd->add_option("--peak", a->peak, "Exposure: spot level above background, DN (default 40000 / 160)");
  cmd->add_option("--noise", a->noise, "Read noise standard deviation, DN (default 60 / 1)");
  cmd->add_option("--gain", a->gain, "Shot noise: electrons per DN, 0 = none (default 4 / 0)");
  cmd->add_option("--seed", a->seed, "Seed of the noise, drops and glints");
  cmd->add_option("--drop", a->drop, "Fraction of spots to leave out, [0, 1)");
  cmd->add_option("--glints", a->glints, "Number of spurious blobs to add");
  cmd->add_option("--upper-lid", a->upper_lid,
                  "Fraction of the pattern's height an upper lid hides, [0, 1) (its spots left out)");
  cmd->add_option("--lower-lid", a->lower_lid, "Fraction of the pattern's height a lower lid hides, [0, 1)");
  cmd->add_option("--lid-skin", a->skin, "The lids' skin: level above the background, DN, textured +-25 % (0: not drawn)");
  cmd->add_option("--lashes", a->lashes, "Lash shadows hanging from the upper lid's margin, count")
      ->check(CLI::Range(0, 50));
  cmd->add_option("--iris", a->iris, "Textured iris behind the pattern: mean level above the background, DN (0: none)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--defocus-rim-px", a->defocus_rim_px,
                  "Defocus growing towards the rim: PSF sigma at the pattern's radius, px (--psf-px at its centre)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--motion-blur-px", a->motion_blur_px, "The eye's movement during the exposure: smear length, px")
      ->check(CLI::Range(0.0, 100.0));
  cmd->add_option("--motion-blur-deg", a->motion_blur_deg, "Direction of the smear from the image's +u axis, degrees");
  cmd->add_option("--tear-film", a->tear_film, "Tear-film break-up: dry patches (spots in them lost or smeared), count")
      ->check(CLI::Range(0, 50));
  cmd->callback([a] { Run(*a); });
}

}  // namespace topocal::tools
