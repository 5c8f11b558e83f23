#pragma once
// The pieces the spot indexer (correct/spot_index.cc) builds its identities from: the designed pattern as a lattice
// with neighbourhoods, a bucket grid of detections for nearest-neighbour queries, and the local affine map that
// predicts where a designed spot lies in the image from its identified neighbours.
#include <algorithm>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "model/config.h"
#include "model/null_screen.h"

namespace topocal::correct::lattice {

// The designed pattern: spots, their rings, the local spacing of each spot (min of its arc and ring spacing, ideal
// image mm) and its neighbours (designed spots within `kNeighbourSpacings` local spacings, nearest first).
struct Template {
  std::vector<model::IdealSpot> spots;
  std::vector<std::vector<int>> rings;   // indices into spots, per ring (0-based ring number)
  std::vector<double> spacing;           // per spot
  std::vector<std::vector<int>> neighbours;
  double ring_step = 0;
};
inline constexpr double kNeighbourSpacings = 2.6;
Template MakeTemplate(const model::IdealImageParams& ideal);
// The indices of the spots of the first `rings` rings.
std::vector<int> InnerSpots(const Template& tpl, int rings);

// Detections in square buckets. Written here because the queries are tiny and many (OpenCV's FLANN builds a tree
// per call and returns through matrices; a grid is the whole job in a few lines and exact).
class DetectionGrid {
 public:
  DetectionGrid(const std::vector<Eigen::Vector2d>& points, double cell);
  // The nearest and second-nearest points within `radius` of p that `usable(i)` accepts (-1 when none).
  template <typename Usable>
  void Nearest2(const Eigen::Vector2d& p, double radius, const Usable& usable, int* best, double* best_d,
                int* second, double* second_d) const;
  // The nearest point within `radius` (-1 when none).
  int Nearest(const Eigen::Vector2d& p, double radius, double* d) const {
    int second;
    double second_d;
    int best;
    Nearest2(p, radius, [](int) { return true; }, &best, d, &second, &second_d);
    return best;
  }

 private:
  const std::vector<Eigen::Vector2d>& points_;
  double cell_;
  Eigen::Vector2d origin_;
  int nx_ = 0, ny_ = 0;
  std::vector<int> start_, items_;  // CSR buckets
};

// Distance to the nearest detection on a raster (cv::distanceTransform) over a square about `centre`: the
// indexer's start scores tens of thousands of hypotheses, each by a few dozen lookups.
class DistanceField {
 public:
  DistanceField(const std::vector<Eigen::Vector2d>& points, const Eigen::Vector2d& centre, double half_width,
                double cell);
  // Distance from p to the nearest point, capped at `cap` (and `cap` outside the raster).
  double At(const Eigen::Vector2d& p, double cap) const {
    const double x = (p.x() - origin_.x()) / cell_ + 0.5, y = (p.y() - origin_.y()) / cell_ + 0.5;
    if (!(x >= 0 && y >= 0 && x < dist_.cols && y < dist_.rows)) return cap;
    const double d = cell_ * dist_.ptr<float>(static_cast<int>(y))[static_cast<int>(x)];
    return d < cap ? d : cap;
  }

 private:
  Eigen::Vector2d origin_;
  static constexpr double kMaxCells = 2048;
  double cell_;
  cv::Mat dist_;
};

// p(q) = offset + linear (q - q0): the image of designed position q near q0.
struct LocalAffine {
  Eigen::Vector2d q0 = Eigen::Vector2d::Zero(), offset = Eigen::Vector2d::Zero();
  Eigen::Matrix2d linear = Eigen::Matrix2d::Identity();
  Eigen::Vector2d operator()(const Eigen::Vector2d& q) const { return offset + linear * (q - q0); }
  // Smallest singular value of `linear`: the factor by which the image shrinks spacings at worst.
  double MinScale() const;
};

// Fits the local affine map at designed spot j from the assigned neighbours of j (det_of_tpl[k] >= 0, k != j), each
// weighted by 1 / (distance to j)^2 so the nearest dominate. Fails (false) with fewer than three neighbours or when
// they do not span both directions (all on one arc: the radial scale unknown): their spread's smaller standard
// deviation below `min_spread_spacings` x the spot's spacing.
bool FitLocalAffine(const Template& tpl, int j, const std::vector<int>& det_of_tpl,
                    const std::vector<Eigen::Vector2d>& det, double min_spread_spacings, LocalAffine* out);

// Least-squares affine map through all pairs (q_k, p_k); false when degenerate.
bool FitAffine(const std::vector<Eigen::Vector2d>& q, const std::vector<Eigen::Vector2d>& p, LocalAffine* out);

// ---- implementation of the template member ----
template <typename Usable>
void DetectionGrid::Nearest2(const Eigen::Vector2d& p, double radius, const Usable& usable, int* best, double* best_d,
                             int* second, double* second_d) const {
  *best = *second = -1;
  *best_d = *second_d = radius;
  if (nx_ == 0) return;
  // Cell ranges clamped in floating point first: a wild prediction must not overflow the cast.
  const auto cell = [&](double v, double o, int n) {
    return static_cast<int>(std::clamp((v - o) / cell_, -1.0, static_cast<double>(n)));
  };
  const int x0 = std::max(0, cell(p.x() - radius, origin_.x(), nx_));
  const int x1 = std::min(nx_ - 1, cell(p.x() + radius, origin_.x(), nx_));
  const int y0 = std::max(0, cell(p.y() - radius, origin_.y(), ny_));
  const int y1 = std::min(ny_ - 1, cell(p.y() + radius, origin_.y(), ny_));
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const int c = y * nx_ + x;
      for (int k = start_[c]; k < start_[c + 1]; ++k) {
        const int i = items_[k];
        const double d = (points_[i] - p).norm();
        if (d >= *second_d || !usable(i)) continue;
        if (d < *best_d) {
          *second = *best;
          *second_d = *best_d;
          *best = i;
          *best_d = d;
        } else {
          *second = i;
          *second_d = d;
        }
      }
    }
  }
}

}  // namespace topocal::correct::lattice
