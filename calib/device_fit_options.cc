// The device fit's options (their validity) and its result's accessors (calib/device_fit.h).
#include "calib/device_fit.h"

#include <cmath>
#include <string>
#include <utility>

#include <fmt/format.h>

namespace topocal::calib {

bool DeviceTolerances::IsValid(std::string* why) const {
  const std::pair<const char*, double> all[] = {
      {"tilt_deg", tilt_deg},       {"roll_deg", roll_deg},          {"lateral_mm", lateral_mm},
      {"axial_mm", axial_mm},       {"principal_point_mm", principal_point_mm},
      {"a_relative", a_relative},   {"radial_scale", radial_scale},  {"sigma_per_mm2", sigma_per_mm2},
      {"brown_k", brown_k},         {"ball_placement_mm", ball_placement_mm}};
  for (const auto& [name, v] : all) {
    if (!(v > 0) || !std::isfinite(v)) {
      if (why) *why = fmt::format("tolerance {} must be > 0 and finite (got {})", name, v);
      return false;
    }
  }
  return true;
}

bool DeviceFitOptions::IsValid(std::string* why) const {
  if (!priors.IsValid(why)) return false;
  if (!(spot_sigma_px > 0) || !std::isfinite(spot_sigma_px)) {
    if (why) *why = fmt::format("spot_sigma_px must be > 0 (got {})", spot_sigma_px);
    return false;
  }
  if (!(corner_sigma_px > 0) || !std::isfinite(corner_sigma_px)) {
    if (why) *why = fmt::format("corner_sigma_px must be > 0 (got {})", corner_sigma_px);
    return false;
  }
  if (datum_ball < 0) {
    if (why) *why = "datum_ball must be >= 0";
    return false;
  }
  for (const double s : ball_steps_mm) {
    if (!std::isfinite(s) || std::abs(s) > 10) {
      if (why) *why = fmt::format("ball_steps_mm must be within +-10 mm (got {})", s);
      return false;
    }
  }
  if (!std::isfinite(datum_z_mm) || std::abs(datum_z_mm) > 10) {
    if (why) *why = fmt::format("datum_z_mm must be within +-10 mm (got {})", datum_z_mm);
    return false;
  }
  if (!(max_chi2_per_dof > 0) || max_iterations < 1) {
    if (why) *why = "max_chi2_per_dof must be > 0 and max_iterations >= 1";
    return false;
  }
  return true;
}

model::DeviceCovariance DeviceFit::Covariance() const {
  model::DeviceCovariance c;
  for (const auto& p : parameters) c.names.push_back(p.name);
  c.matrix = covariance;
  return c;
}

std::optional<DeviceParameterEstimate> DeviceFit::Parameter(const std::string& name) const {
  for (const auto& p : parameters) {
    if (p.name == name) return p;
  }
  return std::nullopt;
}

}  // namespace topocal::calib
