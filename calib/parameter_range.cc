#include "calib/parameter_range.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace topocal::calib {
namespace {

// The largest normalised radius of an image corner from the principal point (pixel-centre convention: the corners
// of the sensor are at -0.5 and size - 0.5).
double CornerRadius(const model::CameraModel& c) {
  double r = 0;
  for (const double u : {-0.5, c.width_px - 0.5}) {
    for (const double v : {-0.5, c.height_px - 0.5}) {
      r = std::max(r, std::hypot((u - c.cx_px) / c.fx_px, (v - c.cy_px) / c.fy_px));
    }
  }
  return r;
}

}  // namespace

double PlausibleHalfRange(std::string_view name, const model::CameraModel& camera) {
  const double rc = CornerRadius(camera);
  if (name == "fx") return 0.5 * std::abs(camera.fx_px);
  if (name == "fy") return 0.5 * std::abs(camera.fy_px);
  if (name == "cx") return 0.5 * camera.width_px;
  if (name == "cy") return 0.5 * camera.height_px;
  if (name == "k1") return std::pow(rc, -2.0);
  if (name == "k2") return std::pow(rc, -4.0);
  if (name == "k3") return std::pow(rc, -6.0);
  // The rational model's denominator: the same bounds as the numerator's terms of the same order.
  if (name == "k4") return std::pow(rc, -2.0);
  if (name == "k5") return std::pow(rc, -4.0);
  if (name == "k6") return std::pow(rc, -6.0);
  if (name == "p1" || name == "p2") return 1.0 / (3.0 * rc);
  if (name == "ex" || name == "ey") return rc;
  return 0;
}

std::vector<UndeterminedParameter> UndeterminedParameters(const CalibrationResult& result) {
  std::vector<UndeterminedParameter> out;
  if (!result.ok()) return out;
  for (const auto& p : result.parameters) {
    if (p.fixed) continue;
    const double range = PlausibleHalfRange(p.name, result.camera);
    // A range that is not finite (a degenerate camera) cannot vouch for the parameter either.
    if (!(std::isfinite(range) && range > 0) || p.stddev > range) out.push_back({p.name, p.value, p.stddev, range});
  }
  return out;
}

std::string UndeterminedMessage(const std::vector<UndeterminedParameter>& undetermined) {
  std::string list, names;
  for (const auto& u : undetermined) {
    list += fmt::format("{}{} = {:.4g} +- {:.3g} (plausible +-{:.3g})", list.empty() ? "" : ", ", u.name, u.value,
                        u.stddev, u.plausible_half_range);
    names += (names.empty() ? "" : " ") + u.name;
  }
  return fmt::format("{}: the views do not determine {}; hold {} fixed (--fix {}) or add views covering the image", list,
                     undetermined.size() == 1 ? "it" : "them", undetermined.size() == 1 ? "it" : "them", names);
}

}  // namespace topocal::calib
