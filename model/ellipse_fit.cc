#include "model/ellipse_fit.h"

#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

namespace topocal::model {

std::optional<Ellipse> FitEllipseDirect(const std::vector<Eigen::Vector2d>& points_mm) {
  const int n = static_cast<int>(points_mm.size());
  if (n < 5) return std::nullopt;
  // Centre and scale the data so the scatter matrices are well conditioned.
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : points_mm) mean += p;
  mean /= n;
  double scale = 0;
  for (const auto& p : points_mm) scale = std::max(scale, (p - mean).cwiseAbs().maxCoeff());
  if (!(scale > 0)) return std::nullopt;

  Eigen::MatrixXd D1(n, 3), D2(n, 3);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d q = (points_mm[i] - mean) / scale;
    D1.row(i) << q.x() * q.x(), q.x() * q.y(), q.y() * q.y();
    D2.row(i) << q.x(), q.y(), 1.0;
  }
  const Eigen::Matrix3d S1 = D1.transpose() * D1, S2 = D1.transpose() * D2, S3 = D2.transpose() * D2;
  Eigen::FullPivLU<Eigen::Matrix3d> lu(S3);
  if (!lu.isInvertible()) return std::nullopt;
  const Eigen::Matrix3d T = -lu.solve(S2.transpose());
  const Eigen::Matrix3d M0 = S1 + S2 * T;
  Eigen::Matrix3d M;  // C1^-1 M0 with C1 = [[0,0,2],[0,-1,0],[2,0,0]]
  M.row(0) = M0.row(2) / 2.0;
  M.row(1) = -M0.row(1);
  M.row(2) = M0.row(0) / 2.0;
  Eigen::EigenSolver<Eigen::Matrix3d> es(M);
  int best = -1;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d v = es.eigenvectors().col(k).real();
    if (4.0 * v(0) * v(2) - v(1) * v(1) > 0) best = k;  // the elliptic constraint picks the solution
  }
  if (best < 0) return std::nullopt;
  const Eigen::Vector3d a1 = es.eigenvectors().col(best).real();
  const Eigen::Vector3d a2 = T * a1;
  // Conic A x^2 + B xy + C y^2 + D x + E y + F = 0 in scaled coordinates.
  const double A = a1(0), B = a1(1), C = a1(2), D = a2(0), E = a2(1), F = a2(2);
  const double den = B * B - 4 * A * C;
  if (!(den < 0)) return std::nullopt;
  const double x0 = (2 * C * D - B * E) / den;
  const double y0 = (2 * A * E - B * D) / den;
  // Value of the conic at the centre and the eigen-decomposition of its quadratic part give the semi-axes.
  const double f0 = A * x0 * x0 + B * x0 * y0 + C * y0 * y0 + D * x0 + E * y0 + F;
  Eigen::Matrix2d Q;
  Q << A, B / 2, B / 2, C;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> qs(Q);
  const Eigen::Vector2d axes2 = -f0 * qs.eigenvalues().cwiseInverse();
  if (!(axes2(0) > 0 && axes2(1) > 0)) return std::nullopt;
  const int major = axes2(0) >= axes2(1) ? 0 : 1;
  const double semi_major = std::sqrt(axes2(major)), semi_minor = std::sqrt(axes2(1 - major));
  const Eigen::Vector2d major_dir = qs.eigenvectors().col(major);
  double beta = std::atan2(major_dir.y(), major_dir.x()) * 180.0 / M_PI;
  if (beta <= -90.0) beta += 180.0;
  if (beta > 90.0) beta -= 180.0;
  Ellipse e;
  e.centre_mm = mean + scale * Eigen::Vector2d(x0, y0);
  e.a_mm = semi_major * scale;
  e.b_mm = semi_minor * scale;
  e.beta_deg = beta;
  return e;
}

}  // namespace topocal::model
