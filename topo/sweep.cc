#include "topo/sweep.h"

#include <chrono>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "model/distortion.h"
#include "topo/device_analysis.h"
#include "topo/image_ellipse.h"
#include "util/parallel.h"

namespace topocal::topo {
namespace {

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

model::SeidelParams SeidelFor(const model::Config& c, double sigma) { return c.distortion.SeidelAt(sigma); }

void ApplyDistortion(const model::Distortion& d, model::SyntheticImage* image) {
  for (auto& s : image->spots) s.position_mm = model::Distort(d, s.position_mm);
}

}  // namespace

model::SyntheticImage SimulateSpots(const model::Config& config, double sigma_per_mm2) {
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  auto image = model::SynthesizeImage(model::Biconic{config.cornea}, model::Topographer{config.topographer},
                                      design.targets);
  ApplyDistortion(SeidelFor(config, sigma_per_mm2), &image);
  return image;
}

SweepResult RunSweep(const model::Config& config, int jobs, const model::Device* device) {
  const auto t_start = std::chrono::steady_clock::now();
  SweepResult result;
  auto t0 = std::chrono::steady_clock::now();
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  result.timing.design_ms = MsSince(t0);
  result.spots = static_cast<int>(design.targets.size());
  result.design_failures = design.failures;
  if (design.targets.empty()) throw std::runtime_error(fmt::format("{}: no spot of the ideal image reaches the cone", config.path));

  t0 = std::chrono::steady_clock::now();
  const auto undistorted =
      device ? model::SynthesizeImage(model::Biconic{config.cornea}, *device, config.topographer, design.targets)
             : model::SynthesizeImage(model::Biconic{config.cornea}, model::Topographer{config.topographer},
                                      design.targets);
  result.timing.synthesis_ms = MsSince(t0);
  result.synthesis_failures = undistorted.failures;
  const int outer_ring = config.ideal_image.rings_N + 1;
  const auto reference = FitImageContour(undistorted.spots, outer_ring);
  if (!reference) {
    throw std::runtime_error(fmt::format("{}: cornea: the outer ring of the image has too few spots for a contour fit", config.path));
  }
  // The sigmas are independent: one work item each, plus the ideal maps (the last item), on `jobs` threads. Each
  // item writes only its own slot and reads only shared constants, so the rows are bit for bit those of a serial
  // run; an error is reported for the first failing sigma in configuration order, whatever the scheduling.
  const auto& sigmas = config.distortion.sigmas_per_mm2;
  const size_t n = sigmas.size();
  result.rows.resize(n);
  std::vector<std::string> errors(n + 1);  // [n]: the ideal maps, reported first
  std::vector<double> analysis_ms(n, 0.0);
  util::ParallelFor(n + 1, jobs, [&](size_t i) {
    if (i == n) {
      try {
        result.ideal_power = IdealPowerMaps(config.cornea, config.reconstruction);
      } catch (const std::runtime_error& e) {
        errors[n] = e.what();
      }
      return;
    }
    const double sigma = sigmas[i];
    model::SyntheticImage image = undistorted;
    ApplyDistortion(SeidelFor(config, sigma), &image);
    const auto ellipse = FitImageContour(image.spots, outer_ring);
    if (!ellipse) {
      errors[i] = fmt::format("{}: sigma {}: contour fit failed", config.path, sigma);
      return;
    }
    SweepRow& row = result.rows[i];
    row.sigma_per_mm2 = sigma;
    row.image_ellipse = *ellipse;
    row.area_change_pct = 100.0 * (ellipse->AreaMm2() / reference->AreaMm2() - 1.0);
    row.spots_imaged = static_cast<int>(image.spots.size());
    const std::vector<model::PlaneSpot> measured = model::PlaneSpotsOf(image.spots);
    const auto t_analysis = std::chrono::steady_clock::now();
    try {
      row.analysis = AnalyzeSpots(measured, design.targets, config, &config.cornea);
    } catch (const std::runtime_error& e) {
      errors[i] = fmt::format("{}: sigma {}: {}", config.path, sigma, e.what());
    }
    analysis_ms[i] = MsSince(t_analysis);
  });
  if (!errors[n].empty()) throw std::runtime_error(errors[n]);
  for (const auto& e : errors) {
    if (!e.empty()) throw std::runtime_error(e);
  }
  for (const double ms : analysis_ms) result.timing.analysis_ms += ms;
  if (device) {
    const std::vector<model::PlaneSpot> exact = model::PlaneSpotsOf(undistorted.spots);
    try {
      result.through_device = AnalyzeThroughDevice(exact, *device, config, &config.cornea);
    } catch (const std::runtime_error& e) {
      throw std::runtime_error(fmt::format("{}: through the device: {}", config.path, e.what()));
    }
  }
  result.timing.total_ms = MsSince(t_start);
  return result;
}

}  // namespace topocal::topo
