// Detection speed: rendering a 640 x 480 view, and detecting checkerboard / AprilTag grid corners in it.
// Run by hand: build-*/bench/bench_calib_detection
#include <benchmark/benchmark.h>

#include "calib/detect.h"
#include "calib/render_target.h"
#include "calib/target.h"

namespace topocal::calib {
namespace {

CameraModel Camera() {
  CameraModel camera;
  camera.width_px = 640;
  camera.height_px = 480;
  camera.fx_px = camera.fy_px = 600.0;
  camera.cx_px = 321.37;
  camera.cy_px = 238.81;
  camera.dist = {-0.18, 0.06, 4e-4, -3e-4, 0.0};
  return camera;
}

TargetDescription Board() {
  return ParseTargetDescription(
      "target_type: checkerboard\ntargetCols: 9\ntargetRows: 6\nrowSpacingMeters: 0.02\ncolSpacingMeters: 0.02\n", "b");
}
TargetDescription Grid() {
  return ParseTargetDescription("target_type: aprilgrid\ntagCols: 6\ntagRows: 5\ntagSize: 0.03\ntagSpacing: 0.3\n",
                                "g");
}

void BM_RenderCheckerboard(benchmark::State& state) {
  const auto target = Board();
  RenderOptions options;
  options.supersampling = static_cast<int>(state.range(0));
  const auto pose = PoseFacingTarget(target, 420.0, 30.0, 0.0, -5.0);
  for (auto _ : state) benchmark::DoNotOptimize(RenderTarget(target, Camera(), pose, options));
}
BENCHMARK(BM_RenderCheckerboard)->Arg(8)->Arg(16)->Arg(32)->Unit(benchmark::kMillisecond);

void BM_DetectCheckerboard(benchmark::State& state) {
  const auto target = Board();
  const auto view = RenderTarget(target, Camera(), PoseFacingTarget(target, 420.0, 30.0, 0.0, -5.0), RenderOptions{});
  DetectionOptions options;
  options.refinement = static_cast<CornerRefinement>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(DetectTarget(target, view->image, options));
}
// 0 = saddle fit, 1 = cv::cornerSubPix, 2 = none (OpenCV's board detector alone).
BENCHMARK(BM_DetectCheckerboard)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_DetectAprilGrid(benchmark::State& state) {
  const auto target = Grid();
  const auto view = RenderTarget(target, Camera(), PoseFacingTarget(target, 550.0, 30.0, 0.0, -3.0), RenderOptions{});
  DetectionOptions options;
  options.refinement = static_cast<CornerRefinement>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(DetectTarget(target, view->image, options));
}
// 0 = edge-model refinement, 2 = libapriltag's corners alone.
BENCHMARK(BM_DetectAprilGrid)->Arg(0)->Arg(2)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace topocal::calib

BENCHMARK_MAIN();
