// pipeline/ speed: the checks of a unit record on the full 4000 x 3000 sensor with the paper's
// sigma = 6.3e-5: the reference-sphere verification (detect, index, reconstruct uncorrected and corrected) and the
// paper cornea simulated through the calibrated camera, each without and with the Monte Carlo of the calibration
// covariance (per draw: undistort, reconstruct, fit, maps).
// Run: build/bench/bench_pipeline --benchmark_min_time=1
#include <benchmark/benchmark.h>

#include "calib/calibrate.h"
#include "correct/spot_render.h"
#include "correct/spot_truth.h"
#include "model/config.h"
#include "model/distortion.h"
#include "model/device.h"
#include "model/topographer_camera.h"
#include "pipeline/unit_verification.h"

namespace {

using namespace topocal;

constexpr double kSigma = 6.3e-5;
constexpr double kSphereRadiusMm = 7.8;

struct Scene {
  model::Config config;
  model::TopographerCamera camera;
  pipeline::UnitCalibration unit;
  cv::Mat sphere16;
};

const Scene& GetScene() {
  static const Scene scene = [] {
    Scene s;
    s.config = model::LoadConfig(TOPOCAL_PAPER_CONFIG);
    s.camera = model::LoadDevice(std::string(TOPOCAL_SOURCE_DIR) + "/data/device.json").device.camera;
    model::SeidelParams seidel;
    seidel.sigma_per_mm2 = kSigma;
    seidel.magnification = s.config.distortion.magnification;
    const auto sphere = pipeline::WithSphere(s.config, kSphereRadiusMm);
    const auto truth = correct::SpotsOnSensor(model::Biconic{sphere.cornea}, sphere.ideal_image, sphere.topographer,
                                              seidel, s.camera);
    s.sphere16 = correct::RenderSpotImage(truth.spots, s.camera.width_px, s.camera.height_px, {});
    // The calibration a single-view Seidel fit reports for this camera (k1 and its standard deviation as
    // `topocal calibrate` gives them, docs/closed-loop.md).
    auto& c = s.unit.camera;
    c.width_px = s.camera.width_px;
    c.height_px = s.camera.height_px;
    c.fx_px = c.fy_px = s.camera.FocalPx();
    c.cx_px = s.camera.principal_point_px.x();
    c.cy_px = s.camera.principal_point_px.y();
    c.dist = {model::SeidelSigmaToBrownK1(kSigma, seidel.magnification, s.camera.a_mm), 0, 0, 0, 0};
    s.unit.covariance.names = {"k1"};
    s.unit.covariance.matrix = Eigen::MatrixXd::Constant(1, 1, 7.5e-4 * 7.5e-4);
    s.unit.covariance.full = true;
    return s;
  }();
  return scene;
}

// The benchmarks' argument: 0 no uncertainty, 1 linear propagation, N >= 2 Monte Carlo with N draws.
pipeline::CheckOptions Checks(const benchmark::State& state) {
  using Method = pipeline::UncertaintySetting::Method;
  const int n = static_cast<int>(state.range(0));
  return {{n == 0 ? Method::kNone : n == 1 ? Method::kLinear : Method::kMonteCarlo, n >= 2 ? n : 0}, 1};
}

void BM_VerifyOnReferenceSphere(benchmark::State& state) {
  const auto& s = GetScene();
  const pipeline::CheckOptions o = Checks(state);
  for (auto _ : state) {
    benchmark::DoNotOptimize(pipeline::VerifyOnReferenceSphere(s.sphere16, kSphereRadiusMm, s.unit, s.camera, s.config, o));
  }
}
BENCHMARK(BM_VerifyOnReferenceSphere)->Arg(0)->Arg(1)->Arg(20)->Unit(benchmark::kMillisecond);

void BM_SimulatePaperCornea(benchmark::State& state) {
  const auto& s = GetScene();
  const pipeline::CheckOptions o = Checks(state);
  for (auto _ : state) {
    benchmark::DoNotOptimize(pipeline::SimulateThroughCalibratedCamera(s.unit, s.camera, s.config, o));
  }
}
BENCHMARK(BM_SimulatePaperCornea)->Arg(0)->Arg(1)->Arg(20)->Unit(benchmark::kMillisecond);

}  // namespace

