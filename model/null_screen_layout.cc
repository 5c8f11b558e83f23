#include "model/null_screen_layout.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include "util/io.h"

namespace topocal::model {

namespace {

constexpr double kTwoPi = 2.0 * M_PI;

// a mod 2 pi in [0, 2 pi).
double WrapTwoPi(double a) {
  double w = std::fmod(a, kTwoPi);
  if (w < 0) w += kTwoPi;
  return w >= kTwoPi ? 0.0 : w;
}

}  // namespace

bool NullScreenLayoutOptions::IsValid(std::string* why) const {
  const auto fail = [&](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (outline_points < 8) return fail("outline_points must be at least 8");
  if (!(rim_margin_mm >= 0) || !std::isfinite(rim_margin_mm)) return fail("rim_margin_mm must be finite and >= 0");
  if (cut_azimuth_rad && !std::isfinite(*cut_azimuth_rad)) return fail("cut_azimuth_rad must be finite");
  return true;
}

double ConeDevelopment::SectorAngleRad() const { return kTwoPi * std::sin(semi_angle_rad); }

double ConeDevelopment::SlantMm(const Eigen::Vector3d& p) const {
  // |P - A| directly rather than (z - z_c)/cos(phi_c): exact for any point, and equal to it on the cone.
  return (p - Eigen::Vector3d(0.0, 0.0, apex_z_mm)).norm();
}

double ConeDevelopment::PsiRad(const Eigen::Vector3d& p) const {
  return WrapTwoPi(std::atan2(p.y(), p.x()) - cut_azimuth_rad) * std::sin(semi_angle_rad);
}

Eigen::Vector2d ConeDevelopment::Unroll(const Eigen::Vector3d& p) const {
  const double s = SlantMm(p), psi = PsiRad(p);
  return {s * std::cos(psi), s * std::sin(psi)};
}

Eigen::Vector2d ConeDevelopment::UnrollNear(const Eigen::Vector3d& p, double near_psi_rad) const {
  const double s = SlantMm(p);
  const double period = SectorAngleRad();
  double psi = PsiRad(p);
  psi += period * std::round((near_psi_rad - psi) / period);
  return {s * std::cos(psi), s * std::sin(psi)};
}

Eigen::Vector3d ConeDevelopment::RollUp(const Eigen::Vector2d& q) const {
  const double s = q.norm();
  const double phi = cut_azimuth_rad + std::atan2(q.y(), q.x()) / std::sin(semi_angle_rad);
  const double rho = s * std::sin(semi_angle_rad);
  return {rho * std::cos(phi), rho * std::sin(phi), apex_z_mm + s * std::cos(semi_angle_rad)};
}

std::optional<Eigen::Vector3d> TraceImagePointToCone(const Topographer& topographer, const Eigen::Vector2d& image_mm) {
  const auto t = TraceIdealPoint(topographer, image_mm);
  if (!t) return std::nullopt;
  return t->on_cone_mm;
}

namespace {

// Seam azimuth crossing the fewest outlines; ties broken by the largest angular clearance to every outline.
// Each outline is reduced to its azimuth interval [lo, hi] (unwrapped around its target, hi - lo < pi).
double ChooseCutAzimuth(const std::vector<std::pair<double, double>>& intervals) {
  // A scan over candidate azimuths rather than an interval sweep: 624 outlines x 7200 candidates is a few ms,
  // once per design, and the 0.05 deg resolution is far below the width of any gap worth using.
  constexpr int kCandidates = 7200;
  double best_phi = 0.0;
  int best_count = std::numeric_limits<int>::max();
  double best_clearance = -1.0;
  for (int c = 0; c < kCandidates; ++c) {
    const double phi = kTwoPi * (c + 0.5) / kCandidates;
    int count = 0;
    double clearance = M_PI;
    for (const auto& [lo, hi] : intervals) {
      // Shift phi onto the branch of the interval's centre.
      const double mid = 0.5 * (lo + hi);
      const double p = mid + std::remainder(phi - mid, kTwoPi);
      if (p >= lo && p <= hi) {
        ++count;
      } else {
        clearance = std::min(clearance, std::min(std::abs(p - lo), std::abs(p - hi)));
      }
    }
    if (count < best_count || (count == best_count && clearance > best_clearance)) {
      best_count = count;
      best_clearance = clearance;
      best_phi = phi;
    }
  }
  return best_phi;
}

}  // namespace

std::vector<SpotId> OrientationKeySpots(const IdealImageParams& ideal) {
  if (!ideal.orientation_key) return {};
  std::vector<SpotId> out;
  constexpr double kRadiusFraction[3] = {0.3, 0.5, 0.7};
  constexpr double kAngleDeg[3] = {0.0, 90.0, 225.0};
  for (int k = 0; k < 3; ++k) {
    const int ring = 1 + static_cast<int>(std::lround(kRadiusFraction[k] * ideal.rings_N));
    const int count = SpotsOnRing(ideal, ring);
    const int index = static_cast<int>(std::lround(kAngleDeg[k] / 360.0 * count)) % count;
    out.push_back({ring, index});
  }
  return out;
}

bool IsOrientationKeySpot(const IdealImageParams& ideal, const SpotId& id) {
  if (!ideal.orientation_key) return false;
  for (const auto& k : OrientationKeySpots(ideal)) {
    if (k == id) return true;
  }
  return false;
}

NullScreenLayout LayoutNullScreen(const IdealImageParams& ideal, const TopographerParams& topographer,
                                  const NullScreenLayoutOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw util::InputError("NullScreenLayoutOptions: " + why);
  const Topographer topo{topographer};
  const double radius_mm = ideal.spot_radius_um * 1e-3;
  NullScreenLayout layout;
  layout.development.apex_z_mm = topographer.cone_vertex_z_mm;
  layout.development.semi_angle_rad = topographer.cone_semi_angle_deg * M_PI / 180.0;

  const auto design = DesignNullScreen(ideal, topographer);
  layout.failures = design.failures;
  // All pairs: 624 spots are 2e5 distance checks, negligible next to the trace.
  for (size_t a = 0; a < design.targets.size(); ++a) {
    for (size_t b = a + 1; b < design.targets.size(); ++b) {
      if ((design.targets[a].ideal_mm - design.targets[b].ideal_mm).norm() < 2.0 * radius_mm) ++layout.overlapping_pairs;
    }
  }
  std::vector<std::pair<double, double>> azimuth_intervals;
  for (const auto& t : design.targets) {
    if (IsOrientationKeySpot(ideal, t.id)) continue;  // the key's gaps are not printed
    SpotOutline o;
    o.id = t.id;
    o.target_on_cone_mm = t.on_cone_mm;
    o.on_cone_mm.reserve(options.outline_points);
    bool ok = true;
    for (int k = 0; k < options.outline_points && ok; ++k) {
      const double a = kTwoPi * k / options.outline_points;
      const auto p = TraceImagePointToCone(topo, t.ideal_mm + radius_mm * Eigen::Vector2d(std::cos(a), std::sin(a)));
      if (p) o.on_cone_mm.push_back(*p);
      ok = p.has_value();
    }
    if (!ok) {
      layout.failures.push_back({t.id, "a point of the spot's outline cannot be traced to the cone"});
      continue;
    }
    const double phi_t = std::atan2(t.on_cone_mm.y(), t.on_cone_mm.x());
    double lo = phi_t, hi = phi_t;
    for (const auto& p : o.on_cone_mm) {
      const double phi = phi_t + std::remainder(std::atan2(p.y(), p.x()) - phi_t, kTwoPi);
      lo = std::min(lo, phi);
      hi = std::max(hi, phi);
    }
    azimuth_intervals.emplace_back(lo, hi);
    layout.outlines.push_back(std::move(o));
  }

  layout.development.cut_azimuth_rad =
      options.cut_azimuth_rad ? WrapTwoPi(*options.cut_azimuth_rad) : ChooseCutAzimuth(azimuth_intervals);
  const auto& dev = layout.development;
  double s_min = std::numeric_limits<double>::infinity(), s_max = 0.0;
  for (auto& o : layout.outlines) {
    const double psi_t = dev.PsiRad(o.target_on_cone_mm);
    o.target_sheet_mm = dev.Unroll(o.target_on_cone_mm);
    o.sheet_mm.reserve(o.on_cone_mm.size());
    for (const auto& p : o.on_cone_mm) {
      const Eigen::Vector2d q = dev.UnrollNear(p, psi_t);
      double psi = dev.PsiRad(p);  // the branch UnrollNear took, without atan2's wrap at pi
      psi += dev.SectorAngleRad() * std::round((psi_t - psi) / dev.SectorAngleRad());
      o.crosses_seam = o.crosses_seam || psi < 0.0 || psi > dev.SectorAngleRad();
      o.sheet_mm.push_back(q);
      s_min = std::min(s_min, q.norm());
      s_max = std::max(s_max, q.norm());
    }
  }
  if (layout.outlines.empty()) s_min = s_max = 0.0;
  layout.inner_slant_mm = std::max(0.0, s_min - options.rim_margin_mm);
  layout.outer_slant_mm = s_max + options.rim_margin_mm;
  return layout;
}

}  // namespace topocal::model
