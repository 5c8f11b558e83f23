#include "correct/spot_lattice.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

namespace topocal::correct::lattice {

Template MakeTemplate(const model::IdealImageParams& ideal) {
  Template t;
  t.spots = model::IdealImage(ideal);
  t.rings.resize(ideal.rings_N + 1);
  t.ring_step = model::RingStepMm(ideal);
  const int n = static_cast<int>(t.spots.size());
  for (int i = 0; i < n; ++i) {
    const auto& s = t.spots[i];
    t.rings[s.id.ring - 1].push_back(i);
    const double arc = 2.0 * M_PI * s.position_mm.norm() / model::SpotsOnRing(ideal, s.id.ring);
    t.spacing.push_back(std::min(arc, t.ring_step));
  }
  t.neighbours.resize(n);
  // Candidates by distance from the centre: a spot within `reach` of spot i lies within `reach` of its radius, so
  // only that slice of the radius-sorted spots is measured (the pattern's rings make it a few rings' worth).
  std::vector<std::pair<double, int>> by_radius;
  for (int k = 0; k < n; ++k) by_radius.emplace_back(t.spots[k].position_mm.norm(), k);
  std::sort(by_radius.begin(), by_radius.end());
  for (int i = 0; i < n; ++i) {
    // The neighbourhood's radius from the larger of the two spacings, so that it spans both directions.
    const double radius = t.spots[i].position_mm.norm();
    const double arc = 2.0 * M_PI * radius / model::SpotsOnRing(ideal, t.spots[i].id.ring);
    const double reach = kNeighbourSpacings * std::max(arc, t.ring_step);
    std::vector<std::pair<double, int>> near;
    const double slice = reach + 1e-9;  // mm: rounding of the norms cannot drop a spot at exactly `reach`
    const auto first = std::lower_bound(by_radius.begin(), by_radius.end(), std::make_pair(radius - slice, -1));
    for (auto it = first; it != by_radius.end() && it->first <= radius + slice; ++it) {
      const int k = it->second;
      const double d = (t.spots[k].position_mm - t.spots[i].position_mm).norm();
      if (k != i && d <= reach) near.emplace_back(d, k);
    }
    std::sort(near.begin(), near.end());
    for (const auto& [d, k] : near) t.neighbours[i].push_back(k);
  }
  return t;
}

DetectionGrid::DetectionGrid(const std::vector<Eigen::Vector2d>& points, double cell) : points_(points), cell_(cell) {
  if (points.empty() || !(cell > 0)) return;
  Eigen::Vector2d lo = points.front(), hi = points.front();
  for (const auto& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  origin_ = lo;
  // At most ~4 cells per point: a sparse spread of far blobs must not allocate a huge grid.
  const double max_cells = 4.0 * points.size() + 16;
  while (((hi.x() - lo.x()) / cell_ + 1) * ((hi.y() - lo.y()) / cell_ + 1) > max_cells) cell_ *= 2;
  nx_ = static_cast<int>((hi.x() - lo.x()) / cell_) + 1;
  ny_ = static_cast<int>((hi.y() - lo.y()) / cell_) + 1;
  std::vector<int> cell_of(points.size());
  start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (size_t i = 0; i < points.size(); ++i) {
    const int x = std::min(nx_ - 1, static_cast<int>((points[i].x() - lo.x()) / cell_));
    const int y = std::min(ny_ - 1, static_cast<int>((points[i].y() - lo.y()) / cell_));
    cell_of[i] = y * nx_ + x;
    ++start_[cell_of[i] + 1];
  }
  for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
  items_.resize(points.size());
  std::vector<int> fill(start_.begin(), start_.end() - 1);
  for (size_t i = 0; i < points.size(); ++i) items_[fill[cell_of[i]]++] = static_cast<int>(i);
}

std::vector<int> InnerSpots(const Template& tpl, int rings) {
  std::vector<int> ids;
  for (int r = 0; r < std::min<int>(rings, tpl.rings.size()); ++r) {
    ids.insert(ids.end(), tpl.rings[r].begin(), tpl.rings[r].end());
  }
  return ids;
}

DistanceField::DistanceField(const std::vector<Eigen::Vector2d>& points, const Eigen::Vector2d& centre,
                             double half_width, double cell)
    : origin_(centre - Eigen::Vector2d::Constant(half_width)),
      // At most kMaxCells a side (16 MB): a few stray detections far apart must not ask for gigabytes.
      cell_(std::max(cell, 2 * half_width / (kMaxCells - 1))) {
  const int n = static_cast<int>(std::ceil(2 * half_width / cell_)) + 1;
  cv::Mat seeds(n, n, CV_8UC1, cv::Scalar(255));
  for (const auto& p : points) {
    const Eigen::Vector2d c = (p - origin_) / cell_;
    if (c.x() >= 0 && c.y() >= 0 && c.x() < n - 0.5 && c.y() < n - 0.5) {
      seeds.at<uint8_t>(static_cast<int>(std::lround(c.y())), static_cast<int>(std::lround(c.x()))) = 0;
    }
  }
  cv::distanceTransform(seeds, dist_, cv::DIST_L2, cv::DIST_MASK_PRECISE);
}

double LocalAffine::MinScale() const { return Eigen::JacobiSVD<Eigen::Matrix2d>(linear).singularValues()(1); }

namespace {

// Weighted least squares p_k = offset + linear (q_k - q0).
bool SolveAffine(const std::vector<Eigen::Vector2d>& q, const std::vector<Eigen::Vector2d>& p,
                 const std::vector<double>& w, const Eigen::Vector2d& q0, LocalAffine* out) {
  Eigen::Matrix3d n = Eigen::Matrix3d::Zero();
  Eigen::Matrix<double, 3, 2> b = Eigen::Matrix<double, 3, 2>::Zero();
  for (size_t k = 0; k < q.size(); ++k) {
    const Eigen::Vector3d a(1.0, q[k].x() - q0.x(), q[k].y() - q0.y());
    n += w[k] * a * a.transpose();
    b += w[k] * a * p[k].transpose();
  }
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(n);
  if (ldlt.info() != Eigen::Success) return false;
  const Eigen::Matrix<double, 3, 2> x = ldlt.solve(b);
  if (!x.allFinite()) return false;
  out->q0 = q0;
  out->offset = x.row(0).transpose();
  out->linear.row(0) = x.col(0).tail<2>().transpose();
  out->linear.row(1) = x.col(1).tail<2>().transpose();
  return out->linear.determinant() > 0;  // a fold or a mirror is no image of the pattern
}

}  // namespace

bool FitLocalAffine(const Template& tpl, int j, const std::vector<int>& det_of_tpl,
                    const std::vector<Eigen::Vector2d>& det, double min_spread_spacings, LocalAffine* out) {
  std::vector<Eigen::Vector2d> q, p;
  std::vector<double> w;
  const Eigen::Vector2d& qj = tpl.spots[j].position_mm;
  for (const int k : tpl.neighbours[j]) {
    if (det_of_tpl[k] < 0) continue;
    const Eigen::Vector2d dq = tpl.spots[k].position_mm - qj;
    q.push_back(tpl.spots[k].position_mm);
    p.push_back(det[det_of_tpl[k]]);
    w.push_back(1.0 / dq.squaredNorm());
  }
  if (q.size() < 3) return false;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& v : q) mean += v;
  mean /= static_cast<double>(q.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const auto& v : q) cov += (v - mean) * (v - mean).transpose();
  cov /= static_cast<double>(q.size());
  const double spread = std::sqrt(std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvalues()(0)));
  if (spread < min_spread_spacings * tpl.spacing[j]) return false;
  return SolveAffine(q, p, w, qj, out);
}

bool FitAffine(const std::vector<Eigen::Vector2d>& q, const std::vector<Eigen::Vector2d>& p, LocalAffine* out) {
  if (q.size() < 3) return false;
  return SolveAffine(q, p, std::vector<double>(q.size(), 1.0), Eigen::Vector2d::Zero(), out);
}

}  // namespace topocal::correct::lattice
