// The pattern matcher's start (correct/spot_index_state.h): where the pattern's centre is and how rings 1-3 map
// onto the detections.
#include <algorithm>
#include <cmath>
#include <vector>

#include <fmt/format.h>

#include "correct/spot_index_state.h"
#include "util/median.h"

namespace topocal::correct::spot_index_detail {
namespace {

using lattice::DistanceField;
using lattice::InnerSpots;
using lattice::LocalAffine;
using util::Median;

struct Hypothesis {
  Eigen::Vector2d centre;
  double scale = 1, score = 0;
  Eigen::Matrix2d shape = Eigen::Matrix2d::Identity();  // the map's linear part at unit scale
};

// The shapes of the second start (StartCandidates' `sheared`): stretches of 6 and 12 % along 0, 45, 90 and 135 deg
// (the first start searched the unstretched shape). A severe cone beside the apex stretches the inner rings (a
// 60 um cone 0.9 mm from the apex of a 26-ring screen: 11 % along -37 deg), which no isotropic hypothesis reaches
// within the gate, while the cone's flank offers isotropic false centres. Rotations of +-5 deg as well found no
// more starts on the test eyes and tripled the work.
std::vector<Eigen::Matrix2d> ShearedShapes() {
  const auto rotation = [](double deg) {
    const double t = deg * M_PI / 180.0;
    Eigen::Matrix2d r;
    r << std::cos(t), -std::sin(t), std::sin(t), std::cos(t);
    return r;
  };
  std::vector<Eigen::Matrix2d> shapes;
  for (const double stretch : {0.06, 0.12}) {
    for (const double axis : {0.0, 45.0, 90.0, 135.0}) {
      const Eigen::Matrix2d diagonal = Eigen::Vector2d(1 + stretch, 1 - stretch).asDiagonal();
      shapes.push_back(rotation(axis) * diagonal * rotation(-axis));
    }
  }
  return shapes;
}

// Coarse search over centres and scales (of each shape), scored on rings 1-2 by sum min(d, gate)^2 / gate^2 (0 for a
// perfect match, ~0.75 per spot for points that only land somewhere on the lattice). The gate and the grid are set
// by the image's own spot spacing (`image_spacing`: the median distance between neighbouring detections), not by the
// hypothesis' scale, so that no scale is favoured; scales are searched around the one that spacing implies. The grid
// (a quarter spacing, 5 % in scale) keeps the true hypothesis within ~0.25 spacings of every inner spot of a
// near-isotropic image, inside the 0.4-spacing gate. Each of `shapes` (the linear part at unit scale) is searched
// alike. Returns the best dozen, a spot spacing apart.
std::vector<Hypothesis> CoarseStart(const State& st, const Eigen::Vector2d& around, double radius,
                                    double image_spacing, double scale_lo, double scale_hi,
                                    const std::vector<Eigen::Matrix2d>& shapes) {
  const std::vector<int> ids = InnerSpots(st.tpl, 2);
  double reach = 0;
  for (const int j : ids) reach = std::max(reach, st.tpl.spots[j].position_mm.norm());
  const double step = 0.25 * image_spacing, gate = 0.4 * image_spacing;
  const DistanceField field(st.det, around, radius + scale_hi * reach + gate, 0.08 * image_spacing);
  // Only the best kKept hypotheses matter (a true centre spawns a few dozen near-duplicates over neighbouring grid
  // points and scales): a hypothesis stops adding spots once its sum passes the worst of those kept.
  constexpr size_t kKept = 600;
  const auto worse = [](const Hypothesis& a, const Hypothesis& b) { return a.score < b.score; };
  std::vector<Hypothesis> all;  // a max-heap on score while it is full
  all.reserve(kKept + 1);
  std::vector<Eigen::Vector2d> offsets(ids.size());
  const int n = static_cast<int>(std::ceil(radius / step));
  const double gate2 = gate * gate;
  for (const Eigen::Matrix2d& shape : shapes) {
    for (double s = scale_lo; s <= scale_hi * 1.0001; s *= 1.05) {
      for (size_t k = 0; k < ids.size(); ++k) offsets[k] = s * shape * st.tpl.spots[ids[k]].position_mm;
      for (int iy = -n; iy <= n; ++iy) {
        for (int ix = -n; ix <= n; ++ix) {
          if (ix * ix + iy * iy > n * n) continue;
          const Eigen::Vector2d c = around + Eigen::Vector2d(ix * step, iy * step);
          const double bound = all.size() == kKept ? all.front().score * gate2 : 1e300;
          double sum = 0;
          for (size_t k = 0; k < offsets.size() && sum < bound; ++k) {
            const double d = field.At(c + offsets[k], gate);
            sum += d * d;
          }
          if (sum >= bound) continue;
          all.push_back({c, s, sum / gate2, shape});
          std::push_heap(all.begin(), all.end(), worse);
          if (all.size() > kKept) {
            std::pop_heap(all.begin(), all.end(), worse);
            all.pop_back();
          }
        }
      }
    }
  }
  std::sort(all.begin(), all.end(), [](const Hypothesis& a, const Hypothesis& b) { return a.score < b.score; });
  std::vector<Hypothesis> best;
  for (const auto& h : all) {
    bool distinct = true;
    for (const auto& b : best) distinct &= (h.centre - b.centre).norm() > image_spacing;
    if (distinct) best.push_back(h);
    if (best.size() == 12) break;
  }
  return best;
}

// A coarse hypothesis refined to the affine map that best carries rings 1-3 onto the detections (nearest
// detections within 0.4 local spacings, refitted three times), scored like the coarse search with a 0.3-spacing
// gate. An eye's inner rings are an affine image of the design to a few hundredths of a spacing; a cone near the
// apex bends them by tenths, which the affine refinement absorbs where an isotropic grid cannot.
double RefineAffine(const State& st, const std::vector<int>& ids, LocalAffine* map) {
  for (int it = 0; it < 4; ++it) {
    std::vector<Eigen::Vector2d> q, p;
    const double shrink = map->MinScale();
    for (const int j : ids) {
      double d;
      const int i = st.grid.Nearest((*map)(st.tpl.spots[j].position_mm), 0.4 * shrink * st.tpl.spacing[j], &d);
      if (i < 0) continue;
      q.push_back(st.tpl.spots[j].position_mm);
      p.push_back(st.det[i]);
    }
    LocalAffine fitted;
    if (q.size() < 6 || !lattice::FitAffine(q, p, &fitted)) break;
    *map = fitted;
  }
  double sum = 0;
  const double shrink = map->MinScale();
  for (const int j : ids) {
    const double gate = 0.3 * shrink * st.tpl.spacing[j];
    double d;
    st.grid.Nearest((*map)(st.tpl.spots[j].position_mm), gate, &d);
    sum += d * d / (gate * gate);
  }
  return sum;
}

// Assigns the designed spots `ids` predicted by `map` to their nearest free detections within gate_fraction x the
// local spacing, when detection and spot are each other's nearest. Returns the number assigned.
int AssignMutualNearest(State& st, const std::vector<int>& ids, const LocalAffine& map, double gate_fraction) {
  std::vector<Eigen::Vector2d> pred;
  for (const int j : ids) pred.push_back(map(st.tpl.spots[j].position_mm));
  const double shrink = map.MinScale();
  int added = 0;
  for (size_t a = 0; a < ids.size(); ++a) {
    const int j = ids[a];
    const double gate = gate_fraction * st.tpl.spacing[j] * shrink;
    double d;
    const int i = st.grid.Nearest(pred[a], gate, &d);
    if (i < 0 || st.tpl_of_det[i] >= 0 || st.det_of_tpl[j] >= 0) continue;
    bool mutual = true;
    for (size_t b = 0; b < ids.size() && mutual; ++b) mutual = b == a || (st.det[i] - pred[b]).norm() > d;
    if (mutual) {
      st.Assign(j, i);
      ++added;
    }
  }
  return added;
}

}  // namespace

// The start's candidates: the coarse hypotheses refined to affine maps of rings 1-3, best (lowest score) first.
// Empty, with the reason, when the detections give no hypothesis.
std::vector<LocalAffine> StartCandidates(const State& st, const IndexingOptions& o, double rho_n, bool sheared,
                                         std::string* why) {
  const std::vector<int> inner = InnerSpots(st.tpl, 3);
  if (st.det.size() < inner.size()) {
    *why = fmt::format("{} detections, fewer than the {} spots of the pattern's three inner rings (merged or missing "
                       "spots)", st.det.size(), inner.size());
    return {};
  }
  std::vector<double> xs, ys;
  for (const auto& p : st.det) {
    xs.push_back(p.x());
    ys.push_back(p.y());
  }
  const Eigen::Vector2d median(Median(xs), Median(ys));
  // The image's spot spacing: the median distance from a detection to its nearest neighbour; against the design's,
  // the pattern's scale (to the spread of spacings across the pattern, which the search covers).
  std::vector<double> nn_image, nn_design;
  for (const auto& p : st.det) {
    int best, second;
    double d1, d2;
    st.grid.Nearest2(p, 4 * st.tpl.ring_step * o.max_scale, [](int) { return true; }, &best, &d1, &second, &d2);
    if (second >= 0) nn_image.push_back(d2);  // the nearest is the detection itself
  }
  for (size_t j = 0; j < st.tpl.spots.size(); ++j) {
    nn_design.push_back((st.tpl.spots[st.tpl.neighbours[j].front()].position_mm - st.tpl.spots[j].position_mm).norm());
  }
  const double image_spacing = Median(nn_image);
  if (!(image_spacing > 0)) {
    *why = "the detections have no neighbours at the pattern's spacing";
    return {};
  }
  const double scale = image_spacing / Median(nn_design);
  const auto coarse = CoarseStart(st, median, o.centre_search_fraction * rho_n, image_spacing,
                                  std::max(o.min_scale, 0.75 * scale), std::min(o.max_scale, 1.33 * scale),
                                  sheared ? ShearedShapes() : std::vector<Eigen::Matrix2d>{Eigen::Matrix2d::Identity()});
  std::vector<std::pair<double, LocalAffine>> refined;
  for (const auto& h : coarse) {
    LocalAffine m;
    m.offset = h.centre;
    m.linear = h.scale * h.shape;
    const double score = RefineAffine(st, inner, &m);
    refined.emplace_back(score, m);
  }
  std::stable_sort(refined.begin(), refined.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<LocalAffine> out;
  for (const auto& r : refined) out.push_back(r.second);
  if (out.empty()) *why = "no candidate centre for the pattern";
  return out;
}

// Rings 1-3 identified from a start candidate by mutual nearest neighbours, the affine map refitted once. False,
// with the reason, when fewer than half of them are found.
bool Seed(State& st, LocalAffine map, const IndexingOptions& o, std::string* why) {
  const std::vector<int> inner = InnerSpots(st.tpl, 3);
  const int needed = static_cast<int>(inner.size()) / 2;
  for (int pass = 0; pass < 2; ++pass) {
    for (const int j : inner) {
      if (st.det_of_tpl[j] >= 0) st.Unassign(j);
    }
    if (AssignMutualNearest(st, inner, map, o.gate_fraction) < needed) break;
    std::vector<Eigen::Vector2d> q, p;
    for (const int j : inner) {
      if (st.det_of_tpl[j] < 0) continue;
      q.push_back(st.tpl.spots[j].position_mm);
      p.push_back(st.det[st.det_of_tpl[j]]);
    }
    if (!lattice::FitAffine(q, p, &map)) break;
  }
  if (st.Assigned() < needed) {
    *why = fmt::format("the pattern's centre was not found: at most {} of the {} spots of rings 1-3 where the best "
                       "centre puts them (need {}); is the centre of the pattern covered or out of the image?",
                       st.Assigned(), inner.size(), needed);
    return false;
  }
  return true;
}

}  // namespace topocal::correct::spot_index_detail
