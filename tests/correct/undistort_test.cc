// Undistortion of points and whole images, Seidel and Brown-Conrady, over the whole sensor.
#include <gtest/gtest.h>

#include <Eigen/SVD>
#include <array>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "model/opencv_view.h"
#include "correct/undistort_map.h"
#include "correct/undistort_points.h"
#include "synthetic.h"

namespace topocal::correct {
namespace {

// Points: the inverse converges to 1e-12 mm in the distorted plane (model::kInverseToleranceMm); the undistorted
// error is that over the Jacobian, which is >= 0.1 inside 0.95 of the fold radius: 1e-11 mm, rounded up.
constexpr double kPointRoundTripMm = 1e-10;
// Maps are stored as float: 2^-24 relative of a <= 4000 px coordinate is 2.4e-4 px.
constexpr double kFloatMapPx = 5e-4;

// A realistic smartphone lens: moderate barrel, a little tangential, the distortion centre off the principal point.
model::LensParams SmartphoneBrown() {
  model::LensParams b;
  b.focal_mm = 5.2;
  b.centre_x_mm = 0.012;
  b.centre_y_mm = -0.008;
  b.k = {-0.12, 0.25, 8e-4, -5e-4, -0.1};
  return b;
}

std::vector<model::Distortion> Models() {
  const auto cfg = testing::PaperConfig();
  std::vector<model::Distortion> m;
  for (const double s : {-2e-4, -6.3e-5, 0.0, 6.3e-5, 2e-4}) {
    auto p = testing::Seidel(cfg, s);
    p.centre_x_mm = 0.02;  // off the optical axis, so a wrong centre convention shows
    p.centre_y_mm = -0.01;
    m.push_back(p);
  }
  m.push_back(SmartphoneBrown());
  return m;
}

Eigen::Vector2d CentreOf(const model::Distortion& d) { return model::DistortionCentreMm(d); }

double MinSingularValue(const model::Distortion& d, const Eigen::Vector2d& mm) {
  constexpr double h = 1e-6;  // mm; central differences of a polynomial map: error ~h^2
  Eigen::Matrix2d j;
  j.col(0) = (model::Distort(d, mm + Eigen::Vector2d(h, 0)) - model::Distort(d, mm - Eigen::Vector2d(h, 0))) / (2 * h);
  j.col(1) = (model::Distort(d, mm + Eigen::Vector2d(0, h)) - model::Distort(d, mm - Eigen::Vector2d(0, h))) / (2 * h);
  return Eigen::JacobiSVD<Eigen::Matrix2d>(j).singularValues()(1);
}

TEST(UndistortPoints, RoundTripOverTheWholeSensor) {
  const auto camera = testing::DefaultCamera();
  for (const auto& d : Models()) {
    SCOPED_TRACE(model::DescribeDistortion(d));
    const double fold = FoldRadiusMm(d, 10.0);
    std::vector<Eigen::Vector2d> truth, distorted;
    for (int v = 0; v < camera.height_px; v += 20) {
      for (int u = 0; u < camera.width_px; u += 20) {
        const Eigen::Vector2d mm = camera.DetectionPlaneFromPixel({u, v});
        if ((mm - CentreOf(d)).norm() >= 0.95 * fold) continue;
        truth.push_back(mm);
        distorted.push_back(model::Distort(d, mm));
      }
    }
    ASSERT_GT(truth.size(), 1000u);
    const auto r = UndistortPoints(d, distorted);
    EXPECT_TRUE(r.failures.empty()) << r.failures.size() << " failures, first: " << r.failures[0].reason;
    double worst = 0;
    for (size_t i = 0; i < truth.size(); ++i) worst = std::max(worst, (r.points_mm[i] - truth[i]).norm());
    EXPECT_LT(worst, kPointRoundTripMm);
    EXPECT_LE(r.max_residual_mm, kPointResidualToleranceMm);
  }
}

TEST(UndistortPoints, ReportsEachFailureByIndex) {
  const auto cfg = testing::PaperConfig();
  const auto barrel = testing::Seidel(cfg, 2e-4);
  // The largest distorted radius of strong barrel is (2/3) r_fold; 0.6 mm lies beyond it: no preimage.
  const auto r = UndistortPoints(barrel, {{0.1, 0.0}, {0.6, 0.0}, {NAN, 0.0}, {0.0, -0.2}});
  ASSERT_EQ(r.failures.size(), 2u);
  EXPECT_EQ(r.failures[0].index, 1);
  EXPECT_EQ(r.failures[1].index, 2);
  EXPECT_EQ(r.ok, (std::vector<bool>{true, false, false, true}));
  EXPECT_NE(r.failures[0].reason.find("did not converge"), std::string::npos);
}

TEST(UndistortMap, InvertsThePointUndistortionEverywhere) {
  const auto camera = testing::DefaultCamera();
  for (const auto& d : Models()) {
    SCOPED_TRACE(model::DescribeDistortion(d));
    const auto map = BuildUndistortMap(d, camera);
    int checked = 0;
    for (int v = 0; v < camera.height_px; v += 13) {
      for (int u = 0; u < camera.width_px; u += 13) {
        const Eigen::Vector2d src(map.map_x.at<float>(v, u), map.map_y.at<float>(v, u));
        if (src.x() == -1.f) {
          // Only beyond the fold.
          EXPECT_GE((camera.DetectionPlaneFromPixel({u, v}) - CentreOf(d)).norm(), map.fold_radius_mm * (1 - 1e-9));
          continue;
        }
        const auto back = model::Undistort(d, camera.DetectionPlaneFromPixel(src));
        ASSERT_TRUE(back.has_value()) << u << ", " << v << " r/fold " << (camera.DetectionPlaneFromPixel({u, v}) - CentreOf(d)).norm() / map.fold_radius_mm;
        // The float rounding of the map entry (one ulp of its magnitude per coordinate, sqrt 2 for both), seen
        // through the inverse: divided by the smallest singular value of the distortion's Jacobian (-> 0 at the fold).
        const double ulp = std::ldexp(1.0, -23) * std::max(1.0, src.cwiseAbs().maxCoeff());
        EXPECT_LT((camera.PixelFromDetectionPlane(*back) - Eigen::Vector2d(u, v)).norm(),
                  std::sqrt(2.0) * ulp / MinSingularValue(d, camera.DetectionPlaneFromPixel({u, v})));
        ++checked;
      }
    }
    EXPECT_GT(checked, 2000);
  }
}

TEST(UndistortMap, EveryLensModelAgreesWithOpenCv) {
  const auto camera = testing::DefaultCamera();
  const double f = camera.FocalPx();
  model::ForEachLensModel([&](auto lens) {
    SCOPED_TRACE(std::string(decltype(lens)::kName));
    model::CameraModel k{.fx_px = f,
                         .fy_px = f,
                         .cx_px = camera.principal_point_px.x() + 13.0,
                         .cy_px = camera.principal_point_px.y() - 7.0,
                         .dist = {-0.12, 0.25, 8e-4, -5e-4, -0.1}};
    k.lens = lens;
    // The rational model's denominator, where it has one.
    for (int i = 5; i < model::LensParameterCount(lens); ++i) k.dist[static_cast<size_t>(i)] = 0.02 * (i - 4);
    const auto on_plane = LensFromOpenCv(k, camera);
    ASSERT_TRUE(on_plane.ok) << on_plane.message;
    const auto ours = BuildUndistortMap(on_plane.lens, camera);
    const cv::Matx33d kk(f, 0, k.cx_px, 0, f, k.cy_px, 0, 0, 1);
    // What cv::undistort(src, dst, K, dist) applies: the same K for the output, the model's own coefficients.
    const cv::Mat dist(1, model::LensParameterCount(lens), CV_64F, k.dist.data());
    cv::Mat mx, my;
    cv::initUndistortRectifyMap(kk, dist, cv::Mat(), kk, cv::Size(camera.width_px, camera.height_px), CV_32FC1, mx,
                                my);
    double worst = 0;
    for (int v = 0; v < camera.height_px; v += 7) {
      for (int u = 0; u < camera.width_px; u += 7) {
        worst = std::max({worst, static_cast<double>(std::abs(mx.at<float>(v, u) - ours.map_x.at<float>(v, u))),
                          static_cast<double>(std::abs(my.at<float>(v, u) - ours.map_y.at<float>(v, u)))});
      }
    }
    EXPECT_LT(worst, 2 * kFloatMapPx);
  });
}

TEST(UndistortMap, RemapOfARenderedPatternMatchesTheTruth) {
  // A 1000 x 1000 crop of the default camera: at sigma = 2e-4 its corners lie beyond the fold (0.68 mm, 604 px).
  auto camera = testing::DefaultCamera();
  camera.width_px = 1000;
  camera.height_px = 1000;
  camera.principal_point_px = {499.5, 499.5};
  const double wavelength_px = 40.0;
  const double k = 2.0 * M_PI / (wavelength_px * camera.PitchMm());
  const auto pattern = [k](const Eigen::Vector2d& mm) {
    return 0.5 + 0.25 * (std::cos(k * mm.x()) + std::cos(k * mm.y()));
  };
  const auto cfg = testing::PaperConfig();
  for (const model::Distortion& d : {model::Distortion(testing::Seidel(cfg, 2e-4)),
                                    model::Distortion(testing::Seidel(cfg, -2e-4)),
                                    model::Distortion(SmartphoneBrown())}) {
    SCOPED_TRACE(model::DescribeDistortion(d));
    // The camera's (distorted) image, rendered exactly: each pixel shows the pattern at its undistorted position.
    cv::Mat distorted(camera.height_px, camera.width_px, CV_32FC1, cv::Scalar(0));
    for (int v = 0; v < camera.height_px; ++v) {
      for (int u = 0; u < camera.width_px; ++u) {
        const auto mm = model::Undistort(d, camera.DetectionPlaneFromPixel({u, v}));
        if (mm) distorted.at<float>(v, u) = static_cast<float>(pattern(*mm));
      }
    }
    const auto map = BuildUndistortMap(d, camera);
    const cv::Mat undistorted = UndistortImage(distorted, map);
    // The one-shot path (map built band by band, never whole) gives the same image bit for bit, and the same count
    // of pixels beyond the fold.
    int invalid_px = -1;
    const cv::Mat one_shot = UndistortImage(distorted, d, camera, &invalid_px);
    EXPECT_EQ(cv::norm(one_shot, undistorted, cv::NORM_INF), 0.0);
    EXPECT_EQ(invalid_px, map.invalid_px);
    // Compared within half the fold radius (or the crop's inscribed circle), where the local compression of the
    // distorted image is at most J = 1 + 3 c r^2 >= 0.75. Bilinear interpolation errs by at most
    // (|f_uu| + |f_vv|) / 8 per unit pixel: 2 * 0.25 (2 pi / (lambda J))^2 / 8.
    const double r_max_mm = std::min(0.5 * map.fold_radius_mm, 0.9 * 499.5 * camera.PitchMm());
    const double j_min = 0.75;
    const double bound = 2 * 0.25 * std::pow(2 * M_PI / (wavelength_px * j_min), 2) / 8.0;
    double worst = 0, sum = 0;
    int n = 0;
    for (int v = 0; v < camera.height_px; ++v) {
      for (int u = 0; u < camera.width_px; ++u) {
        const Eigen::Vector2d mm = camera.DetectionPlaneFromPixel({u, v});
        if ((mm - CentreOf(d)).norm() > r_max_mm) continue;
        // Pincushion pulls from beyond the crop's edge: those pixels have no source in this image.
        const float sx = map.map_x.at<float>(v, u), sy = map.map_y.at<float>(v, u);
        if (sx < 0 || sy < 0 || sx > camera.width_px - 1 || sy > camera.height_px - 1) continue;
        const double e = std::abs(undistorted.at<float>(v, u) - pattern(mm));
        worst = std::max(worst, e);
        sum += e;
        ++n;
      }
    }
    EXPECT_GT(n, 100000);
    EXPECT_LT(worst, bound);
    // And the image is not the distorted one passed through: without correction it would err by O(0.1).
    EXPECT_GT(cv::norm(distorted, undistorted, cv::NORM_INF), 10 * bound);
    if (std::isfinite(map.fold_radius_mm)) {
      EXPECT_GT(map.invalid_px, 0);
    }
  }
}

}  // namespace
}  // namespace topocal::correct

namespace topocal::correct {
namespace {

// The pixel-space camera of a calibration file (OpenCV's Brown model with an optional radial centre e): the
// calibration's own projection, which LensFromOpenCv must reproduce on the detection plane.
Eigen::Vector2d ProjectOpenCv(const model::CameraModel& k, const Eigen::Vector2d& normalised) {
  return k.Project(Eigen::Vector3d(normalised.x(), normalised.y(), 1.0));
}

// Exact agreement: the conversion is algebra, only rounding separates the two paths.
constexpr double kSameModelPx = 1e-9;

TEST(LensFromOpenCv, SameDistortionInPixelsForEveryOrientationAndCentre) {
  for (int o = 0; o < 8; ++o) {
    for (const double e : {0.0, 0.01}) {
      const auto orientation = static_cast<model::ImageOrientation>(o);
      SCOPED_TRACE(::testing::Message() << "orientation " << model::OrientationName(orientation) << " centre " << e);
      auto camera = testing::DefaultCamera();
      camera.orientation = orientation;
      const double f = camera.FocalPx();
      const model::CameraModel k{.fx_px = f,
                                 .fy_px = f,
                                 .cx_px = camera.principal_point_px.x() + 21.0,
                                 .cy_px = camera.principal_point_px.y() - 9.0,
                                 .dist = {-0.12, 0.25, 8e-4, -5e-4, -0.1},
                                 .distortion_centre = {e, -0.5 * e}};
      const auto b = LensFromOpenCv(k, camera);
      ASSERT_TRUE(b.ok) << b.message;
      for (int v = 0; v < camera.height_px; v += 250) {
        for (int u = 0; u < camera.width_px; u += 250) {
          // The same undistorted pixel through both: OpenCV's normalised coordinates from the calibration's K,
          // topocal's millimetres from the topographer camera.
          const Eigen::Vector2d px(u, v);
          const Eigen::Vector2d cv_px = ProjectOpenCv(k, {(u - k.cx_px) / k.fx_px, (v - k.cy_px) / k.fy_px});
          const Eigen::Vector2d ours =
              camera.PixelFromDetectionPlane(model::Distort(b.lens, camera.DetectionPlaneFromPixel(px)));
          EXPECT_LT((cv_px - ours).norm(), kSameModelPx) << u << ", " << v;
        }
      }
    }
  }
}

// More than 5 coefficients never reach the conversion: the calibration file's reader refuses a non-zero k4..
// (tests/calib/calibration_file_test.cc), and CameraModel holds exactly 5.
TEST(LensFromOpenCv, RejectsWhatItCannotRepresent) {
  const auto camera = testing::DefaultCamera();
  const auto lens = [](double fx, double fy) {
    return model::CameraModel{.fx_px = fx, .fy_px = fy, .cx_px = 10, .cy_px = 10, .dist = {0.1, 0, 0, 0, 0}};
  };
  const auto no_focal = LensFromOpenCv(lens(0, 1000), camera);
  EXPECT_FALSE(no_focal.ok);
  EXPECT_NE(no_focal.message.find("focal lengths must be > 0"), std::string::npos);
  auto bad_centre = lens(1000, 1000);
  bad_centre.distortion_centre.x() = std::numeric_limits<double>::quiet_NaN();
  const auto nan_centre = LensFromOpenCv(bad_centre, camera);
  EXPECT_FALSE(nan_centre.ok);
  EXPECT_NE(nan_centre.message.find("distortion centre must be finite"), std::string::npos);
  const auto b = LensFromOpenCv(lens(1000, 1001), camera);
  ASSERT_TRUE(b.ok) << b.message;
  EXPECT_NEAR(b.aspect_error, 1e-3, 1e-6);
}

}  // namespace
}  // namespace topocal::correct
