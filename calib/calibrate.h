#pragma once
// Camera calibration by bundle adjustment (Ceres) of the reprojection error of planar-target corners.
//
// Two problems share one solver:
//
//  * Multi-view (CalibrateMultiView): intrinsics fx, fy, cx, cy, the distortion and one pose per view, started from
//    Zhang's closed form (calib/zhang.h). With model brown5 and nothing fixed this is the problem cv::calibrateCamera
//    solves with default flags, and it converges to the same minimum.
//
//  * Single view (CalibrateSingleView): the topographer case, one image of a planar target placed where the cornea
//    goes, with the lens focal distance, the pixel pitch and the nominal target distance known. What one view can
//    and cannot tell apart (see docs/calibration.md):
//      - fx = fy = focal_mm / pitch_mm are FIXED: a plane seen once cannot separate focal length from distance.
//      - the principal point (cx, cy) is FIXED at the image centre: shifting it is indistinguishable (to first
//        order in the field angle, ~0.1 rad here) from translating/tilting the target.
//      - the distortion (k1, or k1..k3, p1, p2) and the six pose parameters are fitted; the radial distortion centre
//        e is separable from tilt (its r^2 e term has no perspective counterpart) and may be fitted with Seidel.
//    Brown's p1, p2 and a free distortion centre are the same thing to second order (p1 = -k1 e_y, p2 = -k1 e_x),
//    so the options refuse to fit both.
//
// Models: "seidel" = Brown's k1 alone (paper Eq. 18, sigma = k1 M_T^3 / f_mm^2, model/distortion.h), optionally
// about a fitted centre; or any lens model of model/lens_model.h by its name ("brown5" = OpenCV's k1, k2, p1, p2, k3,
// "rational8" = OpenCV's CALIB_RATIONAL_MODEL).
//
// Residuals are predicted - observed, px. RMS is OpenCV's: sqrt(sum over corners |r|^2 / corners).
// Parameter standard deviations: sqrt(diag(sigma^2 (J'J)^-1)) (calib/jacobian_covariance.h) with the residual variance
// sigma^2 = SSR / (2 corners - free parameters).
#include <Eigen/Core>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "calib/observations.h"
#include "calib/zhang.h"
#include "model/camera_model.h"
#include "model/paper_topographer.h"

namespace topocal::calib {

// The distortion a calibration fits: a lens model, or the paper's Seidel distortion (Brown-Conrady's k1 alone).
struct DistortionModelKind {
  bool seidel = false;
  model::LensModelId lens;  // Brown-Conrady when seidel

  static const DistortionModelKind kSeidel;
  static const DistortionModelKind kBrown5;
  friend bool operator==(const DistortionModelKind&, const DistortionModelKind&) = default;
};
inline const DistortionModelKind DistortionModelKind::kSeidel{true, model::BrownConrady{}};
inline const DistortionModelKind DistortionModelKind::kBrown5{false, model::BrownConrady{}};

std::string_view ToString(const DistortionModelKind& model) noexcept;
std::optional<DistortionModelKind> ParseDistortionModel(std::string_view name) noexcept;
// "seidel, brown5, rational8": what ParseDistortionModel accepts, for messages and --help.
std::string DistortionModelNames();

enum class RobustLoss { kNone, kHuber, kCauchy };
std::string_view ToString(RobustLoss loss) noexcept;
std::optional<RobustLoss> ParseRobustLoss(std::string_view name) noexcept;

// Names of the camera parameters of a model, in the order the result reports them: fx, fy, cx, cy, the lens model's
// coefficients, ex, ey (the distortion centre).
std::vector<std::string> CameraParameterNames(const DistortionModelKind& model);

struct CalibrationOptions {
  DistortionModelKind model = DistortionModelKind::kBrown5;
  // Parameters held at their initial value (names from CameraParameterNames). Seidel fixes all but k1 at 0;
  // ex, ey are fixed at 0 unless fit_distortion_centre.
  std::set<std::string> fixed;
  bool fit_distortion_centre = false;
  // Multi-view: hold fx / fy at this ratio during the fit (0 = fx and fy free), for lenses known to have square
  // pixels or to stabilise a fit from few views; OpenCV's CALIB_FIX_ASPECT_RATIO with the ratio given. fx and fy
  // then move together and share one degree of freedom (and one standard deviation, scaled by the ratio).
  double fixed_aspect_ratio = 0;
  // Multi-view: fit the board's parabolic sag with the camera (calib/cost_functions.h BoardWarp), for printed
  // targets that are not flat.
  bool fit_board_warp = false;

  RobustLoss loss = RobustLoss::kNone;
  double loss_scale_px = 1.0;          // where the robust loss leaves the quadratic regime
  bool reject_outliers = false;
  double outlier_threshold = 4.0;      // drop corners with |r| > threshold * robust sigma (per-axis, from the median)
  int max_outlier_rounds = 5;

  int min_views = 3;                   // multi-view only
  int min_corners_per_view = 8;        // fewer and the view is skipped (multi-view) or the fit refused (single)
  int max_iterations = 200;

  // Camera geometry in physical units. Single view needs all three; multi-view uses focal/pitch (if given) only to
  // report the Seidel sigma. magnification is the paper's M_T.
  double focal_mm = 0;
  double pixel_pitch_um = 0;
  double distance_mm = 0;
  double magnification = model::kPaperMagnification;

  // Empty when valid; otherwise *why says what is wrong.
  bool IsValid(std::string* why) const;
};

enum class CalibrationStatus {
  kOk,
  kInvalidOptions,
  kInvalidInput,        // inconsistent image sizes, non-planar target points
  kTooFewViews,
  kTooFewCorners,
  kDegenerate,          // view set or corner layout that does not determine the parameters
  kSolverFailed,        // Ceres did not converge or returned a non-finite cost
  kCovarianceFailed,    // the Jacobian is rank-deficient at the solution
};
std::string_view ToString(CalibrationStatus status) noexcept;

struct SolverSummary {
  bool converged = false;
  int iterations = 0;
  double initial_cost = 0;  // Ceres' cost: 0.5 * sum of (robustified) squared residuals, px^2
  double final_cost = 0;
  std::string message;
};

struct ParameterEstimate {
  std::string name;
  double value = 0;
  double stddev = 0;  // 0 for fixed parameters
  bool fixed = false;
};

struct CornerResidual {
  int view = 0;         // index into the caller's views
  int corner_id = 0;
  Eigen::Vector2d observed_px = Eigen::Vector2d::Zero();
  Eigen::Vector2d residual_px = Eigen::Vector2d::Zero();  // predicted - observed
  bool outlier = false;
};

struct SkippedView {
  int view = 0;
  std::string reason;
};

struct SeidelEstimate {
  double sigma_per_mm2 = 0;
  double sigma_stddev_per_mm2 = 0;  // from k1's standard deviation, focal length taken as exact
  double magnification = model::kPaperMagnification;
  double focal_mm = 0;
  double pixel_pitch_um = 0;
};

// The fitted board warp (calib/cost_functions.h BoardWarp): the middle of the board is sag_x + sag_y mm off the
// plane through its edges; standard deviations from the same covariance as the camera's.
struct BoardWarpEstimate {
  double sag_x_mm = 0, sag_y_mm = 0;
  double sag_x_stddev_mm = 0, sag_y_stddev_mm = 0;
  Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();
  Eigen::Vector2d half_size_mm = Eigen::Vector2d::Zero();
};

struct CalibrationResult {
  CalibrationStatus status = CalibrationStatus::kOk;
  std::string message;  // one line; for failures, what went wrong
  bool ok() const noexcept { return status == CalibrationStatus::kOk; }

  DistortionModelKind model = DistortionModelKind::kBrown5;
  bool single_view = false;
  model::CameraModel camera;
  std::vector<ParameterEstimate> parameters;   // CameraParameterNames(model) order
  // Covariance of the camera parameters, square in CameraParameterNames(model) order (px, normalised
  // units), sigma^2 (J'J)^-1 with the poses marginalised; rows and columns of fixed parameters are zero.
  Eigen::MatrixXd covariance;
  std::optional<SeidelEstimate> seidel;        // Seidel model with a known focal length in mm
  std::optional<BoardWarpEstimate> board_warp;  // when fitted (options.fit_board_warp)
  double fixed_aspect_ratio = 0;               // fx / fy held during the fit (options.fixed_aspect_ratio); 0 = free
  double pixel_pitch_um = 0;                   // from the options; 0 = unknown
  double focal_mm = 0;                         // given (single view), or fitted f_px x pitch; 0 = unknown

  std::vector<int> views_used;                 // indices into the caller's views
  std::vector<SkippedView> skipped_views;
  std::vector<ViewPose> cam_from_target;  // parallel to views_used
  std::vector<double> per_view_rms_px;         // parallel to views_used, inliers only
  double rms_px = 0;                           // inliers only
  int corners_used = 0;
  double residual_variance_px2 = 0;            // SSR / (2 corners - free parameters), inliers
  int free_parameters = 0;
  std::vector<CornerResidual> residuals;       // every corner of the used views, outliers flagged
  std::vector<CornerResidual> outliers;        // the rejected ones
  int outlier_rounds = 0;
  SolverSummary solver;
};

CalibrationResult CalibrateMultiView(const std::vector<ViewObservations>& views, const CalibrationOptions& options);
CalibrationResult CalibrateSingleView(const ViewObservations& view, const CalibrationOptions& options);

}  // namespace topocal::calib
