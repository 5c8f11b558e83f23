#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/core.hpp>

#include "calib/corner_refinement.h"
#include "calib/detect.h"
#include "calib/render_target.h"
#include "detection_fixtures.h"

namespace topocal::calib {
namespace {

// A distortion-free 320 x 240 camera whose principal point is off the pixel grid.
model::CameraModel PinholeCamera() {
  model::CameraModel camera;
  camera.width_px = 320;
  camera.height_px = 240;
  camera.fx_px = camera.fy_px = 500.0;
  camera.cx_px = 159.5 + 0.3137;
  camera.cy_px = 119.5 - 0.2713;
  return camera;
}

// Independent estimate of the renderer's own error: on a fronto-parallel render without blur or noise, the
// position of a vertical ink edge along a pixel row is exactly the summed ink coverage of the pixels from a
// point left of it (an area measure that needs no model of the corner or the blur).
TEST(RenderTarget, EdgesSitWhereTheyProjectToByAreaMeasure) {
  const auto target = testing::Checkerboard9x6();
  const model::CameraModel camera = PinholeCamera();
  const double distance_mm = 400.0;
  const auto pose = PoseFacingTarget(target, distance_mm, 0, 0, 0, 0.1234, -0.0771);
  RenderOptions options;
  options.blur_sigma_px = 0.0;
  const auto view = RenderTarget(target, camera, pose, options);
  ASSERT_TRUE(view.has_value());

  // N = 16: a Fibonacci lattice of 233 sub-samples with distinct x offsets 1/233 px apart, so one pixel's coverage
  // of a straight vertical edge is off by at most 1/233; rounding to 8 bits adds at most 0.5 / 190 of a pixel.
  const double kMaxEdgeErrorPx = 1.0 / 233.0 + 0.5 / (options.white_grey - options.black_grey);
  // Uniform errors within +-1/466 px (std 0.0012) and +-0.0026 px (std 0.0015): RMS ~0.002.
  constexpr double kRmsEdgeErrorPx = 0.003;
  const double black = options.black_grey, white = options.white_grey;
  const double square_px = 20.0 * camera.fx_px / distance_mm;
  double sum2 = 0, max_error = 0;
  int count = 0;
  for (int k = 0; k <= 8; ++k) {
    const Eigen::Vector3d edge_in_cam = pose.rotation * Eigen::Vector3d(20.0 * k, 0, 0) + pose.translation_mm;
    const double edge_px = camera.fx_px * edge_in_cam.x() / edge_in_cam.z() + camera.cx_px;
    const int a = static_cast<int>(std::ceil(edge_px - 0.4 * square_px));
    const int b = static_cast<int>(std::floor(edge_px + 0.4 * square_px));
    for (int r = 0; r < 6; ++r) {
      // Pixel rows in the middle 60 % of the squares between corner rows r and r + 1.
      const Eigen::Vector3d top = pose.rotation * Eigen::Vector3d(0, 20.0 * r, 0) + pose.translation_mm;
      const double top_px = camera.fy_px * top.y() / top.z() + camera.cy_px;
      for (int y = static_cast<int>(std::ceil(top_px + 0.2 * square_px)); y < top_px + 0.8 * square_px; ++y) {
        const double left = view->image.at<uint8_t>(y, a), right = view->image.at<uint8_t>(y, b);
        ASSERT_GT(std::abs(right - left), 100.0) << "no edge between columns " << a << " and " << b;
        const double lo = left < right ? black : white, hi = left < right ? white : black;
        double left_fraction = 0;
        for (int x = a; x <= b; ++x) left_fraction += 1.0 - (view->image.at<uint8_t>(y, x) - lo) / (hi - lo);
        const double error = (a - 0.5 + left_fraction) - edge_px;
        sum2 += error * error;
        max_error = std::max(max_error, std::abs(error));
        ++count;
      }
    }
  }
  ASSERT_GT(count, 500);
  const double rms = std::sqrt(sum2 / count);
  RecordProperty("edge_rms_px", std::to_string(rms));
  std::printf("renderer edge error by area measure: RMS %.4f px, max %.4f px over %d rows\n", rms, max_error, count);
  EXPECT_LT(max_error, kMaxEdgeErrorPx);
  EXPECT_LT(rms, kRmsEdgeErrorPx);
}

// The renderer's contribution to corner error: the same scene at N = 16 (default) and N = 24 sub-samples per axis,
// detected identically, agrees to the sampling noise of the default render.
TEST(RenderTarget, DefaultSupersamplingAgreesWithDenseSampling) {
  const auto target = testing::Checkerboard9x6();
  model::CameraModel camera = PinholeCamera();
  camera.dist = {-0.15, 0.04, 0, 0, 0};
  const auto pose = PoseFacingTarget(target, 420.0, 25.0, -10.0, 7.0);
  RenderOptions coarse, dense;
  dense.supersampling = 24;
  const auto a = RenderTarget(target, camera, pose, coarse), b = RenderTarget(target, camera, pose, dense);
  ASSERT_TRUE(a && b);
  const auto da = DetectTarget(target, a->image);
  ASSERT_TRUE(da.has_value());
  // Both renders are refined from the same start (the N = 16 corners), so that only the renderer differs: the
  // saddle fit's window is centred on the rounded estimate and its end point can move by a few thousandths of a
  // pixel with the start (calib/corner_refinement.h), which is the detector's property, not the renderer's.
  double sum2 = 0;
  for (const auto& c : da->corners) {
    const auto ra = RefineSaddle(a->image, c.image_px, SaddleFitOptions{3.0});
    const auto rb = RefineSaddle(b->image, c.image_px, SaddleFitOptions{3.0});
    ASSERT_TRUE(ra && rb) << "corner " << c.id;
    sum2 += (*ra - *rb).squaredNorm();
  }
  const double rms = std::sqrt(sum2 / static_cast<double>(da->corners.size()));
  std::printf("corner shift between N=16 and N=24 renders: RMS %.4f px\n", rms);
  // Quasi-Monte-Carlo error of a rank-1 lattice on a step edge falls as S^(-3/4): with S = 233 (N = 16) about
  // 1.7 % of the contrast per edge pixel, random from pixel to pixel; the saddle fit's linear terms average it over
  // ~20-30 edge pixels, ~0.4 % of the contrast-weighted edge width (~2 px): ~0.004 px. The N = 24 render (S = 610)
  // adds ~50 % of that in quadrature: ~0.0045 px.
  constexpr double kSamplingRmsPx = 0.006;
  EXPECT_LT(rms, kSamplingRmsPx);
}

TEST(RenderTarget, TruthIsTheProjectionOfVisibleCorners) {
  const auto target = testing::Checkerboard9x6();
  const model::CameraModel camera = testing::TestCamera();
  // Shifted so that part of the board leaves the image.
  const auto pose = PoseFacingTarget(target, 350.0, 10.0, 0.0, 0.0, 120.0, 0.0);
  RenderOptions options;
  options.supersampling = 2;
  const auto view = RenderTarget(target, camera, pose, options);
  ASSERT_TRUE(view.has_value());
  EXPECT_GT(view->corners.size(), 10u);
  EXPECT_LT(view->corners.size(), 54u);
  for (const auto& c : view->corners) {
    const Eigen::Vector2d expected = camera.Project(pose.rotation * *target.CornerMm(c.id) + pose.translation_mm);
    EXPECT_EQ(c.image_px, expected);
    EXPECT_GE(c.image_px.x(), 0.0);
    EXPECT_LE(c.image_px.x(), camera.width_px - 1.0);
  }
}

TEST(RenderTarget, SeededAndValidated) {
  const auto target = testing::AprilGrid6x5();
  model::CameraModel camera = PinholeCamera();
  const auto pose = PoseFacingTarget(target, 900.0);
  RenderOptions options;
  options.supersampling = 2;
  options.noise_grey = 2.0;
  const auto a = RenderTarget(target, camera, pose, options), b = RenderTarget(target, camera, pose, options);
  options.seed = 2;
  const auto c = RenderTarget(target, camera, pose, options);
  ASSERT_TRUE(a && b && c);
  EXPECT_EQ(cv::norm(a->image, b->image, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a->image, c->image, cv::NORM_INF), 0.0);

  std::string why;
  options.supersampling = 0;
  EXPECT_FALSE(RenderTarget(target, camera, pose, options, &why).has_value());
  EXPECT_NE(why.find("supersampling"), std::string::npos);
  options.supersampling = 2;
  options.noise_grey = -1;
  EXPECT_FALSE(RenderTarget(target, camera, pose, options, &why).has_value());
  options.noise_grey = 0;
  camera.width_px = 0;
  EXPECT_FALSE(RenderTarget(target, camera, pose, options, &why).has_value());
}

}  // namespace
}  // namespace topocal::calib
