#include "pipeline/capture_quality.h"

#include <algorithm>
#include <cmath>
#include <set>

#include <fmt/format.h>

#include "model/null_screen_layout.h"
#include "util/median.h"

namespace topocal::pipeline {
namespace {

using util::Median;

// The side of the image a detection-plane direction points to.
std::string SideOf(const Eigen::Vector2d& direction_mm, const model::TopographerCamera& camera) {
  const Eigen::Vector2d px = camera.Orientation() * direction_mm;  // pixel axes: u right, v down
  if (std::abs(px.y()) >= std::abs(px.x())) return px.y() < 0 ? "top" : "bottom";
  return px.x() < 0 ? "left" : "right";
}

}  // namespace

CaptureQuality AssessCapture(const correct::DetectAndIndexResult& located, const model::TopographerCamera& camera,
                             const model::IdealImageParams& ideal) {
  CaptureQuality q;
  const auto keys = model::OrientationKeySpots(ideal);
  const std::set<model::SpotId> key_set(keys.begin(), keys.end());
  const auto spots = model::IdealImage(ideal);
  q.designed = static_cast<int>(spots.size() - key_set.size());
  q.usable = static_cast<int>(located.spots.size());
  q.identified = q.usable + static_cast<int>(located.excluded.size());
  q.refused = located.refused_identities;
  q.unassigned = static_cast<int>(located.unassigned.size());
  q.visible_fraction = q.designed > 0 ? static_cast<double>(q.identified) / q.designed : 0;
  std::set<model::SpotId> found;
  std::vector<double> areas;
  for (const auto* list : {&located.spots, &located.excluded}) {
    for (const auto& s : *list) {
      found.insert(s.id);
      areas.push_back(s.area_px);
    }
  }
  q.median_spot_area_px = Median(areas);
  // Azimuths (1 deg bins) of the outer half of the rings where a designed spot was identified.
  std::vector<bool> seen(360, false);
  const int first_outer = (ideal.rings_N + 1) / 2 + 1;
  for (const auto& s : spots) {
    if (s.id.ring < first_outer || key_set.count(s.id) || !found.count(s.id)) continue;
    const double az = std::atan2(s.position_mm.y(), s.position_mm.x()) * 180.0 / M_PI;
    seen[static_cast<int>(std::floor(az + 360.0)) % 360] = true;
  }
  // Bins narrower than the outer rings' spot spacing are empty between spots: a gap is reported from 30 deg up.
  int best_len = 0, best_start = 0;
  for (int start = 0; start < 360; ++start) {
    if (seen[start] || !seen[(start + 359) % 360]) continue;  // a run starts after a seen bin
    int len = 0;
    while (len < 360 && !seen[(start + len) % 360]) ++len;
    if (len > best_len) {
      best_len = len;
      best_start = start;
    }
  }
  if (std::none_of(seen.begin(), seen.end(), [](bool b) { return b; })) best_len = 360;
  q.largest_gap_deg = best_len;
  if (best_len >= 30 && best_len < 360) {
    const double mid = (best_start + 0.5 * best_len) * M_PI / 180.0;
    q.gap_side = SideOf(Eigen::Vector2d(std::cos(mid), std::sin(mid)), camera);
  }
  return q;
}

namespace {

// The spots whose slope residual stands out of their neighbours' (RejectSurfaceOutliers); empty when none does or
// too many do. A shape the surface model smooths over leaves residuals that neighbouring spots share; a centre a
// lash pulled, or a wrong identity, leaves one of its own. So each residual is compared with the component-wise
// median of its kNeighbours nearest spots' residuals.
std::set<model::SpotId> SlopeOutliers(const topo::Reconstruction& r) {
  constexpr size_t kNeighbours = 6;
  const size_t n = r.points.size();
  if (n < 20) return {};
  std::vector<Eigen::Vector2d> residual(n), xy(n);
  for (size_t i = 0; i < n; ++i) {
    const auto& p = r.points[i];
    model::SurfaceDerivatives d;
    r.Derivatives(p.point_mm.x(), p.point_mm.y(), &d);
    residual[i] = Eigen::Vector2d(-p.normal.x() / p.normal.z(), -p.normal.y() / p.normal.z()) -
                  Eigen::Vector2d(d.zx, d.zy);
    xy[i] = p.point_mm.head<2>();
  }
  std::vector<double> departure(n);
  std::vector<std::pair<double, size_t>> near;
  std::vector<double> cx, cy;
  for (size_t i = 0; i < n; ++i) {
    near.clear();
    for (size_t j = 0; j < n; ++j) {
      if (j != i) near.emplace_back((xy[j] - xy[i]).squaredNorm(), j);
    }
    std::partial_sort(near.begin(), near.begin() + kNeighbours, near.end());
    cx.clear();
    cy.clear();
    for (size_t k = 0; k < kNeighbours; ++k) {
      cx.push_back(residual[near[k].second].x());
      cy.push_back(residual[near[k].second].y());
    }
    departure[i] = (residual[i] - Eigen::Vector2d(Median(cx), Median(cy))).norm();
  }
  // The magnitude of a 2-D Gaussian departure of sd s per component has median 1.1774 s.
  const double scale = std::max(Median(departure) / 1.1774, r.expected_slope_noise);
  if (!(scale > 0)) return {};
  std::set<model::SpotId> out;
  for (size_t i = 0; i < n; ++i) {
    if (departure[i] > kSurfaceOutlierSigmas * scale) out.insert(r.points[i].id);
  }
  if (out.size() > kMaxSurfaceOutlierShare * n) return {};
  return out;
}

}  // namespace

topo::Analysis RejectSurfaceOutliers(
    std::vector<model::PlaneSpot> spots,
    const std::function<topo::Analysis(const std::vector<model::PlaneSpot>&)>& analyze, CaptureQuality* capture) {
  topo::Analysis analysis = analyze(spots);
  for (int pass = 0; pass < kSurfaceOutlierPasses && analysis.reconstruction.ok; ++pass) {
    const auto outliers = SlopeOutliers(analysis.reconstruction);
    if (outliers.empty()) break;
    std::erase_if(spots, [&](const model::PlaneSpot& s) { return outliers.count(s.id) > 0; });
    if (capture) {
      capture->surface_outliers.insert(capture->surface_outliers.end(), outliers.begin(), outliers.end());
      capture->usable -= static_cast<int>(outliers.size());
    }
    analysis = analyze(spots);
  }
  return analysis;
}

std::string CaptureQuality::Line() const {
  std::string gap = largest_gap_deg >= 30
                        ? fmt::format("outer rings missing over {:.0f} deg{}", largest_gap_deg,
                                      gap_side.empty() ? std::string() : " at the image's " + gap_side +
                                                                            (gap_side == "top" ? " (upper lid?)" : ""))
                        : std::string("no sector missing");
  return fmt::format("capture: {} of {} spots identified ({:.0f} % visible), {} usable; {}; {} unidentified blobs "
                     "(glints, lashes, skin); {} identities refused as ambiguous; {} spots rejected by the "
                     "reconstructed surface, {} identified through it; median spot area {:.0f} px",
                     identified, designed, 100 * visible_fraction, usable, gap, unassigned, refused,
                     surface_outliers.size(), surface_labelled, median_spot_area_px);
}

MeasurementVerdict JudgeMeasurement(const CaptureQuality& capture, const topo::Analysis& analysis) {
  MeasurementVerdict v;
  if (capture.visible_fraction < kMinVisibleFraction) {
    v.reasons.push_back(fmt::format("only {} of the {} designed spots identified ({:.0f} %, need {:.0f} %)",
                                    capture.identified, capture.designed, 100 * capture.visible_fraction,
                                    100 * kMinVisibleFraction));
  }
  if (!analysis.clinical_ok) v.reasons.push_back(analysis.clinical_message);
  const auto& r = analysis.reconstruction;
  if (!topo::ModelFitsData(r)) {
    v.reasons.push_back(fmt::format("the surface model does not represent the identified spots (slope residual "
                                    "{:.1f} x the expected noise, shared part {:.2f} x): a wrong identity or a shape "
                                    "no model here holds",
                                    r.adequacy_ratio, r.structured_residual_ratio));
  }
  v.valid = v.reasons.empty();
  return v;
}

}  // namespace topocal::pipeline
