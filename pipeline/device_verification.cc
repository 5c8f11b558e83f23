#include "pipeline/device_verification.h"

#include <stdexcept>

#include <fmt/format.h>

#include "model/keratometry.h"
#include "pipeline/measure_spots.h"
#include "topo/power_map.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

// The same range as the reference sphere of VerifyOnReferenceSphere.
constexpr double kMinRadiusMm = 5.0;
constexpr double kMaxRadiusMm = 11.0;

StageResult Stage(const std::vector<std::pair<model::SpotId, Eigen::Vector2d>>& pixels, const model::Device& device,
                  const model::Config& config, const model::BiconicParams* truth, const char* what) {
  std::vector<model::PlaneSpot> spots;
  for (const auto& [id, px] : pixels) {
    if (const auto mm = device.UndistortedOf(px)) spots.push_back({id, *mm});
  }
  StageResult r;
  try {
    r.analysis = AnalyzeThroughDevice(spots, device, config, truth);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(fmt::format("{}: {}", what, e.what()));
  }
  r.numbers = Summarize(r.analysis, static_cast<int>(spots.size()));
  return r;
}

ThreeWay MeasureThreeWays(const std::vector<std::pair<model::SpotId, Eigen::Vector2d>>& pixels,
                          const model::Device& nominal, const model::Device& lens_only,
                          const model::Device& calibrated, const model::Config& config,
                          const model::BiconicParams* truth, const std::string& what) {
  ThreeWay t;
  t.uncorrected = Stage(pixels, nominal, config, truth, (what + ", uncorrected").c_str());
  t.lens_only = Stage(pixels, lens_only, config, truth, (what + ", lens only").c_str());
  t.device = Stage(pixels, calibrated, config, truth, (what + ", through the calibrated device").c_str());
  return t;
}

}  // namespace

HeldOutBall VerifyHeldOutBall(const cv::Mat& image, double radius_mm, const model::Device& nominal,
                              const model::Device& lens_only, const model::Device& calibrated,
                              const model::Config& config) {
  if (!(radius_mm >= kMinRadiusMm && radius_mm <= kMaxRadiusMm)) {
    throw util::InputError(
        fmt::format("ball radius {} mm is outside [{}, {}] mm", radius_mm, kMinRadiusMm, kMaxRadiusMm));
  }
  const auto& cam = nominal.camera;
  if (image.cols != cam.width_px || image.rows != cam.height_px) {
    throw util::InputError(fmt::format("the image is {} x {} px but the camera is {} x {} px", image.cols,
                                            image.rows, cam.width_px, cam.height_px));
  }
  const model::Config ball = WithSphere(config, radius_mm);
  // Detected and indexed once, through the nominal camera; each stage maps the same pixels its own way.
  const auto raw = MeasureSpots(image, nominal.camera, ball.ideal_image, std::nullopt);
  std::vector<std::pair<model::SpotId, Eigen::Vector2d>> pixels;
  for (const auto& s : raw.detected) pixels.emplace_back(s.id, nominal.camera.PixelFromDetectionPlane(s.position_mm));
  HeldOutBall v;
  v.radius_true_mm = radius_mm;
  v.power_true_D = model::PowerFromCurvatureD(1.0 / radius_mm);  // Eq. 25
  v.spots_indexed = raw.indexed;
  // No height truth: the ball sits anywhere laterally, so only its radius and power are compared.
  v.stages = MeasureThreeWays(pixels, nominal, lens_only, calibrated, ball, nullptr, "held-out ball");
  return v;
}

ThreeWay PaperCorneaThroughDevice(const model::Device& nominal, const model::Device& lens_only,
                                  const model::Device& calibrated, const model::Config& config) {
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  const auto image = model::SynthesizeImage(model::Biconic{config.cornea}, calibrated, config.topographer, design.targets);
  if (image.spots.empty()) throw std::runtime_error("the paper cornea images no spot through the calibrated device");
  std::vector<std::pair<model::SpotId, Eigen::Vector2d>> pixels;
  for (const auto& s : image.spots) pixels.emplace_back(s.id, calibrated.PixelOf(s.position_mm));
  return MeasureThreeWays(pixels, nominal, lens_only, calibrated, config, &config.cornea, "paper cornea");
}

}  // namespace topocal::pipeline
