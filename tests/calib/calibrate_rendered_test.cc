// End to end on rendered images (calib/render_target.h): render -> detect (calib/detect.h) -> calibrate, against the
// camera the images were rendered with.
#include <cmath>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "calib/calibrate.h"
#include "calib/detect.h"
#include "calib/render_target.h"
#include "calib/target.h"
#include "model/distortion.h"

namespace topocal::calib {
namespace {

// Acceptance: multi-view residual distortion over the area the target covers <= 0.02 px, taken as the RMS over that
// area (the statistic used for corner accuracy; the maximum, at the hull's edges where the fit
// extrapolates, is recorded and reported in docs/calibration.md); single view at the topographer geometry recovers
// sigma within 0.2 %.
constexpr double kResidualDistortionPx = 0.02;
constexpr double kSigmaRelative = 2e-3;
// Pixels on a grid of this step inside the target's footprint in some view are compared.
constexpr double kGridStepPx = 8.0;

ViewObservations RenderAndDetect(const TargetDescription& target, const model::CameraModel& camera,
                                 const CamFromTarget& pose, uint32_t seed, int supersampling) {
  RenderOptions options;
  options.blur_sigma_px = 1.0;
  options.noise_grey = 1.0;
  options.seed = seed;
  options.supersampling = supersampling;
  std::string why;
  const auto rendered = RenderTarget(target, camera, pose, options, &why);
  EXPECT_TRUE(rendered) << why;
  if (!rendered) return {};
  const auto view = DetectTarget(target, rendered->image);
  EXPECT_TRUE(view) << "no target found in render " << seed;
  return view ? *view : ViewObservations{};
}

// Discrepancy between two cameras at pixel px: where the fitted camera images the ray the true camera sees at px.
// A difference of fx, fy, cx, cy alone is affine in the pixel; the residual distortion is what is left after the
// best affine map is removed (least squares over the compared pixels).
struct FieldComparison {
  double raw_max_px = 0;
  double residual_max_px = 0;
  double residual_rms_px = 0;
  int pixels = 0;
};

FieldComparison CompareDistortionFields(const model::CameraModel& truth, const model::CameraModel& fitted,
                                        const std::vector<ViewObservations>& views) {
  std::vector<std::vector<cv::Point2f>> hulls;
  for (const auto& v : views) {
    std::vector<cv::Point2f> pts, hull;
    for (const auto& c : v.corners) pts.emplace_back(static_cast<float>(c.image_px.x()), static_cast<float>(c.image_px.y()));
    if (pts.size() < 3) continue;
    cv::convexHull(pts, hull);
    hulls.push_back(hull);
  }
  std::vector<Eigen::Vector2d> px, d;
  for (double y = 0; y < truth.height_px; y += kGridStepPx) {
    for (double x = 0; x < truth.width_px; x += kGridStepPx) {
      bool covered = false;
      for (const auto& h : hulls) covered = covered || cv::pointPolygonTest(h, cv::Point2f(x, y), false) >= 0;
      if (!covered) continue;
      const auto u = truth.PixelToNormalized({x, y});
      if (!u) continue;
      px.emplace_back(x, y);
      d.push_back(fitted.Project({u->x(), u->y(), 1.0}) - Eigen::Vector2d(x, y));
    }
  }
  FieldComparison out;
  out.pixels = static_cast<int>(px.size());
  if (px.empty()) return out;
  Eigen::MatrixXd a(px.size(), 3);
  Eigen::MatrixXd b(px.size(), 2);
  for (size_t i = 0; i < px.size(); ++i) {
    a.row(static_cast<Eigen::Index>(i)) << px[i].x(), px[i].y(), 1.0;
    b.row(static_cast<Eigen::Index>(i)) = d[i].transpose();
    out.raw_max_px = std::max(out.raw_max_px, d[i].norm());
  }
  const Eigen::MatrixXd affine = a.colPivHouseholderQr().solve(b);
  const Eigen::MatrixXd residual = b - a * affine;
  double sum2 = 0;
  for (Eigen::Index i = 0; i < residual.rows(); ++i) {
    out.residual_max_px = std::max(out.residual_max_px, residual.row(i).norm());
    sum2 += residual.row(i).squaredNorm();
  }
  out.residual_rms_px = std::sqrt(sum2 / static_cast<double>(residual.rows()));
  return out;
}

TEST(RenderedMultiView, ResidualDistortionOverTheTargetIsWithinBudget) {
  model::CameraModel camera;
  camera.width_px = 640;
  camera.height_px = 480;
  camera.fx_px = 600.0;
  camera.fy_px = 602.0;
  camera.cx_px = 321.37;
  camera.cy_px = 238.81;
  camera.dist = {-0.18, 0.06, 4e-4, -3e-4, 0.0};
  const auto target = ParseTargetDescription(
      "target_type: checkerboard\ntargetCols: 11\ntargetRows: 8\nrowSpacingMeters: 0.025\ncolSpacingMeters: 0.025\n",
      "checkerboard-11x8");
  struct Placement { double tilt_x_deg, tilt_y_deg, roll_deg, shift_x_mm, shift_y_mm; };
  const Placement placements[] = {{0, 0, 3, 0, 0},        {25, 0, -5, 0, 0},      {0, 25, 8, 0, 0},
                                  {-20, 15, 4, 60, 40},   {15, -20, -6, -60, -40}, {20, 20, 10, 60, -40},
                                  {-20, -20, -8, -60, 40}, {-25, 5, 0, 0, 0}};
  std::vector<ViewObservations> views;
  uint32_t seed = 31;
  for (const auto& p : placements) {
    const auto pose = PoseFacingTarget(target, 480.0, p.tilt_x_deg, p.tilt_y_deg, p.roll_deg, p.shift_x_mm, p.shift_y_mm);
    views.push_back(RenderAndDetect(target, camera, pose, seed++, 4));
  }
  const auto r = CalibrateMultiView(views, {});
  ASSERT_TRUE(r.ok()) << r.message;
  const auto field = CompareDistortionFields(camera, r.camera, views);
  ASSERT_GT(field.pixels, 1000);
  EXPECT_LE(field.residual_rms_px, kResidualDistortionPx);
  // Regression bound: measured 2026-12-02 residual rms 0.0069 px (max 0.039 px) over 2432 px of the target (seeded
  // renders); 0.014 px is twice that.
  EXPECT_LE(field.residual_rms_px, 0.014);
  RecordProperty("rms_px", std::to_string(r.rms_px));
  RecordProperty("raw_max_px", std::to_string(field.raw_max_px));
  RecordProperty("residual_max_px", std::to_string(field.residual_max_px));
  RecordProperty("residual_rms_px", std::to_string(field.residual_rms_px));
  std::printf("rendered multi-view: rms %.4f px, fx %.3f (600) fy %.3f (602) cx %.3f cy %.3f; field over %d px: raw "
              "max %.4f px, residual max %.4f rms %.4f px\n",
              r.rms_px, r.camera.fx_px, r.camera.fy_px, r.camera.cx_px, r.camera.cy_px, field.pixels,
              field.raw_max_px, field.residual_max_px, field.residual_rms_px);
}

struct SingleViewCase {
  double sigma_per_mm2;
  int corners;  // inner corners per side, 1 mm apart
};
class RenderedSingleView : public ::testing::TestWithParam<SingleViewCase> {};

TEST_P(RenderedSingleView, RecoversSigmaAtTheTopographerGeometry) {
  constexpr double kFocalMm = 5.2, kPitchUm = 1.12, kDistanceMm = 70.0;
  const double sigma = GetParam().sigma_per_mm2;
  const int corners = GetParam().corners;
  model::CameraModel camera;
  // The 12 mm target spans ~800 px; 1000 x 1000 px holds it with the strongest distortion of Table IV.
  camera.width_px = 1000;
  camera.height_px = 1000;
  camera.fx_px = camera.fy_px = kFocalMm / (kPitchUm * 1e-3);
  camera.cx_px = camera.cy_px = 499.5;
  camera.dist = {model::SeidelSigmaToBrownK1(sigma, model::kPaperMagnification, kFocalMm), 0, 0, 0, 0};
  const auto target = ParseTargetDescription(fmt::format("target_type: checkerboard\ntargetCols: {0}\ntargetRows: {0}\n"
                                                         "rowSpacingMeters: 0.001\ncolSpacingMeters: 0.001\n",
                                                         corners),
                                             "checkerboard-1mm");
  const auto pose = PoseFacingTarget(target, kDistanceMm + 0.5, 1.0, -0.7, 4.0, 0.2, -0.1);
  const auto view = RenderAndDetect(target, camera, pose, 41, 4);
  ASSERT_EQ(view.corners.size(), static_cast<size_t>(corners * corners));
  CalibrationOptions o;
  o.model = DistortionModelKind::kSeidel;
  o.focal_mm = kFocalMm;
  o.pixel_pitch_um = kPitchUm;
  o.distance_mm = kDistanceMm;
  const auto r = CalibrateSingleView(view, o);
  ASSERT_TRUE(r.ok()) << r.message;
  ASSERT_TRUE(r.seidel);
  EXPECT_NEAR(r.seidel->sigma_per_mm2, sigma, kSigmaRelative * std::abs(sigma));
  // Regression bound: measured 2026-12-02 relative error -4.5e-5 (sigma 6.3e-5) and -8.5e-5 (2e-4); 3e-4 is ~3.5x the
  // larger.
  EXPECT_NEAR(r.seidel->sigma_per_mm2, sigma, 3e-4 * std::abs(sigma));
  std::printf("rendered single view sigma %.3g: fitted %.6g +- %.2g (rel error %.2e), rms %.4f px\n", sigma,
              r.seidel->sigma_per_mm2, r.seidel->sigma_stddev_per_mm2, (r.seidel->sigma_per_mm2 - sigma) / sigma,
              r.rms_px);
}

// Paper Table IV: sigma_6 and sigma_7 (barrel). At sigma_7 the 12 mm board is squeezed by 29 % at its corners and
// the checkerboard detector does not find it (calib/detect.h); an 8 mm board (13 % at the corners) is used there.
INSTANTIATE_TEST_SUITE_P(TableIV, RenderedSingleView,
                         ::testing::Values(SingleViewCase{6.3e-5, 13}, SingleViewCase{2.0e-4, 9}));

}  // namespace
}  // namespace topocal::calib
