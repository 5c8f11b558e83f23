#include "calib/distortion_valid_region.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <ceres/jet.h>

namespace topocal::calib {
namespace {

using Jet2 = ceres::Jet<double, 2>;

struct RayPoint {
  Eigen::Vector2d px;
  double det_j;  // det d(pixel)/d(normalised): > 0 while the model is one-to-one and orientation-preserving
};

RayPoint Evaluate(const model::CameraModel& c, const Eigen::Vector2d& u) {
  const Jet2 in[4] = {Jet2(c.fx_px), Jet2(c.fy_px), Jet2(c.cx_px), Jet2(c.cy_px)};
  Jet2 dist[model::kMaxLensParams];
  for (int i = 0; i < model::kMaxLensParams; ++i) dist[i] = Jet2(c.dist[static_cast<size_t>(i)]);
  const Jet2 centre[2] = {Jet2(c.distortion_centre.x()), Jet2(c.distortion_centre.y())};
  const Jet2 uj[2] = {Jet2(u.x(), 0), Jet2(u.y(), 1)};
  Jet2 px[2];
  model::CameraModel::NormalizedToPixel(c.lens, in, dist, centre, uj, px);
  return {{px[0].a, px[1].a}, px[0].v[0] * px[1].v[1] - px[0].v[1] * px[1].v[0]};
}

}  // namespace

double FarthestSensorPixelPx(const model::CameraModel& c) {
  const double dx = std::max(c.cx_px, c.width_px - 1.0 - c.cx_px);
  const double dy = std::max(c.cy_px, c.height_px - 1.0 - c.cy_px);
  return std::hypot(dx, dy);
}

DistortionValidRegion ValidRegionOf(const model::CameraModel& c) {
  constexpr int kRays = 360;
  constexpr double kBisectionPx = 1e-3;
  const double limit_px = 2.0 * 0.5 * std::hypot(c.width_px, c.height_px);
  const Eigen::Vector2d principal(c.cx_px, c.cy_px);
  // A step of ~1 px at the undistorted scale; distortion near a fold compresses, so steps there are shorter still.
  // At most kMaxStepsPerRay steps: a 4000 x 3000 sensor takes 20000, and a file with fy = 3e10 px next to
  // fx = 300 px (found by the fuzzer) asked for 1.6e11 and hung the reader.
  constexpr double kMaxStepsPerRay = 100000;
  const double max_s = 4.0 * limit_px / std::min(c.fx_px, c.fy_px);  // generous: pincushion stretches the image
  const double step = std::max(1.0 / std::max(c.fx_px, c.fy_px), max_s / kMaxStepsPerRay);
  DistortionValidRegion region;
  region.radius_px = limit_px;
  for (int k = 0; k < kRays; ++k) {
    const double theta = 2.0 * std::numbers::pi * k / kRays;
    const Eigen::Vector2d dir(std::cos(theta), std::sin(theta));
    double s_good = 0, s = 0;
    bool folded = false;
    while (s < max_s) {
      s = s_good + step;
      const RayPoint p = Evaluate(c, c.distortion_centre + s * dir);
      if (!(p.det_j > 0)) {
        folded = true;
        break;
      }
      if ((p.px - principal).norm() >= region.radius_px) break;  // no fold nearer than the best so far on this ray
      s_good = s;
    }
    if (!folded) continue;
    double lo = s_good, hi = s;  // det J > 0 at lo, <= 0 at hi
    // Bisection to 1e-3 px; 200 halvings reach any double's resolution, so the cap only stops non-finite models.
    for (int i = 0; i < 200 && (Evaluate(c, c.distortion_centre + hi * dir).px -
                                Evaluate(c, c.distortion_centre + lo * dir).px).norm() > kBisectionPx;
         ++i) {
      const double mid = 0.5 * (lo + hi);
      (Evaluate(c, c.distortion_centre + mid * dir).det_j > 0 ? lo : hi) = mid;
    }
    const double r = (Evaluate(c, c.distortion_centre + lo * dir).px - principal).norm();
    region.radius_px = std::min(region.radius_px, r);
  }
  region.covers_sensor = region.radius_px >= FarthestSensorPixelPx(c);
  return region;
}

bool InsideValidRegion(const DistortionValidRegion& region, const model::CameraModel& camera,
                       const Eigen::Vector2d& px) {
  return (px - Eigen::Vector2d(camera.cx_px, camera.cy_px)).norm() <= region.radius_px;
}

}  // namespace topocal::calib
