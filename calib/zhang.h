#pragma once
// Closed-form initialisation of a multi-view planar calibration (Z. Zhang, "A flexible new technique for camera
// calibration", IEEE TPAMI 22(11), 2000, Sec. 3.1 and Appendix B), with zero skew imposed as one more linear
// constraint so that two views suffice.
//
//   1. one homography per view, target plane (X, Y mm) -> pixel:  H ~ K [r1 r2 t]      (cv::findHomography)
//   2. each H gives two linear constraints on B = K^-T K^-1:       h1' B h2 = 0,  h1' B h1 = h2' B h2
//      stacked with B12 = 0 (zero skew), solved for b by SVD      (Eigen)
//   3. K from B in closed form; each pose from K^-1 H, its rotation projected onto SO(3) by SVD.
//
// Why not cv::initCameraMatrix2D: it solves only for fx and fy with the principal point pinned to the image
// centre, and it neither returns the poses nor says when the views are degenerate (e.g. all parallel to each other,
// where the constraints have rank 3 instead of 5). We need the full closed form to detect that case and to start
// the bundle adjustment from a consistent (K, poses) pair. The distortion is initialised at zero.
//
// Homographies are computed in pixel coordinates normalised by the image size (Hartley's conditioning): B's six
// entries then have comparable magnitudes and the rank test below is meaningful.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calib/observations.h"

namespace topocal::calib {

// Rigid transform target -> camera (cam_from_target): angle-axis rotation (rad) and translation (mm), the
// parameterisation the bundle adjustment uses (calib/render_target.h has the rotation-matrix form for rendering).
struct ViewPose {
  Eigen::Vector3d angle_axis = Eigen::Vector3d::Zero();
  Eigen::Vector3d translation_mm = Eigen::Vector3d::Zero();
};

struct ZhangInitialisation {
  bool ok = false;
  std::string message;  // why not, when !ok
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0;
  std::vector<ViewPose> cam_from_target;  // one per input view
  // Singular values of the normalised constraint matrix, largest first: the 5th over the 1st is the conditioning of
  // the intrinsics (near zero = degenerate view set).
  double constraint_conditioning = 0;
};

// The minimum relative size of the 5th singular value of the stacked constraints; below it the view set does not
// determine the intrinsics (all views parallel, or a single orientation: rank 3 in exact arithmetic, ~1e-10 on
// noise-free corners). Measured: OpenCV's 13 photographs 0.17, the synthetic 8-view set 0.11, five parallel views
// with 0.1 px noise 0.003 — noise lifts a degenerate set well above any safe rank threshold, so noisy degenerate
// sets are caught by the next checks (B not positive definite, implausible intrinsics); one that slipped through
// would show as large parameter standard deviations (or a rank-deficient covariance) after bundle adjustment.
inline constexpr double kMinConstraintConditioning = 1e-4;

// Least-squares homography target plane (mm) -> pixel for one view; nullopt with fewer than 4 corners or when the
// corners are collinear.
std::optional<Eigen::Matrix3d> TargetToImageHomography(const ViewObservations& view);

// The pose of the target given K and its homography (Zhang Sec. 3.1), target in front of the camera.
ViewPose PoseFromHomography(const Eigen::Matrix3d& camera_matrix, const Eigen::Matrix3d& homography);

// Zhang's closed form over all views (each with >= 4 non-collinear corners and the same image size). !ok with the
// reason in `message` when a homography fails, the views are degenerate or B is not positive definite (a computation
// that failed: the caller's calibration reports it as CalibrationStatus::kDegenerate).
ZhangInitialisation InitialiseZhang(const std::vector<ViewObservations>& views);

}  // namespace topocal::calib
