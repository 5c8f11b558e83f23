#include "calib/estimate_table.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include <ceres/manifold.h>

namespace topocal::calib {
namespace {

// One entry's row of P: the tangent columns it moves with and by how much (the non-zero plus-Jacobian entries).
using SparseRow = std::vector<std::pair<int, double>>;

// The plus-Jacobian of each block (ambient x tangent, row-major) at its current value; false if one fails.
bool PlusJacobians(const ceres::Problem& problem, const std::vector<double*>& blocks,
                   const TangentCovarianceResult& tangent, std::map<const double*, std::pair<int, Eigen::MatrixXd>>* out) {
  for (size_t b = 0; b < blocks.size(); ++b) {
    const int ambient = problem.ParameterBlockSize(blocks[b]);
    const int size = tangent.tangent_size[b];
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> jacobian(ambient, size);
    const ceres::Manifold* manifold = problem.GetManifold(blocks[b]);
    if (manifold == nullptr) {
      jacobian.setIdentity();
    } else if (!manifold->PlusJacobian(blocks[b], jacobian.data())) {
      return false;
    }
    (*out)[blocks[b]] = {tangent.offset[b], jacobian};
  }
  return true;
}

}  // namespace

void EstimateTable::AddBlock(const std::vector<std::string>& names, const double* block) {
  for (size_t i = 0; i < names.size(); ++i) Add(names[i], block, static_cast<int>(i));
}

std::vector<std::string> EstimateTable::Names() const {
  std::vector<std::string> names;
  for (const auto& e : entries_) names.push_back(e.name);
  return names;
}

std::vector<double> EstimateTable::Values() const {
  std::vector<double> values;
  for (const auto& e : entries_) values.push_back(e.block[e.index]);
  return values;
}

std::optional<Eigen::MatrixXd> EstimateTable::Covariance(const ceres::Problem& problem,
                                                         const std::vector<double*>& blocks,
                                                         const TangentCovarianceResult& tangent, double variance_scale,
                                                         std::string* why) const {
  std::map<const double*, std::pair<int, Eigen::MatrixXd>> jacobians;
  if (!PlusJacobians(problem, blocks, tangent, &jacobians)) {
    if (why) *why = "internal: a parameter block's plus-Jacobian failed";
    return std::nullopt;
  }
  std::vector<SparseRow> rows(entries_.size());
  for (size_t i = 0; i < entries_.size(); ++i) {
    const auto it = jacobians.find(entries_[i].block);
    if (it == jacobians.end()) continue;  // a constant block: held
    const auto& [offset, jacobian] = it->second;
    for (int t = 0; t < jacobian.cols(); ++t) {
      const double w = jacobian(entries_[i].index, t);
      if (w != 0) rows[i].emplace_back(offset + t, w);
    }
  }
  // Summed entry by entry over the non-zero weights only: a held parameter's rows stay an exact +0, and a parameter
  // that is one tangent coordinate (every block here but the tied fx, fy) gets that coordinate's variance exactly.
  const int n = size();
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      double sum = 0.0;
      for (const auto& [k, wi] : rows[static_cast<size_t>(i)]) {
        for (const auto& [l, wj] : rows[static_cast<size_t>(j)]) sum += (wi * tangent.matrix(k, l)) * wj;
      }
      cov(i, j) = sum * variance_scale;
    }
  }
  if (!cov.allFinite()) {
    if (why) *why = "non-finite parameter covariance";
    return std::nullopt;
  }
  return cov;
}

std::vector<double> EstimateTable::StandardDeviations(const Eigen::MatrixXd& covariance) {
  std::vector<double> sd(static_cast<size_t>(covariance.rows()), 0.0);
  for (int i = 0; i < covariance.rows(); ++i) {
    const double var = covariance(i, i);
    sd[static_cast<size_t>(i)] = var > 0 ? std::sqrt(var) : 0.0;
  }
  return sd;
}

}  // namespace topocal::calib
