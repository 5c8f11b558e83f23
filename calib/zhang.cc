#include "calib/zhang.h"

#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

namespace topocal::calib {
namespace {

// v_ij of Zhang Eq. 8 for the columns i, j of H: h_i' B h_j = v_ij' b with b = [B11 B12 B22 B13 B23 B33].
Eigen::Matrix<double, 1, 6> ConstraintRow(const Eigen::Matrix3d& h, int i, int j) {
  Eigen::Matrix<double, 1, 6> v;
  v << h(0, i) * h(0, j), h(0, i) * h(1, j) + h(1, i) * h(0, j), h(1, i) * h(1, j),
      h(2, i) * h(0, j) + h(0, i) * h(2, j), h(2, i) * h(1, j) + h(1, i) * h(2, j), h(2, i) * h(2, j);
  return v;
}

Eigen::Vector3d RotationToAngleAxis(const Eigen::Matrix3d& r) {
  const Eigen::AngleAxisd aa(r);
  return aa.angle() * aa.axis();
}

}  // namespace

std::optional<Eigen::Matrix3d> TargetToImageHomography(const ViewObservations& view) {
  if (view.corners.size() < 4) return std::nullopt;
  std::vector<cv::Point2d> target, image;
  for (const auto& c : view.corners) {
    target.emplace_back(c.target_mm.x(), c.target_mm.y());
    image.emplace_back(c.image_px.x(), c.image_px.y());
  }
  // method 0: all points, normalised DLT followed by Levenberg-Marquardt on the reprojection error.
  const cv::Mat h = cv::findHomography(target, image, 0);
  if (h.empty()) return std::nullopt;
  Eigen::Matrix3d out;
  cv::cv2eigen(h, out);
  if (!out.allFinite()) return std::nullopt;
  return out;
}

ViewPose PoseFromHomography(const Eigen::Matrix3d& camera_matrix, const Eigen::Matrix3d& homography) {
  const Eigen::Matrix3d m = camera_matrix.inverse() * homography;
  double lambda = 1.0 / m.col(0).norm();
  if (m(2, 2) * lambda < 0) lambda = -lambda;  // the target origin must lie in front of the camera
  Eigen::Matrix3d r;
  r.col(0) = lambda * m.col(0);
  r.col(1) = lambda * m.col(1);
  r.col(2) = r.col(0).cross(r.col(1));
  // Nearest rotation in the Frobenius norm (Zhang Appendix C).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(r, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d rot = svd.matrixU() * svd.matrixV().transpose();
  if (rot.determinant() < 0) {
    Eigen::Matrix3d u = svd.matrixU();
    u.col(2) *= -1;
    rot = u * svd.matrixV().transpose();
  }
  ViewPose pose;
  pose.angle_axis = RotationToAngleAxis(rot);
  pose.translation_mm = lambda * m.col(2);
  return pose;
}

ZhangInitialisation InitialiseZhang(const std::vector<ViewObservations>& views) {
  const auto fail = [](std::string reason) {
    ZhangInitialisation failed;
    failed.message = std::move(reason);
    return failed;
  };
  if (views.size() < 2) return fail("Zhang's initialisation needs at least 2 views");
  const int width = views.front().image_width, height = views.front().image_height;
  if (width <= 0 || height <= 0) return fail("image size unknown");
  // Conditioning: pixel -> (px - centre) / size.
  const double scale = 1.0 / std::max(width, height);
  Eigen::Matrix3d t_norm;
  t_norm << scale, 0, -scale * 0.5 * (width - 1), 0, scale, -scale * 0.5 * (height - 1), 0, 0, 1;

  std::vector<Eigen::Matrix3d> homographies;
  Eigen::MatrixXd v(2 * views.size() + 1, 6);
  for (size_t i = 0; i < views.size(); ++i) {
    const auto h = TargetToImageHomography(views[i]);
    if (!h) return fail(fmt::format("view {} ({}): no homography from its corners", i, views[i].image_path));
    homographies.push_back(*h);
    Eigen::Matrix3d hn = t_norm * *h;
    hn /= hn.col(0).norm() + hn.col(1).norm();  // the scale of H is arbitrary; keep the rows comparable
    v.row(2 * i) = ConstraintRow(hn, 0, 1);
    v.row(2 * i + 1) = ConstraintRow(hn, 0, 0) - ConstraintRow(hn, 1, 1);
  }
  v.row(2 * views.size()) << 0, 1, 0, 0, 0, 0;  // zero skew: B12 = 0
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(v, Eigen::ComputeFullV);
  const Eigen::VectorXd& s = svd.singularValues();
  const double conditioning = s(4) / s(0);
  if (!(conditioning >= kMinConstraintConditioning)) {
    return fail(fmt::format(
        "degenerate view set: the target orientations do not determine the intrinsics (conditioning {:.2g} < {:.0e}); "
        "tilt the target differently between views",
        conditioning, kMinConstraintConditioning));
  }
  const Eigen::VectorXd b = svd.matrixV().col(5);
  const double b11 = b(0), b12 = b(1), b22 = b(2), b13 = b(3), b23 = b(4), b33 = b(5);
  const double den = b11 * b22 - b12 * b12;
  if (!(std::abs(den) > 0) || !(std::abs(b11) > 0)) {
    return fail(fmt::format("degenerate view set: B is singular (conditioning {:.2g})", conditioning));
  }
  const double v0 = (b12 * b13 - b11 * b23) / den;
  const double lambda = b33 - (b13 * b13 + v0 * (b12 * b13 - b11 * b23)) / b11;
  const double alpha2 = lambda / b11, beta2 = lambda * b11 / den;
  if (!(alpha2 > 0) || !(beta2 > 0)) {
    return fail(fmt::format("degenerate view set: B is not positive definite (conditioning {:.2g})", conditioning));
  }
  const double alpha = std::sqrt(alpha2), beta = std::sqrt(beta2);
  const double u0 = -b13 * alpha2 / lambda;  // skew term is zero by construction

  // Back from normalised to pixel units: K = T^-1 K_norm.
  Eigen::Matrix3d k_norm;
  k_norm << alpha, 0, u0, 0, beta, v0, 0, 0, 1;
  const Eigen::Matrix3d k = t_norm.inverse() * k_norm;

  ZhangInitialisation init;
  init.fx_px = k(0, 0);
  init.fy_px = k(1, 1);
  init.cx_px = k(0, 2);
  init.cy_px = k(1, 2);
  init.constraint_conditioning = conditioning;
  // A principal point far outside the image or a strongly anisotropic pixel means the constraints were fitted to
  // noise rather than geometry.
  if (!(init.fx_px > 0 && init.fy_px > 0) || init.fx_px / init.fy_px > 2 || init.fy_px / init.fx_px > 2 ||
      init.cx_px < -0.5 * width || init.cx_px > 1.5 * width || init.cy_px < -0.5 * height ||
      init.cy_px > 1.5 * height) {
    return fail(fmt::format("degenerate view set: implausible initial intrinsics fx={:.4g} fy={:.4g} cx={:.4g} "
                            "cy={:.4g} px (conditioning {:.2g})",
                            init.fx_px, init.fy_px, init.cx_px, init.cy_px, conditioning));
  }
  for (const auto& h : homographies) init.cam_from_target.push_back(PoseFromHomography(k, h));
  init.ok = true;
  return init;
}

}  // namespace topocal::calib
