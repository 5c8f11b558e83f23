// A three-ball device calibration on the full 4000 x 3000 sensor, detection included (decoded
// images in memory: detect + index each ball, then the bundle adjustment), on one core. Target <= 1 s.
// The peer in the same run: OpenCV's cv::calibrateCamera on the same number of points (three views of a 624-point
// planar pattern), the closest thing a general camera-calibration library does with comparable data.
// The same fit with five target views added (845 corners: every lens coefficient fitted with the pose), beside
// cv::calibrateCamera on those views alone.
// A measurement of an eye through the calibrated device (detect, index, reconstruct, reject
// outliers, judge) without and with the U of every number (linear propagation of the device's covariance + 16 draws
// of the spot noise), on one core and on every core: process CPU time, the figure bounded at +50 %.
// A capture whose lattice leaves spots without identity (a +6 D hyperopic ablation under lids 30 %
// and 15 %) measured with the surface's predict-and-label loop, and with the lattice's identities alone (today's
// matcher without it) in the same run: process CPU time, bounded at 2x.
// Run: build/bench/bench_device --benchmark_min_time=1
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>

#include "correct/spot_render.h"
#include "correct/spot_truth.h"
#include "model/config.h"
#include "model/device.h"
#include "model/freeform_test_set.h"
#include "pipeline/device_calibration.h"
#include "pipeline/measurement_uncertainty.h"
#include "pipeline/measure_spots.h"
#include "pipeline/surface_labelling.h"

namespace {

using namespace topocal;

struct Scene {
  model::Config config;
  model::Device nominal, unit;
  std::vector<pipeline::BallImage> balls;
  pipeline::DeviceCalibration calibrated;  // the unit calibrated from its balls
  cv::Mat eye;                              // the paper cornea through the unit, on the full sensor
  cv::Mat ablated;                          // a +6 D hyperopic ablation under both lids, through the unit
  model::Config measure;                    // as reconstruct measures eyes: surface model "auto"
};

const Scene& GetScene() {
  static const Scene scene = [] {
    Scene s;
    s.config = model::LoadConfig(TOPOCAL_PAPER_CONFIG);
    s.nominal = model::LoadDevice(std::string(TOPOCAL_SOURCE_DIR) + "/data/device.json").device;
    s.unit = model::LoadDevice(std::string(TOPOCAL_SOURCE_DIR) + "/data/demo-unit-device.json").device;
    const double radii[] = {6.5, 7.8, 9.0};
    const Eigen::Vector3d at[] = {{0.12, -0.2, 0.05}, {-0.25, 0.1, -0.15}, {0.2, 0.22, 0.1}};
    for (int i = 0; i < 3; ++i) {
      model::Sphere ball{radii[i], at[i].z(), at[i].x(), at[i].y()};
      const auto truth = correct::SpotsOnSensor(ball, s.config.ideal_image, s.config.topographer, s.unit);
      s.balls.push_back({"ball", correct::RenderSpotImage(truth.spots, s.unit.camera.width_px,
                                                         s.unit.camera.height_px, {}),
                         radii[i]});
    }
    s.calibrated = pipeline::CalibrateDevice(s.balls, s.nominal, s.config, {});
    const auto eye = correct::SpotsOnSensor(model::Biconic{s.config.cornea}, s.config.ideal_image,
                                            s.config.topographer, s.unit);
    s.eye = correct::RenderSpotImage(eye.spots, s.unit.camera.width_px, s.unit.camera.height_px, {});
    s.measure = s.config;
    s.measure.reconstruction.surface_model = "auto";
    const auto hyperopic = model::FreeformTestSubset({"lasik-hyperopic-6D"}).front().surface;
    const auto ablated = correct::SpotsOnSensor(hyperopic, s.config.ideal_image, s.config.topographer, s.unit);
    s.ablated = correct::RenderSpotImage(
        correct::HideUnderLids(ablated.spots, correct::LidsOver(ablated.spots, 0.30, 0.15)), s.unit.camera.width_px,
        s.unit.camera.height_px, {});
    return s;
  }();
  return scene;
}

void BM_DeviceCalibrationThreeBalls(benchmark::State& state) {
  const auto& s = GetScene();
  for (auto _ : state) {
    const auto c = pipeline::CalibrateDevice(s.balls, s.nominal, s.config, {});
    if (!c.fit.ok) state.SkipWithError(c.fit.message.c_str());
    benchmark::DoNotOptimize(c.fit.parameters.data());
  }
}
BENCHMARK(BM_DeviceCalibrationThreeBalls)->Unit(benchmark::kMillisecond);

void BM_DeviceFitOnlyThreeBalls(benchmark::State& state) {
  const auto& s = GetScene();
  std::vector<calib::BallView> views;
  for (const auto& b : s.balls) views.push_back(pipeline::DetectBall(b, s.nominal, s.config.ideal_image).view);
  const auto design = model::DesignNullScreen(s.config.ideal_image, s.config.topographer);
  for (auto _ : state) {
    const auto fit = calib::FitDevice(s.nominal, s.config.topographer, design.targets, views);
    benchmark::DoNotOptimize(fit.parameters.data());
  }
}
BENCHMARK(BM_DeviceFitOnlyThreeBalls)->Unit(benchmark::kMillisecond);

// Five views of a 13 x 13 board of 0.9 mm squares at the cornea position (0, +-15 deg about x and y), imaged exactly
// through the unit: the corners a target view gives the joint fit.
std::vector<calib::ViewObservations> BoardViews(const Scene& s) {
  const auto setup = model::ProjectionSetupOf(s.unit, s.config.topographer);
  const double sigma = std::get<model::SeidelParams>(s.unit.distortion).sigma_per_mm2;
  const double pp[2] = {s.unit.camera.principal_point_px.x(), s.unit.camera.principal_point_px.y()};
  std::vector<calib::ViewObservations> views;
  for (const auto& [tx, ty] : {std::pair{0.0, 0.0}, {0.26, 0.0}, {-0.26, 0.0}, {0.0, 0.26}, {0.0, -0.26}}) {
    const Eigen::Matrix3d r = (Eigen::AngleAxisd(tx, Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(ty, Eigen::Vector3d::UnitY())).toRotationMatrix();
    calib::ViewObservations v{"board", s.unit.camera.width_px, s.unit.camera.height_px, {}};
    for (int i = 0; i < 169; ++i) {
      const Eigen::Vector3d on_board((i % 13 - 6) * 0.9, (i / 13 - 6) * 0.9, 0.0);
      const Eigen::Vector3d point = r * on_board;
      double px[2];
      model::ProjectPoint(setup, pp, &s.unit.camera.a_mm, &sigma, point.data(), px);
      v.corners.push_back({i, Eigen::Vector2d(px[0], px[1]), on_board});
    }
    views.push_back(v);
  }
  return views;
}

// The joint fit: the three balls and the five board views (845 corners) in one problem.
void BM_DeviceFitThreeBallsAndFiveTargetViews(benchmark::State& state) {
  const auto& s = GetScene();
  std::vector<calib::BallView> balls;
  for (const auto& b : s.balls) balls.push_back(pipeline::DetectBall(b, s.nominal, s.config.ideal_image).view);
  const auto design = model::DesignNullScreen(s.config.ideal_image, s.config.topographer);
  const auto views = BoardViews(s);
  for (auto _ : state) {
    const auto fit = calib::FitDevice(s.nominal, s.config.topographer, design.targets, balls, {}, views);
    if (!fit.ok) state.SkipWithError(fit.message.c_str());
    benchmark::DoNotOptimize(fit.parameters.data());
  }
}
BENCHMARK(BM_DeviceFitThreeBallsAndFiveTargetViews)->Unit(benchmark::kMillisecond);

// Peer of the joint fit: cv::calibrateCamera on the same five views' corners (intrinsics, 5 coefficients, 5 poses).
void BM_OpenCvCalibrateCameraFiveTargetViews(benchmark::State& state) {
  const auto views = BoardViews(GetScene());
  std::vector<std::vector<cv::Point3f>> objects;
  std::vector<std::vector<cv::Point2f>> images;
  for (const auto& v : views) {
    objects.emplace_back();
    images.emplace_back();
    for (const auto& c : v.corners) {
      objects.back().emplace_back(c.target_mm.x(), c.target_mm.y(), 0.0f);
      images.back().emplace_back(c.image_px.x(), c.image_px.y());
    }
  }
  for (auto _ : state) {
    cv::Mat camera, dist;
    std::vector<cv::Mat> r, tv;
    benchmark::DoNotOptimize(cv::calibrateCamera(objects, images, cv::Size(4000, 3000), camera, dist, r, tv));
  }
}
BENCHMARK(BM_OpenCvCalibrateCameraFiveTargetViews)->Unit(benchmark::kMillisecond);

// Peer: cv::calibrateCamera, three views of a planar 624-point pattern (the spots' ideal image, scaled to a 26 x 26
// mm target 100 mm away), intrinsics + 5 distortion coefficients + three poses.
void BM_OpenCvCalibrateCameraThreeViews(benchmark::State& state) {
  const auto& s = GetScene();
  const auto ideal = model::IdealImage(s.config.ideal_image);
  std::vector<cv::Point3f> object;
  for (const auto& p : ideal) object.emplace_back(p.position_mm.x() * 40.0, p.position_mm.y() * 40.0, 0.0f);
  const cv::Matx33d k(s.unit.camera.FocalPx(), 0, 1999.5, 0, s.unit.camera.FocalPx(), 1499.5, 0, 0, 1);
  std::vector<std::vector<cv::Point3f>> objects;
  std::vector<std::vector<cv::Point2f>> images;
  const double tilts[] = {0.0, 0.2, -0.2};
  for (const double t : tilts) {
    std::vector<cv::Point2f> projected;
    cv::projectPoints(object, cv::Vec3d(t, -t / 2, 0.1), cv::Vec3d(0.5, -0.3, 100.0), k, cv::noArray(), projected);
    objects.push_back(object);
    images.push_back(projected);
  }
  for (auto _ : state) {
    cv::Mat camera, dist;
    std::vector<cv::Mat> r, tv;
    benchmark::DoNotOptimize(cv::calibrateCamera(objects, images, cv::Size(4000, 3000), camera, dist, r, tv));
  }
}
BENCHMARK(BM_OpenCvCalibrateCameraThreeViews)->Unit(benchmark::kMillisecond);

// Arg: threads of the propagation (1: one core; 0: every core). The measurement itself as reconstruct runs it.
void BM_MeasureEyeThroughDevice(benchmark::State& state) {
  const auto& s = GetScene();
  if (!s.calibrated.fit.ok) state.SkipWithError(s.calibrated.fit.message.c_str());
  for (auto _ : state) {
    const auto m = pipeline::MeasureEye(s.eye, s.calibrated.fit.device, s.measure);
    benchmark::DoNotOptimize(m.analysis.power.axial_D.data());
  }
}
BENCHMARK(BM_MeasureEyeThroughDevice)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

// Arg 1: with the surface's labelling (as reconstruct measures); 0: the lattice's identities alone.
void BM_MeasureAblationUnderLids(benchmark::State& state) {
  const auto& s = GetScene();
  const auto& device = s.calibrated.fit.device;
  if (!s.calibrated.fit.ok) state.SkipWithError(s.calibrated.fit.message.c_str());
  const auto analyze = [&](const std::vector<model::PlaneSpot>& spots) {
    return pipeline::AnalyzeThroughDevice(spots, device, s.measure, nullptr);
  };
  int identified = 0;
  for (auto _ : state) {
    auto m = pipeline::MeasureSpots(s.ablated, device, s.measure.ideal_image);
    const auto a = state.range(0) ? pipeline::LabelThroughSurface(&m, device, s.measure, analyze)
                                  : pipeline::RejectSurfaceOutliers(m.spots, analyze, &m.capture);
    identified = m.capture.identified;
    benchmark::DoNotOptimize(a.power.axial_D.data());
  }
  state.counters["identified"] = identified;
}
BENCHMARK(BM_MeasureAblationUnderLids)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

void BM_MeasureEyeWithUncertainty(benchmark::State& state) {
  const auto& s = GetScene();
  if (!s.calibrated.fit.ok) state.SkipWithError(s.calibrated.fit.message.c_str());
  pipeline::UncertaintyOptions o;
  o.jobs = static_cast<int>(state.range(0));
  for (auto _ : state) {
    const auto m = pipeline::MeasureEye(s.eye, s.calibrated.fit.device, s.measure);
    const auto u = pipeline::PropagateMeasurementUncertainty(m.spots.detected, s.calibrated.fit.device,
                                                             s.calibrated.fit.Covariance(), s.measure, m.analysis, o);
    benchmark::DoNotOptimize(u.quantities.data());
  }
}
BENCHMARK(BM_MeasureEyeWithUncertainty)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

}  // namespace

