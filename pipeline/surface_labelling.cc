#include "pipeline/surface_labelling.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <type_traits>

#include "model/distortion.h"
#include "model/freeform_terms.h"
#include "pipeline/capture_quality.h"

namespace topocal::pipeline {
namespace {

// The recovered surface (Psi plus its spline residual) as the sag callable of model::SolveReflectionPointOn, whose
// Newton solve passes 2-jets in (x, y): value, gradient and Hessian in double give the jets' first derivatives
// exactly by the chain rule. Beyond the identified spots' reach in each direction the surface is continued from the
// reach with its slope there and the curvature of the sphere that best fits the recovered points: a degree-10
// polynomial extrapolated one ring beyond its data images a spot several spacings away from where any smooth cornea
// would, and so does the surface's own curvature at a blend zone's edge.
class RecoveredSag {
 public:
  static constexpr int kSectors = 36;

  explicit RecoveredSag(const topo::Reconstruction& surface) : surface_(surface) {
    // The paraxial sphere z ~ kappa rho^2 / 2 through the vertex, by least squares.
    double zr2 = 0, r4 = 0;
    for (const auto& p : surface.points) {
      const double rho2 = p.point_mm.head<2>().squaredNorm();
      double& r = reach_mm_[SectorOf(p.point_mm.x(), p.point_mm.y())];
      r = std::max(r, std::sqrt(rho2));
      zr2 += (p.point_mm.z() - surface.vertex_t_mm) * rho2;
      r4 += rho2 * rho2;
    }
    curvature_per_mm_ = r4 > 0 ? 2 * zr2 / r4 : 0.0;
  }

  template <typename T>
  bool operator()(const T& x, const T& y, T* z, T* zx, T* zy) const {
    const double px = model::ScalarPart(x), py = model::ScalarPart(y);
    const double rho = std::hypot(px, py), reach = reach_mm_[SectorOf(px, py)];
    model::SurfaceDerivatives d;
    if (rho <= reach || !(reach > 0)) {
      surface_.Derivatives(px, py, &d);
    } else {
      // z(B + h) = z + g.h + kappa |h|^2 / 2 from the reach B; its gradient g + kappa h and Hessian kappa I.
      const double bx = px * reach / rho, by = py * reach / rho, hx = px - bx, hy = py - by, k = curvature_per_mm_;
      surface_.Derivatives(bx, by, &d);
      d.z += d.zx * hx + d.zy * hy + 0.5 * k * (hx * hx + hy * hy);
      d.zx += k * hx;
      d.zy += k * hy;
      d.zxx = d.zyy = k;
      d.zxy = 0;
    }
    if (!std::isfinite(d.z) || !std::isfinite(d.zx) || !std::isfinite(d.zy)) return false;
    if constexpr (std::is_same_v<T, double>) {
      *z = d.z, *zx = d.zx, *zy = d.zy;
    } else {
      *z = T(d.z), *zx = T(d.zx), *zy = T(d.zy);
      z->v = d.zx * x.v + d.zy * y.v;
      zx->v = d.zxx * x.v + d.zxy * y.v;
      zy->v = d.zxy * x.v + d.zyy * y.v;
    }
    return true;
  }

 private:
  static int SectorOf(double x, double y) {
    const int s = static_cast<int>(std::floor((std::atan2(y, x) + M_PI) / (2 * M_PI) * kSectors));
    return std::clamp(s, 0, kSectors - 1);
  }
  const topo::Reconstruction& surface_;
  std::array<double, kSectors> reach_mm_{};
  double curvature_per_mm_ = 0;
};

// The identified spot nearest to p (-1 when there is none) and its distance.
int NearestAnchor(const Eigen::Vector2d& p, const std::vector<IdentifiedAnchor>& anchors, double* distance) {
  int best = -1;
  *distance = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k < anchors.size(); ++k) {
    const double d = (anchors[k].position_mm - p).norm();
    if (d < *distance) *distance = d, best = static_cast<int>(k);
  }
  return best;
}

// The nearest prediction to p other than predictions[skip].
double NearestPrediction(const Eigen::Vector2d& p, const std::vector<PredictedSpot>& predictions, size_t skip) {
  double best = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k < predictions.size(); ++k) {
    if (k != skip) best = std::min(best, (predictions[k].position_mm - p).norm());
  }
  return best;
}

// The identified spots with the distance at which the surface images each from where it was detected.
std::vector<IdentifiedAnchor> Anchors(const topo::Reconstruction& surface,
                                      const std::vector<model::PlaneSpot>& detected, const model::Device& device,
                                      const model::Config& config) {
  std::vector<model::SpotId> ids;
  for (const auto& s : detected) ids.push_back(s.id);
  std::map<model::SpotId, Eigen::Vector2d> predicted;
  for (const auto& p : PredictSpots(surface, ids, device, config)) predicted[p.id] = p.position_mm;
  std::vector<IdentifiedAnchor> out;
  for (const auto& s : detected) {
    const auto it = predicted.find(s.id);
    out.push_back({s.position_mm, it == predicted.end() ? std::numeric_limits<double>::infinity()
                                                         : (it->second - s.position_mm).norm()});
  }
  return out;
}

// The pattern's centre in the image: the mean of the innermost identified ring's spots.
Eigen::Vector2d PatternCentre(const std::vector<model::PlaneSpot>& detected) {
  int innermost = std::numeric_limits<int>::max();
  for (const auto& s : detected) innermost = std::min(innermost, s.id.ring);
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  int n = 0;
  for (const auto& s : detected) {
    if (s.id.ring == innermost) sum += s.position_mm, ++n;
  }
  return n > 0 ? Eigen::Vector2d(sum / n) : sum;
}

}  // namespace

std::vector<PredictedSpot> PredictSpots(const topo::Reconstruction& surface, const std::vector<model::SpotId>& ids,
                                        const model::Device& device, const model::Config& config) {
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  const auto placed = device.PlaceTargets(design.targets, config.topographer);
  std::map<model::SpotId, const model::TargetPoint*> by_id;
  for (const auto& t : placed) by_id[t.id] = &t;
  const model::Topographer as_built{device.AsBuilt(config.topographer)};
  const RecoveredSag sag(surface);
  std::vector<PredictedSpot> out;
  for (const auto& id : ids) {
    const auto it = by_id.find(id);
    if (it == by_id.end()) continue;
    const model::TargetPoint& t = *it->second;
    const auto p2 = model::SolveReflectionPointOn(sag, as_built.Pinhole(), t.on_cone_mm,
                                                  Eigen::Vector2d(t.on_sphere_mm.head<2>()));
    if (!p2) continue;
    out.push_back({id, model::Distort(device.distortion, as_built.ImageOf(*p2))});
  }
  return out;
}

namespace {

// The local spacing s at prediction j (the nearest other prediction or identified spot) when the prediction may be
// used at all (an identified spot within kReachSpacings s whose own prediction is within kTrustSpacings s); 0 when not.
double UsableSpacing(const std::vector<PredictedSpot>& predictions, size_t j,
                     const std::vector<IdentifiedAnchor>& identified) {
  const Eigen::Vector2d& p = predictions[j].position_mm;
  double to_identified;
  const int anchor = NearestAnchor(p, identified, &to_identified);
  const double spacing = std::min(to_identified, NearestPrediction(p, predictions, j));
  if (anchor < 0 || !std::isfinite(spacing) || !(spacing > 0) || to_identified > kReachSpacings * spacing ||
      !(identified[anchor].prediction_error_mm <= kTrustSpacings * spacing)) {
    return 0;
  }
  return spacing;
}

// The free detection nearest to p (-1 when none), its distance e1 and the next one's e2.
int NearestFree(const Eigen::Vector2d& p, const std::vector<Eigen::Vector2d>& free_mm, double* e1, double* e2) {
  int nearest = -1;
  *e1 = *e2 = std::numeric_limits<double>::infinity();
  for (size_t k = 0; k < free_mm.size(); ++k) {
    const double e = (free_mm[k] - p).norm();
    if (e < *e1) {
      *e2 = *e1;
      *e1 = e;
      nearest = static_cast<int>(k);
    } else {
      *e2 = std::min(*e2, e);
    }
  }
  return nearest;
}

}  // namespace

std::vector<SurfaceLabel> LabelFromPredictions(const std::vector<PredictedSpot>& predictions,
                                               const std::vector<IdentifiedAnchor>& identified,
                                               const std::vector<Eigen::Vector2d>& free_mm) {
  std::vector<SurfaceLabel> out;
  for (size_t j = 0; j < predictions.size(); ++j) {
    const double spacing = UsableSpacing(predictions, j, identified);
    if (!(spacing > 0)) continue;
    const Eigen::Vector2d& p = predictions[j].position_mm;
    double e1, e2;
    const int nearest = NearestFree(p, free_mm, &e1, &e2);
    if (nearest < 0 || e1 > kGateSpacings * spacing || e1 > kAmbiguityRatio * e2) continue;
    const Eigen::Vector2d& d = free_mm[nearest];
    double others;
    NearestAnchor(d, identified, &others);
    others = std::min(others, NearestPrediction(d, predictions, j));
    if (e1 > kAmbiguityRatio * others) continue;
    out.push_back({predictions[j].id, nearest});
  }
  return out;
}

std::vector<SurfaceLabel> GrowFromPredictions(std::vector<PredictedSpot> predictions,
                                              std::vector<IdentifiedAnchor> identified,
                                              const std::vector<Eigen::Vector2d>& free_mm) {
  std::vector<SurfaceLabel> out;
  std::vector<Eigen::Vector2d> remaining = free_mm;
  std::vector<int> original(free_mm.size());
  for (size_t k = 0; k < original.size(); ++k) original[k] = static_cast<int>(k);
  for (int pass = 0; pass < kGrowthPasses; ++pass) {
    const auto labels = LabelFromPredictions(predictions, identified, remaining);
    if (labels.empty()) break;
    std::vector<char> used_prediction(predictions.size(), 0), used_free(remaining.size(), 0);
    for (const auto& l : labels) {
      const auto j = static_cast<size_t>(std::find_if(predictions.begin(), predictions.end(),
                                                      [&](const PredictedSpot& p) { return p.id == l.id; }) -
                                         predictions.begin());
      const Eigen::Vector2d& d = remaining[l.free_index];
      identified.push_back({d, (predictions[j].position_mm - d).norm()});
      used_prediction[j] = used_free[l.free_index] = 1;
      out.push_back({l.id, original[l.free_index]});
    }
    std::vector<PredictedSpot> kept_predictions;
    for (size_t j = 0; j < predictions.size(); ++j) {
      if (!used_prediction[j]) kept_predictions.push_back(predictions[j]);
    }
    predictions = std::move(kept_predictions);
    std::vector<Eigen::Vector2d> kept_free;
    std::vector<int> kept_original;
    for (size_t k = 0; k < remaining.size(); ++k) {
      if (!used_free[k]) kept_free.push_back(remaining[k]), kept_original.push_back(original[k]);
    }
    remaining = std::move(kept_free);
    original = std::move(kept_original);
  }
  return out;
}

std::vector<SurfaceLabel> LabelShiftedRing(const std::vector<PredictedSpot>& predictions,
                                           const std::vector<IdentifiedAnchor>& identified,
                                           const std::vector<Eigen::Vector2d>& free_mm, const Eigen::Vector2d& centre_mm) {
  std::map<int, std::vector<size_t>> by_ring;
  std::vector<double> spacing(predictions.size(), 0.0);
  for (size_t j = 0; j < predictions.size(); ++j) {
    spacing[j] = UsableSpacing(predictions, j, identified);
    if (spacing[j] > 0) by_ring[predictions[j].id.ring].push_back(j);
  }
  for (const auto& [ring, members] : by_ring) {
    if (static_cast<int>(members.size()) < kMinRingPredictions) continue;
    std::vector<double> s;
    for (size_t j : members) s.push_back(spacing[j]);
    std::nth_element(s.begin(), s.begin() + s.size() / 2, s.end());
    const double step = kRingShiftStep * s[s.size() / 2];
    const auto shifted = [&](size_t j, double delta) -> Eigen::Vector2d {
      const Eigen::Vector2d& p = predictions[j].position_mm;
      return p + delta * (p - centre_mm).normalized();
    };
    // Matches per shift: predictions with a free detection within the gate.
    const int n_steps = static_cast<int>(std::lround(kMaxRingShift / kRingShiftStep));
    std::vector<int> matches(2 * n_steps + 1, 0);
    for (int k = -n_steps; k <= n_steps; ++k) {
      for (size_t j : members) {
        double e1, e2;
        NearestFree(shifted(j, k * step), free_mm, &e1, &e2);
        matches[k + n_steps] += e1 <= kGateSpacings * spacing[j];
      }
    }
    int best = 0;  // index of the best shift; ties go to the smaller shift
    for (int k = 0; k < static_cast<int>(matches.size()); ++k) {
      const bool better = matches[k] > matches[best] ||
                          (matches[k] == matches[best] && std::abs(k - n_steps) < std::abs(best - n_steps));
      if (better) best = k;
    }
    int rival = 0;  // the best shift at least half a spacing away from it
    const int apart = static_cast<int>(std::lround(kRingShiftApart / kRingShiftStep));
    for (int k = 0; k < static_cast<int>(matches.size()); ++k) {
      if (std::abs(k - best) >= apart) rival = std::max(rival, matches[k]);
    }
    if (matches[best] < kRingShiftShare * members.size() || matches[best] < kRingShiftRivalRatio * rival) continue;
    std::vector<PredictedSpot> moved = predictions;
    for (size_t j : members) moved[j].position_mm = shifted(j, (best - n_steps) * step);
    std::vector<SurfaceLabel> out;
    for (const auto& l : GrowFromPredictions(moved, identified, free_mm)) {
      if (l.id.ring == ring) out.push_back(l);
    }
    if (!out.empty()) return out;
  }
  return {};
}

namespace {

// *m with `labels` added (moved from its free detections; counted from `base`, the capture's counts before any
// surface check) in *trial; returns how many were added (a label outside the distortion's invertible domain is not).
int WithLabels(const SpotMeasurement& m, const std::vector<SurfaceLabel>& labels, const model::Device& device,
               CaptureQuality* base, SpotMeasurement* trial) {
  *trial = m;
  std::vector<char> taken(m.free_mm.size(), 0);
  int added = 0;
  for (const auto& l : labels) {
    const Eigen::Vector2d& mm = m.free_mm[l.free_index];
    const auto undistorted = model::Undistort(device.distortion, mm);
    if (!undistorted) continue;
    taken[l.free_index] = 1;
    trial->detected.push_back({l.id, mm});
    trial->spots.push_back({l.id, *undistorted});
    std::erase(trial->missing_ids, l.id);
    ++added;
  }
  trial->free_mm.clear();
  for (size_t k = 0; k < taken.size(); ++k) {
    if (!taken[k]) trial->free_mm.push_back(m.free_mm[k]);
  }
  const auto by_id = [](const auto& a, const auto& b) { return a.id < b.id; };
  std::sort(trial->detected.begin(), trial->detected.end(), by_id);
  std::sort(trial->spots.begin(), trial->spots.end(), by_id);
  trial->indexed += added;
  trial->unassigned -= added;
  trial->missing -= added;
  base->surface_labelled += added;
  base->identified += added;
  base->usable += added;
  base->unassigned -= added;
  base->visible_fraction = base->designed > 0 ? static_cast<double>(base->identified) / base->designed : 0.0;
  trial->capture = *base;
  return added;
}

// A measurement with its analysis and the capture's counts before the surface's check.
struct Labelled {
  SpotMeasurement m;
  CaptureQuality base;
  topo::Analysis analysis;
};

}  // namespace

topo::Analysis LabelThroughSurface(SpotMeasurement* m, const model::Device& device, const model::Config& config,
                                   const std::function<topo::Analysis(const std::vector<model::PlaneSpot>&)>& analyze) {
  Labelled now{*m, m->capture, {}};
  now.analysis = RejectSurfaceOutliers(now.m.spots, analyze, &now.m.capture);
  // The last state whose surface represents every identified spot: a blend zone may make the model miss while its
  // rings are being added (the data end at the blend) and fit again once the rings beyond are in; a wrong identity
  // keeps it missing.
  std::optional<Labelled> fitting;
  if (topo::ModelFitsData(now.analysis.reconstruction)) fitting = now;
  const Labelled initial = now;
  for (int round = 0; round < kMaxLabellingRounds; ++round) {
    if (!now.analysis.reconstruction.ok || now.m.missing_ids.empty() || now.m.free_mm.empty()) break;
    const auto predictions = PredictSpots(now.analysis.reconstruction, now.m.missing_ids, device, config);
    const auto anchors = Anchors(now.analysis.reconstruction, now.m.detected, device, config);
    auto labels = GrowFromPredictions(predictions, anchors, now.m.free_mm);
    if (labels.empty()) labels = LabelShiftedRing(predictions, anchors, now.m.free_mm, PatternCentre(now.m.detected));
    Labelled next{{}, now.base, {}};
    if (WithLabels(now.m, labels, device, &next.base, &next.m) == 0) break;
    next.analysis = RejectSurfaceOutliers(next.m.spots, analyze, &next.m.capture);
    if (!next.analysis.reconstruction.ok) break;  // the round's identities are withdrawn
    now = std::move(next);
    if (topo::ModelFitsData(now.analysis.reconstruction)) fitting = now;
  }
  if (!topo::ModelFitsData(now.analysis.reconstruction)) now = fitting ? *fitting : initial;
  *m = std::move(now.m);
  return std::move(now.analysis);
}

}  // namespace topocal::pipeline
