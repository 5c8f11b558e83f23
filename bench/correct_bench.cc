// correct/ speed: detect + index the 624 spots of a 4000 x 3000 raw image (goal <= 50 ms), and
// undistort a 4000 x 3000 image with a precomputed map against cv::undistort in the same run.
// Run: build/bench/bench_correct --benchmark_min_time=1
#include <benchmark/benchmark.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "correct/detect_and_index.h"
#include "model/opencv_view.h"
#include "correct/spot_render.h"
#include "correct/spot_truth.h"
#include "correct/undistort_map.h"
#include "imageio/image_file.h"
#include "imageio/large_buffers.h"
#include "model/config.h"
#include "model/device.h"
#include "model/freeform_test_set.h"
#include "model/topographer_camera.h"

namespace {

using namespace topocal;

struct Scene {
  model::Config config;
  model::TopographerCamera camera;
  cv::Mat spots16;  // raw spot image, 16-bit
  cv::Mat grey8;    // a textured 8-bit frame for the remap comparison
  model::CameraModel lens;
  model::LensParams brown;
};

const Scene& GetScene() {
  static const Scene scene = [] {
    Scene s;
    s.config = model::LoadConfig(TOPOCAL_PAPER_CONFIG);
    s.camera = model::LoadDevice(std::string(TOPOCAL_SOURCE_DIR) + "/data/device.json").device.camera;
    model::SeidelParams seidel;
    seidel.sigma_per_mm2 = 6.3e-5;
    seidel.magnification = s.config.distortion.magnification;
    const auto truth = correct::SpotsOnSensor(model::Biconic{s.config.cornea}, s.config.ideal_image,
                                              s.config.topographer, seidel, s.camera);
    correct::SpotRenderOptions o;  // 16-bit, ellipse spots, realistic noise
    s.spots16 = correct::RenderSpotImage(truth.spots, s.camera.width_px, s.camera.height_px, o);
    s.grey8.create(s.camera.height_px, s.camera.width_px, CV_8UC1);
    cv::randu(s.grey8, 0, 255);
    const double f = s.camera.FocalPx();
    s.lens = {.fx_px = f,
              .fy_px = f,
              .cx_px = s.camera.principal_point_px.x() + 4,
              .cy_px = s.camera.principal_point_px.y() - 3,
              .dist = {-0.12, 0.25, 8e-4, -5e-4, -0.1}};
    s.brown = model::LensFromOpenCv(s.lens, s.camera).lens;
    return s;
  }();
  return scene;
}

void BM_DetectAndIndex624Spots(benchmark::State& state) {
  const auto& s = GetScene();
  size_t found = 0;
  for (auto _ : state) {
    const auto r = correct::DetectAndIndexSpots(s.spots16, s.camera, s.config.ideal_image);
    found = r.spots.size();
    benchmark::DoNotOptimize(r);
  }
  state.counters["spots"] = static_cast<double>(found);
}
BENCHMARK(BM_DetectAndIndex624Spots)->Unit(benchmark::kMillisecond)->UseRealTime();

// Detect + index + estimate at 4000 x 3000 with each estimator, on PSF spots (sigma 2 px, 16 bit,
// Poisson + read noise: where the default estimator fits every spot) — the default (psf) beside today's centroid.
const cv::Mat& PsfImage() {
  static const cv::Mat image = [] {
    const auto& s = GetScene();
    model::SeidelParams seidel;
    seidel.sigma_per_mm2 = 6.3e-5;
    seidel.magnification = s.config.distortion.magnification;
    const auto truth = correct::SpotsOnSensor(model::Biconic{s.config.cornea}, s.config.ideal_image,
                                              s.config.topographer, seidel, s.camera);
    correct::SpotRenderOptions o;
    o.shape = correct::SpotShape::kPsf;
    o.psf_sigma_px = 2.0;
    return correct::RenderSpotImage(truth.spots, s.camera.width_px, s.camera.height_px, o);
  }();
  return image;
}

void BM_DetectIndexEstimatePsfSpots(benchmark::State& state) {
  const auto& s = GetScene();
  correct::DetectAndIndexOptions o;
  o.detection.method = static_cast<correct::CentroidMethod>(state.range(0));
  state.SetLabel(correct::CentroidMethodName(o.detection.method));
  const cv::Mat& image = PsfImage();  // rendered once, outside the timing
  size_t found = 0;
  for (auto _ : state) {
    const auto r = correct::DetectAndIndexSpots(image, s.camera, s.config.ideal_image, o);
    found = r.spots.size();
    benchmark::DoNotOptimize(r);
  }
  state.counters["spots"] = static_cast<double>(found);
}
BENCHMARK(BM_DetectIndexEstimatePsfSpots)
    ->Arg(static_cast<int>(correct::CentroidMethod::kWeightedPsfFit))
    ->Arg(static_cast<int>(correct::CentroidMethod::kIntensityWeighted))
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_DetectOnly(benchmark::State& state) {
  const auto& s = GetScene();
  for (auto _ : state) benchmark::DoNotOptimize(correct::DetectSpots(s.spots16));
}
BENCHMARK(BM_DetectOnly)->Unit(benchmark::kMillisecond)->UseRealTime();

// A frame without a spot (the sensor's level, 16-bit, with its read noise, and exactly flat): what `detect` pays
// before it knows there is nothing to find. The peer is one OpenCV pass over the same frame, its maximum.
cv::Mat BlankFrame(bool noisy) {
  const auto& s = GetScene();
  cv::Mat frame(s.camera.height_px, s.camera.width_px, CV_16UC1, cv::Scalar(1000));
  if (noisy) {
    cv::RNG rng(7);
    cv::Mat noise(frame.size(), CV_32F);
    rng.fill(noise, cv::RNG::NORMAL, 1000, 60);
    noise.convertTo(frame, CV_16U);
  }
  return frame;
}

void BM_DetectBlankFrame(benchmark::State& state) {
  const cv::Mat frame = BlankFrame(state.range(0) != 0);
  for (auto _ : state) {
    const auto d = correct::DetectSpots(frame);
    if (!d.spots.empty()) state.SkipWithError("spots found on a blank frame");
    benchmark::DoNotOptimize(d);
  }
}
BENCHMARK(BM_DetectBlankFrame)->ArgName("noisy")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_OpenCvMaxOfBlankFrame(benchmark::State& state) {
  const cv::Mat frame = BlankFrame(state.range(0) != 0);
  for (auto _ : state) {
    double max_dn = 0;
    cv::minMaxIdx(frame, nullptr, &max_dn);
    benchmark::DoNotOptimize(max_dn);
  }
}
BENCHMARK(BM_OpenCvMaxOfBlankFrame)->ArgName("noisy")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// A blank frame from its PNG bytes to "nothing above the threshold", as `detect` does it (imageio's decoder, then
// DetectSpots, in the CLI's image buffers). The peer is OpenCV decoding the same bytes and taking the frame's maximum (cv::imdecode +
// cv::minMaxIdx).
// The CLI's image buffers (huge pages, imageio/large_buffers.h) while one benchmark runs, for it and its peer alike;
// the other benchmarks here keep OpenCV's own.
class CliImageBuffers {
 public:
  CliImageBuffers() : before_(cv::Mat::getDefaultAllocator()) { imageio::UseHugePagesForImageBuffers(); }
  ~CliImageBuffers() { cv::Mat::setDefaultAllocator(before_); }
  CliImageBuffers(const CliImageBuffers&) = delete;
  CliImageBuffers& operator=(const CliImageBuffers&) = delete;

 private:
  cv::MatAllocator* before_;
};

std::string BlankPng(bool noisy) {
  std::vector<unsigned char> bytes;
  cv::imencode(".png", BlankFrame(noisy), bytes);
  return std::string(bytes.begin(), bytes.end());
}

void BM_DecodeAndDetectBlankPng(benchmark::State& state) {
  const std::string png = BlankPng(state.range(0) != 0);
  const CliImageBuffers buffers;
  for (auto _ : state) {
    const auto d = correct::DetectSpots(imageio::DecodeImage(png, imageio::Channels::kAsStored, "blank.png"));
    if (!d.spots.empty()) state.SkipWithError("spots found on a blank frame");
  }
}
BENCHMARK(BM_DecodeAndDetectBlankPng)->ArgName("noisy")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_OpenCvDecodeAndMaxOfBlankPng(benchmark::State& state) {
  const std::string png = BlankPng(state.range(0) != 0);
  const cv::Mat bytes(1, static_cast<int>(png.size()), CV_8UC1, const_cast<char*>(png.data()));
  const CliImageBuffers buffers;
  for (auto _ : state) {
    double max_dn = 0;
    cv::minMaxIdx(cv::imdecode(bytes, cv::IMREAD_UNCHANGED), nullptr, &max_dn);
    benchmark::DoNotOptimize(max_dn);
  }
}
BENCHMARK(BM_OpenCvDecodeAndMaxOfBlankPng)
    ->ArgName("noisy")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_IndexOnly(benchmark::State& state) {
  const auto& s = GetScene();
  const auto det = correct::DetectSpots(s.spots16);
  std::vector<Eigen::Vector2d> mm;
  for (const auto& d : det.spots) mm.push_back(s.camera.DetectionPlaneFromPixel(d.centre_px));
  for (auto _ : state) benchmark::DoNotOptimize(correct::IndexSpots(mm, s.config.ideal_image));
}
BENCHMARK(BM_IndexOnly)->Unit(benchmark::kMillisecond)->UseRealTime();

// The pattern matcher where its first start fails: a 60 um cone 0.9 mm beside the apex, imaged on the 26-ring x 6
// screen `design --optimize` chooses (exact spots, nominal device). The isotropic starts grow lattices that are all
// wrong and refused; the stretched starts read it (docs/spot-identification.md, step 1).
void BM_IndexSevereConeOnDenseScreen(benchmark::State& state) {
  const auto& s = GetScene();
  model::IdealImageParams ideal = s.config.ideal_image;
  ideal.rings_N = 25;
  ideal.eta0 = ideal.eta = 6;
  ideal.spot_radius_um = 2.70;
  model::Freeform cornea = model::FreeformTestSubset({"kc-33um-0.85mm"}).front().surface;
  cornea.cones = {{60.0, 1.0, 0.4, -0.8}};
  model::FocusOnAxis(&cornea);
  const auto truth = correct::SpotsOnSensor(cornea, ideal, s.config.topographer, model::NominalDevice(s.camera));
  std::vector<Eigen::Vector2d> mm;
  for (const auto& spot : truth.spots) mm.push_back(s.camera.DetectionPlaneFromPixel(spot.centre_px));
  size_t identified = 0;
  for (auto _ : state) {
    const auto r = correct::IndexSpots(mm, ideal);
    identified = r.spots.size();
    benchmark::DoNotOptimize(r);
  }
  state.counters["identified"] = static_cast<double>(identified);
}
BENCHMARK(BM_IndexSevereConeOnDenseScreen)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_BuildUndistortMapBrown(benchmark::State& state) {
  const auto& s = GetScene();
  for (auto _ : state) benchmark::DoNotOptimize(correct::BuildUndistortMap(s.brown, s.camera));
}
BENCHMARK(BM_BuildUndistortMapBrown)->Unit(benchmark::kMillisecond)->UseRealTime();

// As cv::initUndistortRectifyMap below is measured: into buffers that already exist.
void BM_RebuildUndistortMapBrown(benchmark::State& state) {
  const auto& s = GetScene();
  correct::UndistortMap map;
  for (auto _ : state) {
    correct::BuildUndistortMap(s.brown, s.camera, &map);
    benchmark::DoNotOptimize(map.map_x.data);
  }
}
BENCHMARK(BM_RebuildUndistortMapBrown)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_BuildUndistortMapSeidel(benchmark::State& state) {
  const auto& s = GetScene();
  model::SeidelParams seidel;
  seidel.sigma_per_mm2 = 6.3e-5;
  seidel.magnification = s.config.distortion.magnification;
  for (auto _ : state) benchmark::DoNotOptimize(correct::BuildUndistortMap(seidel, s.camera));
}
BENCHMARK(BM_BuildUndistortMapSeidel)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_OpenCvInitUndistortRectifyMap(benchmark::State& state) {
  const auto& s = GetScene();
  const cv::Matx33d k(s.lens.fx_px, 0, s.lens.cx_px, 0, s.lens.fy_px, s.lens.cy_px, 0, 0, 1);
  cv::Mat mx, my;
  for (auto _ : state) {
    cv::initUndistortRectifyMap(k, s.lens.dist, cv::Mat(), k, s.grey8.size(), CV_32FC1, mx, my);
    benchmark::DoNotOptimize(mx.data);
  }
}
BENCHMARK(BM_OpenCvInitUndistortRectifyMap)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_UndistortWithPrecomputedMap(benchmark::State& state) {
  const auto& s = GetScene();
  const auto map = correct::BuildUndistortMap(s.brown, s.camera);
  for (auto _ : state) benchmark::DoNotOptimize(correct::UndistortImage(s.grey8, map));
}
BENCHMARK(BM_UndistortWithPrecomputedMap)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_UndistortWithPrecomputedFixedPointMap(benchmark::State& state) {
  const auto& s = GetScene();
  const auto map = correct::BuildUndistortMap(s.brown, s.camera);
  cv::Mat m1, m2, out;
  cv::convertMaps(map.map_x, map.map_y, m1, m2, CV_16SC2);  // OpenCV's 1/32 px fixed-point tables
  for (auto _ : state) {
    cv::remap(s.grey8, out, m1, m2, cv::INTER_LINEAR);
    benchmark::DoNotOptimize(out.data);
  }
}
BENCHMARK(BM_UndistortWithPrecomputedFixedPointMap)->Unit(benchmark::kMillisecond)->UseRealTime();

// One image, nothing precomputed (the `undistort` verb): topocal's banded one-shot against cv::undistort, which
// does the same job the same way (below).
void BM_UndistortOneShot(benchmark::State& state) {
  const auto& s = GetScene();
  for (auto _ : state) benchmark::DoNotOptimize(correct::UndistortImage(s.grey8, s.brown, s.camera).data);
}
BENCHMARK(BM_UndistortOneShot)->Unit(benchmark::kMillisecond)->UseRealTime();

// The earlier one-shot: two whole maps allocated and built, then one remap.
void BM_UndistortOneShotWholeMaps(benchmark::State& state) {
  const auto& s = GetScene();
  for (auto _ : state) {
    benchmark::DoNotOptimize(correct::UndistortImage(s.grey8, correct::BuildUndistortMap(s.brown, s.camera)).data);
  }
}
BENCHMARK(BM_UndistortOneShotWholeMaps)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_CvUndistort(benchmark::State& state) {
  const auto& s = GetScene();
  const cv::Matx33d k(s.lens.fx_px, 0, s.lens.cx_px, 0, s.lens.fy_px, s.lens.cy_px, 0, 0, 1);
  cv::Mat out;
  for (auto _ : state) {
    cv::undistort(s.grey8, out, k, s.lens.dist);
    benchmark::DoNotOptimize(out.data);
  }
}
BENCHMARK(BM_CvUndistort)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

