// Detection speed: rendering a 640 x 480 view and the unit's 4000 x 3000 view (with an OpenCV peer), and detecting
// checkerboard / AprilTag grid corners in them.
// Run by hand: build-*/bench/bench_calib_detection
#include <benchmark/benchmark.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "calib/apriltag_raii.h"

#include "calib/detect.h"
#include "calib/render_target.h"
#include "calib/target.h"
#include "model/distortion.h"

namespace topocal::calib {
namespace {

model::CameraModel Camera() {
  model::CameraModel camera;
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
                                "g");  // Kalibr's layout (aruco + saddle fit)
}
TargetDescription KalibrGrid6x6() {
  return ParseTargetDescription("target_type: aprilgrid\ntagCols: 6\ntagRows: 6\ntagSize: 0.03\ntagSpacing: 0.3\n",
                                "k66");
}
TargetDescription GridOneCell() {
  return ParseTargetDescription(
      "target_type: aprilgrid\ntagCols: 6\ntagRows: 5\ntagSize: 0.03\ntagSpacing: 0.3\ntagBorderBits: 1\n", "g1");
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

// A frame without a board (sensor noise, 640 x 480): topocal's whole search (OpenCV's classic detector behind its
// quick test, then SB) against OpenCV's classic detector without the quick test, as topocal once called it.
cv::Mat NoiseFrame() {
  cv::Mat noise(480, 640, CV_8UC1);
  cv::setRNGSeed(16);
  cv::randu(noise, 0, 255);
  return noise;
}
void BM_DetectOnNoise(benchmark::State& state) {
  const auto target = Board();
  const cv::Mat noise = NoiseFrame();
  for (auto _ : state) benchmark::DoNotOptimize(DetectTarget(target, noise));
}
BENCHMARK(BM_DetectOnNoise)->Unit(benchmark::kMillisecond);
void BM_DetectOnNoiseOpenCvClassic(benchmark::State& state) {
  const cv::Mat noise = NoiseFrame();
  std::vector<cv::Point2f> corners;
  for (auto _ : state) {
    benchmark::DoNotOptimize(cv::findChessboardCorners(noise, cv::Size(9, 6), corners,
                                                       cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE));
  }
}
BENCHMARK(BM_DetectOnNoiseOpenCvClassic)->Unit(benchmark::kMillisecond)->Iterations(1);

void BM_DetectAprilGrid(benchmark::State& state) {
  const auto target = Grid();
  const auto view = RenderTarget(target, Camera(), PoseFacingTarget(target, 550.0, 30.0, 0.0, -3.0), RenderOptions{});
  DetectionOptions options;
  options.refinement = static_cast<CornerRefinement>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(DetectTarget(target, view->image, options));
}
// 0 = saddle fit, 2 = aruco's corners alone.
BENCHMARK(BM_DetectAprilGrid)->Arg(0)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_DetectAprilGridOneCell(benchmark::State& state) {
  const auto target = GridOneCell();
  const auto view = RenderTarget(target, Camera(), PoseFacingTarget(target, 550.0, 30.0, 0.0, -3.0), RenderOptions{});
  DetectionOptions options;
  options.refinement = static_cast<CornerRefinement>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(DetectTarget(target, view->image, options));
}
// 0 = edge-model refinement, 2 = libapriltag's corners alone.
BENCHMARK(BM_DetectAprilGridOneCell)->Arg(0)->Arg(2)->Unit(benchmark::kMillisecond);

// A Kalibr 6 x 6 grid as a phone stores it (tests/calib/kalibr_grid_recall_test.cc): tags of ~30 px tilted 30
// degrees, blur 1 px, noise 2, gamma-encoded, JPEG quality 50. topocal's whole detection (aruco + libapriltag,
// saddle fit) against libapriltag with the 2-cell-border family alone, on the same view in the same run.
const cv::Mat& KalibrJpegView() {
  static const cv::Mat view = [] {
    const auto target = KalibrGrid6x6();
    RenderOptions options;
    options.noise_grey = 2.0;
    const auto render = RenderTarget(target, Camera(), PoseFacingTarget(target, 600.0, 30.0, 0.0, 20.0), options);
    cv::Mat encoded;
    cv::pow(render->irradiance / 255.0, 1.0 / 2.2, encoded);
    std::vector<uchar> jpeg;
    cv::imencode(".jpg", AddSensorNoise(encoded * 255.0, options.noise_grey, options.seed), jpeg,
                 {cv::IMWRITE_JPEG_QUALITY, 50});
    return cv::imdecode(jpeg, cv::IMREAD_GRAYSCALE);
  }();
  return view;
}

void BM_DetectKalibrGridJpeg(benchmark::State& state) {
  const auto target = KalibrGrid6x6();
  DetectionOptions options;
  options.refinement = static_cast<CornerRefinement>(state.range(0));
  // Outside the timing: the render, and the per-thread libapriltag table the first detection builds (timed below).
  int tags = DetectTargetDetailed(target, KalibrJpegView(), options).tags_detected;
  for (auto _ : state) tags = DetectTargetDetailed(target, KalibrJpegView(), options).tags_detected;
  state.counters["tags"] = tags;
  state.SetLabel(state.range(0) == 0 ? "topocal: aruco + libapriltag, saddle fit" : "topocal: searches alone");
}
// 0 = saddle fit, 2 = the two searches' corners alone.
BENCHMARK(BM_DetectKalibrGridJpeg)->Arg(0)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_LibapriltagKalibrFamilyJpeg(benchmark::State& state) {
  // The detector and its 2-bit decoding table are built once, outside the timing, as topocal keeps them per thread.
  const auto family = apriltag_raii::MakeKalibrTag36h11();
  const apriltag_raii::Detector detector(apriltag_detector_create());
  apriltag_detector_add_family_bits(detector.get(), family.get(), 2);
  detector->quad_decimate = 1.0f;
  detector->refine_edges = true;
  detector->nthreads = 1;
  cv::Mat copy = KalibrJpegView().clone();
  image_u8_t image{copy.cols, copy.rows, static_cast<int32_t>(copy.step[0]), copy.data};
  int tags = 0;
  for (auto _ : state) {
    const apriltag_raii::Detections detections(apriltag_detector_detect(detector.get(), &image));
    tags = zarray_size(detections.get());
  }
  state.counters["tags"] = tags;
  state.SetLabel("libapriltag, tag36h11 with a 2-cell border, quad_decimate 1");
}
BENCHMARK(BM_LibapriltagKalibrFamilyJpeg)->Unit(benchmark::kMillisecond);

void BM_LibapriltagKalibrFamilyTable(benchmark::State& state) {
  for (auto _ : state) {
    const auto family = apriltag_raii::MakeKalibrTag36h11();
    const apriltag_raii::Detector detector(apriltag_detector_create());
    apriltag_detector_add_family_bits(detector.get(), family.get(), static_cast<int>(state.range(0)));
  }
  state.SetLabel("building libapriltag's decoding table for N corrected bits (once per thread in topocal)");
}
BENCHMARK(BM_LibapriltagKalibrFamilyTable)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

// The unit's camera: the full 4000 x 3000 sensor, a = 5.2 mm, 1.12 um pitch, Brown k1 alone.
model::CameraModel UnitCamera(double k1) {
  model::CameraModel camera;
  camera.width_px = 4000;
  camera.height_px = 3000;
  camera.fx_px = camera.fy_px = 5.2 / 1.12e-3;
  camera.cx_px = 1999.5;
  camera.cy_px = 1499.5;
  camera.dist = {k1, 0.0, 0.0, 0.0, 0.0};
  return camera;
}

// A unit's target image: data/target-topographer.yaml (13 x 13 inner corners of 0.9 mm) at 70 mm on the full
// 4000 x 3000 sensor (a = 5.2 mm, 1.12 um pitch; README's demo), with OpenCV's detectors on the same image as peers.
const RenderedView& UnitView() {
  static const RenderedView view = [] {
    const auto target = LoadTargetDescription(TOPOCAL_SOURCE_DIR "/data/target-topographer.yaml");
    const model::CameraModel camera = UnitCamera(-0.05);
    RenderOptions options;
    options.supersampling = 4;  // the detector's speed does not depend on the render's fidelity
    options.noise_grey = 1.0;
    return *RenderTarget(target, camera, PoseFacingTarget(target, 70.0, 5.0, -5.0, 2.0), options);
  }();
  return view;
}

// The README's unit view, rendered as `topocal render-target` does (supersampling 4, blur 1 px, noise 1 grey level;
// the paper's sigma = 6.3e-5, k1 = -6.2, folds 718 px from the centre). Arg: threads (0 = every core). Wall time.
void BM_RenderUnitTarget(benchmark::State& state) {
  const auto target = LoadTargetDescription(TOPOCAL_SOURCE_DIR "/data/target-topographer.yaml");
  const auto camera = UnitCamera(model::SeidelSigmaToBrownK1(6.3e-5, -0.065, 5.2));
  const auto pose = PoseFacingTarget(target, 70.0);
  RenderOptions options;
  options.supersampling = 4;
  options.noise_grey = 1.0;
  options.jobs = static_cast<int>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(RenderTarget(target, camera, pose, options));
  state.SetLabel("topocal: exact inverse near the paper, 13 sub-samples per edge pixel, truth corners");
}
BENCHMARK(BM_RenderUnitTarget)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// The peer, a lower bound for the same picture with OpenCV: the paper and the black squares drawn at pixel
// resolution (cv::fillPoly, anti-aliased, 1/16 px vertices) in the undistorted image, warped through the distortion
// (cv::remap, bilinear), blurred (cv::GaussianBlur, sigma 1 px) and noised (cv::randn, 1 grey level). Its
// undistortion map is given (cv::undistortPoints of every pixel, outside the timing): per pixel the same inverse
// the renderer computes near the paper only.
void BM_RenderUnitTargetOpenCv(benchmark::State& state) {
  const auto target = LoadTargetDescription(TOPOCAL_SOURCE_DIR "/data/target-topographer.yaml");
  const auto camera = UnitCamera(model::SeidelSigmaToBrownK1(6.3e-5, -0.065, 5.2));
  const auto pose = PoseFacingTarget(target, 70.0);
  const cv::Matx33d k(camera.fx_px, 0, camera.cx_px, 0, camera.fy_px, camera.cy_px, 0, 0, 1);
  const std::vector<double> dist(camera.dist.begin(), camera.dist.end());
  const cv::Size size(camera.width_px, camera.height_px);
  cv::Mat map_x(size, CV_32FC1), map_y(size, CV_32FC1);
  {
    std::vector<cv::Point2f> pixels, undistorted;
    pixels.reserve(static_cast<size_t>(size.area()));
    for (int y = 0; y < size.height; ++y) {
      for (int x = 0; x < size.width; ++x) pixels.emplace_back(static_cast<float>(x), static_cast<float>(y));
    }
    cv::undistortPoints(pixels, undistorted, k, dist, cv::noArray(), k);
    for (int y = 0; y < size.height; ++y) {
      for (int x = 0; x < size.width; ++x) {
        map_x.at<float>(y, x) = undistorted[static_cast<size_t>(y * size.width + x)].x;
        map_y.at<float>(y, x) = undistorted[static_cast<size_t>(y * size.width + x)].y;
      }
    }
  }
  constexpr int kShift = 4;  // fillPoly's fractional bits
  const auto to_pixel = [&](double x_mm, double y_mm) {
    const Eigen::Vector3d in_cam = pose.rotation * Eigen::Vector3d(x_mm, y_mm, 0) + pose.translation_mm;
    return cv::Point(static_cast<int>(std::lround((camera.fx_px * in_cam.x() / in_cam.z() + camera.cx_px) * 16)),
                     static_cast<int>(std::lround((camera.fy_px * in_cam.y() / in_cam.z() + camera.cy_px) * 16)));
  };
  const auto quad = [&](double x0, double y0, double x1, double y1) {
    return std::vector<cv::Point>{to_pixel(x0, y0), to_pixel(x1, y0), to_pixel(x1, y1), to_pixel(x0, y1)};
  };
  const auto& board = std::get<CheckerboardLayout>(target.layout);
  const TargetExtent paper = target.PaperExtent();
  std::vector<std::vector<cv::Point>> squares;
  for (int j = 0; j <= board.rows; ++j) {
    for (int i = (j % 2 == 0) ? 0 : 1; i <= board.cols; i += 2) {  // square (0, 0) is black
      squares.push_back(quad((i - 1) * board.col_spacing_mm, (j - 1) * board.row_spacing_mm,
                             i * board.col_spacing_mm, j * board.row_spacing_mm));
    }
  }
  for (auto _ : state) {
    cv::Mat ideal(size, CV_8UC1, cv::Scalar(110));
    cv::fillPoly(ideal, std::vector{quad(paper.min_x_mm, paper.min_y_mm, paper.max_x_mm, paper.max_y_mm)},
                 cv::Scalar(220), cv::LINE_AA, kShift);
    cv::fillPoly(ideal, squares, cv::Scalar(30), cv::LINE_AA, kShift);
    cv::Mat warped, blurred, noise(size, CV_16SC1), image;
    cv::remap(ideal, warped, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(110));
    cv::GaussianBlur(warped, blurred, cv::Size(0, 0), 1.0);
    cv::randn(noise, 0, 1);
    cv::add(blurred, noise, image, cv::noArray(), CV_8U);
    benchmark::DoNotOptimize(image.data);
  }
  state.SetLabel("OpenCV: fillPoly + remap + GaussianBlur + randn, map given");
}
BENCHMARK(BM_RenderUnitTargetOpenCv)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_DetectUnitTarget(benchmark::State& state) {
  const auto target = LoadTargetDescription(TOPOCAL_SOURCE_DIR "/data/target-topographer.yaml");
  const cv::Mat& image = UnitView().image;
  size_t corners = 0;
  for (auto _ : state) {
    const auto view = DetectTarget(target, image);
    corners = view ? view->corners.size() : 0;
  }
  state.counters["corners"] = static_cast<double>(corners);
  state.SetLabel("topocal: classic on the pyramid + saddle fit, 4000 x 3000");
}
BENCHMARK(BM_DetectUnitTarget)->Unit(benchmark::kMillisecond);

void BM_DetectUnitTargetOpenCv(benchmark::State& state) {
  const cv::Mat& image = UnitView().image;
  const bool sb = state.range(0) != 0;
  size_t corners = 0;
  for (auto _ : state) {
    std::vector<cv::Point2f> found;
    bool ok = false;
    if (sb) {
      ok = cv::findChessboardCornersSB(image, cv::Size(13, 13), found, cv::CALIB_CB_NORMALIZE_IMAGE);
    } else {
      ok = cv::findChessboardCorners(image, cv::Size(13, 13), found);
      if (ok) {
        cv::cornerSubPix(image, found, cv::Size(11, 11), cv::Size(-1, -1),
                         cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 1e-3));
      }
    }
    corners = ok ? found.size() : 0;
  }
  state.counters["corners"] = static_cast<double>(corners);
  state.SetLabel(sb ? "findChessboardCornersSB (topocal's old first choice)"
                    : "findChessboardCorners + cornerSubPix, full resolution");
}
BENCHMARK(BM_DetectUnitTargetOpenCv)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace topocal::calib

