#include "pipeline/simulation_surface.h"

#include <fmt/format.h>

#include <cmath>

#include "model/distortion.h"
#include "util/io.h"

namespace topocal::pipeline {

model::Surface SurfaceToImage(const model::Config& config, double sphere_radius_mm, const std::vector<double>& ball_at_mm) {
  if (sphere_radius_mm < 0 || !std::isfinite(sphere_radius_mm)) {
    throw util::InputError(fmt::format("--sphere-radius-mm: must be a positive radius (got {})", sphere_radius_mm));
  }
  if (!ball_at_mm.empty() && sphere_radius_mm == 0) {
    throw util::InputError("--ball-at: needs --sphere-radius-mm (the ball's radius)");
  }
  // The spots of a ball farther than this from the cornea position leave the pattern the indexer knows.
  constexpr double kMaxOffsetMm = 5.0;
  for (const double v : ball_at_mm) {
    if (!(std::abs(v) <= kMaxOffsetMm)) {
      throw util::InputError(
          fmt::format("--ball-at: {} mm is not near the cornea position (+-{} mm)", v, kMaxOffsetMm));
    }
  }
  if (sphere_radius_mm == 0) return model::Biconic{config.cornea};
  model::Sphere ball;
  ball.radius_mm = sphere_radius_mm;
  if (!ball_at_mm.empty()) {
    ball.x0_mm = ball_at_mm[0];
    ball.y0_mm = ball_at_mm[1];
    ball.z0_mm = ball_at_mm[2];
  }
  return ball;
}

void RequireFoldFreeSigma(double sigma_per_mm2, const model::Config& config, const std::string& config_path) {
  if (const double max = model::MaxFoldFreeSigmaPerMm2(config.ideal_image, config.distortion);
      sigma_per_mm2 != 0 && !(std::abs(sigma_per_mm2) < max)) {
    throw util::InputError(fmt::format("--sigma {}: folds the image of {} (|sigma| must be below {:.3g} mm^-2)",
                                       sigma_per_mm2, config_path, max));
  }
}

}  // namespace topocal::pipeline
