// Board warp (calib/cost_functions.h BoardWarp): a printed board that is not flat. Seeded synthetic corners of a
// warped board through a known camera: the warp is recovered within its reported uncertainty, the intrinsics are
// unbiased with the warp fitted and biased without it.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>

#include "calib/calibrate.h"
#include "calib/cost_functions.h"
#include "synthetic_views.h"

namespace topocal::calib {
namespace {

constexpr double kSagXMm = 1.5;   // a wall-mounted paper board bows by millimetres (mrcal's typical fits)
constexpr double kSagYMm = -0.8;
constexpr double kNoisePx = 0.1;
// Within 4 reported standard deviations (one test of several parameters, seeded).
constexpr double kSigmas = 4.0;

std::vector<ViewObservations> WarpedViews(const model::CameraModel& camera, uint32_t seed) {
  const testing::GridTarget grid;
  BoardWarp geometry;
  geometry.centre_mm = {0.5 * (grid.cols - 1) * grid.spacing_mm, 0.5 * (grid.rows - 1) * grid.spacing_mm};
  geometry.half_size_mm = geometry.centre_mm;
  const double warp[2] = {kSagXMm, kSagYMm};
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, kNoisePx);
  std::vector<ViewObservations> views;
  for (const auto& pose : testing::ReferencePoses(grid)) {
    ViewObservations view;
    view.image_width = camera.width_px;
    view.image_height = camera.height_px;
    const double angle = pose.angle_axis.norm();
    const Eigen::Matrix3d r = Eigen::AngleAxisd(angle, pose.angle_axis / angle).toRotationMatrix();
    for (int row = 0; row < grid.rows; ++row) {
      for (int col = 0; col < grid.cols; ++col) {
        CornerObservation c;
        c.id = row * grid.cols + col;
        c.target_mm = {col * grid.spacing_mm, row * grid.spacing_mm, 0.0};  // what the target file says
        const Eigen::Vector3d actual(c.target_mm.x(), c.target_mm.y(),
                                     geometry.SagMm(warp, c.target_mm.x(), c.target_mm.y()));
        c.image_px = camera.Project(r * actual + pose.translation_mm) + Eigen::Vector2d(noise(rng), noise(rng));
        if (c.image_px.x() < 0 || c.image_px.y() < 0 || c.image_px.x() > camera.width_px - 1 ||
            c.image_px.y() > camera.height_px - 1) {
          continue;
        }
        view.corners.push_back(c);
      }
    }
    views.push_back(view);
  }
  return views;
}

TEST(BoardWarp, WarpIsRecoveredAndIntrinsicsUnbiased) {
  const model::CameraModel truth = testing::ReferenceCamera();
  const auto views = WarpedViews(truth, 11);
  CalibrationOptions options;
  options.fit_board_warp = true;
  const auto fitted = CalibrateMultiView(views, options);
  ASSERT_TRUE(fitted.ok()) << fitted.message;
  ASSERT_TRUE(fitted.board_warp.has_value());
  const auto& w = *fitted.board_warp;
  std::printf("warp fitted: sag_x %.4f +- %.4f mm (truth %.1f), sag_y %.4f +- %.4f mm (truth %.1f), rms %.4f px\n",
              w.sag_x_mm, w.sag_x_stddev_mm, kSagXMm, w.sag_y_mm, w.sag_y_stddev_mm, kSagYMm, fitted.rms_px);
  EXPECT_GT(w.sag_x_stddev_mm, 0.0);
  EXPECT_LT(std::abs(w.sag_x_mm - kSagXMm), kSigmas * w.sag_x_stddev_mm);
  EXPECT_LT(std::abs(w.sag_y_mm - kSagYMm), kSigmas * w.sag_y_stddev_mm);
  // The residual is the noise alone once the warp is modelled: RMS of the residual norm = sqrt(2) x per-axis sigma.
  EXPECT_LT(fitted.rms_px, 1.1 * std::sqrt(2.0) * kNoisePx);

  CalibrationOptions flat;
  const auto ignored = CalibrateMultiView(views, flat);
  ASSERT_TRUE(ignored.ok()) << ignored.message;
  EXPECT_FALSE(ignored.board_warp.has_value());
  std::printf("fx: truth %.3f, warp fitted %.3f +- %.3f, flat %.3f +- %.3f; flat rms %.4f px\n", truth.fx_px,
              fitted.camera.fx_px, fitted.parameters[0].stddev, ignored.camera.fx_px, ignored.parameters[0].stddev,
              ignored.rms_px);
  const double values_truth[] = {truth.fx_px, truth.fy_px, truth.cx_px, truth.cy_px, truth.dist[0]};
  int biased_without_warp = 0;
  for (int i = 0; i < 5; ++i) {
    const auto& p = fitted.parameters[static_cast<size_t>(i)];
    EXPECT_LT(std::abs(p.value - values_truth[i]), kSigmas * p.stddev) << p.name;
    const auto& q = ignored.parameters[static_cast<size_t>(i)];
    biased_without_warp += std::abs(q.value - values_truth[i]) > kSigmas * q.stddev;
  }
  // Without the warp term the sag goes into the camera: at least one of fx, fy, cx, cy, k1 is off by > 4 sigma.
  EXPECT_GE(biased_without_warp, 1);
}

TEST(BoardWarp, FlatBoardFitsZeroWarpAndSingleViewRefusesIt) {
  const model::CameraModel truth = testing::ReferenceCamera();
  const testing::GridTarget grid;
  std::mt19937 rng(5);
  std::vector<ViewObservations> views;
  for (const auto& pose : testing::ReferencePoses(grid)) views.push_back(testing::ProjectGrid(truth, pose, grid, 0.1, rng));
  CalibrationOptions options;
  options.fit_board_warp = true;
  const auto fitted = CalibrateMultiView(views, options);
  ASSERT_TRUE(fitted.ok()) << fitted.message;
  EXPECT_LT(std::abs(fitted.board_warp->sag_x_mm), kSigmas * fitted.board_warp->sag_x_stddev_mm);
  EXPECT_LT(std::abs(fitted.board_warp->sag_y_mm), kSigmas * fitted.board_warp->sag_y_stddev_mm);
  options.focal_mm = 4;
  options.pixel_pitch_um = 2;
  options.distance_mm = 400;
  const auto single = CalibrateSingleView(views[0], options);
  EXPECT_EQ(single.status, CalibrationStatus::kInvalidOptions);
}

}  // namespace
}  // namespace topocal::calib
