#include "correct/detect_and_index.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include <Eigen/LU>

#include <fmt/format.h>

#include "model/null_screen_layout.h"

namespace topocal::correct {

std::vector<model::ImageSpot> DetectAndIndexResult::AsImageSpots() const {
  std::vector<model::ImageSpot> out;
  out.reserve(spots.size());
  for (const auto& s : spots) {
    model::ImageSpot is;
    is.id = s.id;
    is.position_mm = s.position_mm;
    is.on_surface_mm.setZero();
    out.push_back(is);
  }
  return out;
}

namespace {

// Which of the eight orientations the key's gaps support. The image's identities are those of the pattern as the
// declared orientation maps it; if the image is really turned by R relative to the declaration (R = M_declared^T
// M_actual), the gap at ideal position q shows at R q, so the identity nearest R q is missing and the one at q is
// taken by a real spot. Hypothesis R is consistent when none of the identities at R q_k is taken.
OrientationCheck CheckOrientation(const std::set<model::SpotId>& taken, const model::TopographerCamera& camera,
                                  const model::IdealImageParams& ideal) {
  OrientationCheck out;
  const auto keys = model::OrientationKeySpots(ideal);
  if (keys.empty()) {
    out.message = "orientation: NOT verifiable (the null screen has no orientation key): an undeclared mirrored or "
                  "rotated image mirrors or turns the astigmatism axis unnoticed (docs/image-orientation.md)";
    return out;
  }
  const auto ideal_spots = model::IdealImage(ideal);
  const auto position_of = [&](const model::SpotId& id) {
    for (const auto& s : ideal_spots) {
      if (s.id == id) return s.position_mm;
    }
    return Eigen::Vector2d(Eigen::Vector2d::Zero());
  };
  const auto nearest_id = [&](const Eigen::Vector2d& q) {
    const model::IdealSpot* best = &ideal_spots.front();
    for (const auto& s : ideal_spots) {
      if ((s.position_mm - q).squaredNorm() < (best->position_mm - q).squaredNorm()) best = &s;
    }
    return best->id;
  };
  out.key_spots = static_cast<int>(keys.size());
  std::vector<model::ImageOrientation> consistent;
  constexpr model::ImageOrientation kAll[] = {
      model::ImageOrientation::kIdentity, model::ImageOrientation::kRotate90,  model::ImageOrientation::kRotate180,
      model::ImageOrientation::kRotate270, model::ImageOrientation::kFlipU,    model::ImageOrientation::kFlipV,
      model::ImageOrientation::kTranspose, model::ImageOrientation::kTransverse};
  for (const auto r : kAll) {
    const Eigen::Matrix2d rm = model::OrientationMatrix(r);
    int occupied = 0;
    for (const auto& k : keys) occupied += taken.count(nearest_id(rm * position_of(k))) > 0;
    if (r == model::ImageOrientation::kIdentity) out.key_occupied = occupied;
    if (occupied == 0) consistent.push_back(r);
  }
  const char* declared = model::OrientationName(camera.orientation);
  if (out.key_occupied == 0) {
    out.status = consistent.size() == 1 ? OrientationCheck::Status::kConfirmed : OrientationCheck::Status::kUndetermined;
    out.message = consistent.size() == 1
                      ? fmt::format("orientation: confirmed by the null screen's key ({} as declared)", declared)
                      : fmt::format("orientation: the key's gaps fit the declared {} but also {} other orientation(s) "
                                    "(too many spots missing around them); not confirmed",
                                    declared, consistent.size() - 1);
    return out;
  }
  out.status = OrientationCheck::Status::kMismatch;
  std::string apparent_text = "no orientation fits the key's gaps either (a wrong configuration or device?)";
  if (!consistent.empty()) {
    // M_actual = M_declared R.
    const Eigen::Matrix2d actual = camera.Orientation() * model::OrientationMatrix(consistent.front());
    for (const auto o : kAll) {
      if ((model::OrientationMatrix(o) - actual).norm() < 1e-9) out.apparent = o;
    }
    const bool mirrored = model::OrientationMatrix(consistent.front()).determinant() < 0;
    apparent_text = fmt::format("the image looks {} relative to the declaration, i.e. its orientation is {}",
                                mirrored ? "mirrored" : "rotated", model::OrientationName(*out.apparent));
  }
  out.message = fmt::format(
      "orientation refused: {} of the null screen's {} orientation-key gaps are occupied, so the image is not "
      "oriented as the camera file declares ({}); {}. Likely cause: a mirrored or rotated image (sensor readout, "
      "mirror, phone API) or a wrong `orientation` in the camera/device file",
      out.key_occupied, out.key_spots, declared, apparent_text);
  return out;
}

// The median nearest-neighbour distance of the identified spots: the pattern's local spacing.
double MedianSpacing(const SpotIndexing& idx) {
  std::vector<double> nearest;
  for (const auto& a : idx.spots) {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& b : idx.spots) {
      if (&a != &b) best = std::min(best, (a.position - b.position).norm());
    }
    if (std::isfinite(best)) nearest.push_back(best);
  }
  if (nearest.empty()) return 0;
  std::nth_element(nearest.begin(), nearest.begin() + nearest.size() / 2, nearest.end());
  return nearest[nearest.size() / 2];
}

// kFluxOutlier (DetectAndIndexOptions): the spot's light against the median of its identified ring neighbours
// (indices +-1, +-2, cyclic). Like spots on a ring carry like light — their images change size slowly along it —
// so a spot that lost part of its light to a lash's shadow, the lid margin or a dry patch, or gained a glint's, shows
// as an outlier, and its centre is pulled by what was lost or added. Where fewer than three ring neighbours are
// identified (at a lid's margin, beside a lash), the spot is judged against every identified spot of its ring (at
// least three), else against the nearest identified spot of each neighbouring ring within kAdjacentRingSpacings
// spacings (one suffices), and flagged only outside 0.5-2 times their median: a glint or a lash's fragment taken for a hidden spot at the lid's margin carries a tenth
// of a spot's light (measured 0.07-0.15 on the all-artefact captures), and without neighbours to compare with it
// went unjudged.
void FlagFluxOutliers(const model::IdealImageParams& ideal, const SpotIndexing& idx, const DetectAndIndexOptions& o,
                      SpotDetection* detection) {
  constexpr double kAdjacentRingSpacings = 2.0, kFarFluxLow = 0.5, kFarFluxHigh = 2.0;
  std::map<model::SpotId, double> flux;
  for (const auto& s : idx.spots) flux[s.id] = detection->spots[s.detection].flux_dn;
  const double reach = kAdjacentRingSpacings * MedianSpacing(idx);
  for (const auto& s : idx.spots) {
    const int on_ring = ideal.eta0 + ideal.eta * (s.id.ring - 1);
    if (on_ring <= 0) continue;
    std::vector<double> around;
    double low = o.flux_low, high = o.flux_high;
    for (const int step : {-2, -1, 1, 2}) {
      const auto it = flux.find(model::SpotId{s.id.ring, ((s.id.index + step) % on_ring + on_ring) % on_ring});
      if (it != flux.end() && it->first != s.id) around.push_back(it->second);
    }
    if (around.size() < 3) {
      // Spots further along the ring or on the next ring differ more: only a gross deficit or excess is judged.
      low = kFarFluxLow;
      high = kFarFluxHigh;
      around.clear();
      for (const auto& t : idx.spots) {
        if (t.id.ring == s.id.ring && !(t.id == s.id)) around.push_back(flux[t.id]);
      }
    }
    if (around.size() < 3) {
      around.clear();
      for (const int ring : {s.id.ring - 1, s.id.ring + 1}) {
        const IndexedSpot* nearest = nullptr;
        for (const auto& t : idx.spots) {
          if (t.id.ring != ring) continue;
          if (!nearest || (t.position - s.position).norm() < (nearest->position - s.position).norm()) nearest = &t;
        }
        if (nearest && (nearest->position - s.position).norm() <= reach) around.push_back(flux[nearest->id]);
      }
      if (around.empty()) continue;
    }
    std::sort(around.begin(), around.end());
    const double median = around.size() % 2 ? around[around.size() / 2]
                                             : 0.5 * (around[around.size() / 2 - 1] + around[around.size() / 2]);
    const double own = flux[s.id];
    if (own < low * median || own > high * median) detection->spots[s.detection].flags |= kFluxOutlier;
  }
}

}  // namespace

DetectAndIndexResult DetectAndIndexSpots(const cv::Mat& image, const model::TopographerCamera& camera,
                                         const model::IdealImageParams& ideal, const DetectAndIndexOptions& options) {
  DetectAndIndexResult out;
  out.detection = DetectSpots(image, options.detection);
  std::vector<Eigen::Vector2d> mm;
  mm.reserve(out.detection.spots.size());
  for (const auto& s : out.detection.spots) mm.push_back(camera.DetectionPlaneFromPixel(s.centre_px));
  const SpotIndexing idx = IndexSpots(mm, ideal, options.indexing);
  FlagFluxOutliers(ideal, idx, options, &out.detection);
  std::set<model::SpotId> taken;
  for (const auto& s : idx.spots) {
    const auto& d = out.detection.spots[s.detection];
    LocatedSpot l{s.id, d.flags, d.centre_px, mm[s.detection], d.area_px, d.flux_dn};
    (d.flags & options.exclude_flags ? out.excluded : out.spots).push_back(l);
    taken.insert(s.id);
  }
  for (const int i : idx.unassigned_detections) {
    const auto& d = out.detection.spots[i];
    out.unassigned.push_back({model::SpotId{0, i}, d.flags, d.centre_px, mm[i], d.area_px, d.flux_dn});
  }
  out.missing = idx.missing;
  out.index_residual_rms_mm = idx.residual_rms;
  out.refused_identities = idx.dropped;
  out.ok = idx.ok;
  out.message = idx.message;
  if (out.ok) {
    out.orientation = CheckOrientation(taken, camera, ideal);
    if (out.orientation.status == OrientationCheck::Status::kMismatch) {
      out.ok = false;
      out.message = out.orientation.message;
    }
  }
  return out;
}

}  // namespace topocal::correct
