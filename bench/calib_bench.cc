// Calibration on OpenCV's 13 real chessboard photographs (left01..left14, 9x6 inner corners): detection, topocal's
// solve and cv::calibrateCamera on the same corners, in the same run.
//
//   build/bench/bench_calib [--benchmark_filter=...]
//
// The corners are detected once (cv::findChessboardCorners + cv::cornerSubPix, OpenCV's own recipe) so that both
// solvers see identical input; the detection is timed on its own, and with topocal's detector (calib/detect.h).
#include <filesystem>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "calib/calibrate.h"
#include "calib/detect.h"
#include "calib/target.h"

namespace {

using topocal::calib::CornerObservation;
using topocal::calib::ViewObservations;

constexpr double kSquareMm = 25.0;  // arbitrary: the photographs do not say
const cv::Size kPattern(9, 6);

std::vector<std::string> ImagePaths() {
  std::vector<std::string> paths;
  for (int i = 1; i <= 14; ++i) {
    const std::string p = std::string("/usr/share/doc/opencv-doc/examples/data/") + (i < 10 ? "left0" : "left") +
                          std::to_string(i) + ".jpg";
    if (std::filesystem::exists(p)) paths.push_back(p);
  }
  return paths;
}

struct Corners {
  std::vector<ViewObservations> views;
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> image;
  cv::Size size;
};

Corners DetectOpenCv(const std::vector<cv::Mat>& images) {
  Corners c;
  for (const auto& gray : images) {
    std::vector<cv::Point2f> pts;
    if (!cv::findChessboardCorners(gray, kPattern, pts)) continue;
    cv::cornerSubPix(gray, pts, cv::Size(11, 11), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 1e-3));
    c.size = gray.size();
    ViewObservations v;
    v.image_width = gray.cols;
    v.image_height = gray.rows;
    std::vector<cv::Point3f> obj;
    for (int k = 0; k < static_cast<int>(pts.size()); ++k) {
      CornerObservation o;
      o.id = k;
      o.image_px = {pts[k].x, pts[k].y};
      o.target_mm = {(k % kPattern.width) * kSquareMm, (k / kPattern.width) * kSquareMm, 0};
      v.corners.push_back(o);
      obj.emplace_back(static_cast<float>(o.target_mm.x()), static_cast<float>(o.target_mm.y()), 0.f);
    }
    c.views.push_back(v);
    c.object.push_back(obj);
    c.image.push_back(pts);
  }
  return c;
}

const std::vector<cv::Mat>& Images() {
  static const std::vector<cv::Mat> images = [] {
    std::vector<cv::Mat> out;
    for (const auto& p : ImagePaths()) out.push_back(cv::imread(p, cv::IMREAD_GRAYSCALE));
    return out;
  }();
  return images;
}

const Corners& SharedCorners() {
  static const Corners corners = DetectOpenCv(Images());
  return corners;
}

bool HaveData(benchmark::State& state) {
  if (SharedCorners().views.empty()) {
    state.SkipWithError("opencv-doc's left*.jpg are not installed");
    return false;
  }
  return true;
}

void BM_DetectOpenCv(benchmark::State& state) {
  if (!HaveData(state)) return;
  for (auto _ : state) benchmark::DoNotOptimize(DetectOpenCv(Images()));
  state.counters["views"] = static_cast<double>(SharedCorners().views.size());
}
BENCHMARK(BM_DetectOpenCv)->Unit(benchmark::kMillisecond);

void BM_DetectTopocal(benchmark::State& state) {
  if (!HaveData(state)) return;
  topocal::calib::TargetDescription target;
  target.layout = topocal::calib::CheckerboardLayout{9, 6, kSquareMm, kSquareMm};
  int found = 0;
  for (auto _ : state) {
    found = 0;
    for (const auto& img : Images()) found += topocal::calib::DetectTarget(target, img).has_value();
  }
  state.counters["views"] = found;
}
BENCHMARK(BM_DetectTopocal)->Unit(benchmark::kMillisecond);

void BM_SolveTopocal(benchmark::State& state) {
  if (!HaveData(state)) return;
  topocal::calib::CalibrationOptions options;
  options.loss = state.range(0) ? topocal::calib::RobustLoss::kHuber : topocal::calib::RobustLoss::kNone;
  options.reject_outliers = state.range(0) != 0;
  topocal::calib::CalibrationResult r;
  for (auto _ : state) r = topocal::calib::CalibrateMultiView(SharedCorners().views, options);
  state.counters["rms_px"] = r.rms_px;
  state.counters["fx_px"] = r.camera.fx_px;
  state.counters["fy_px"] = r.camera.fy_px;
  state.counters["iterations"] = r.solver.iterations;
  state.counters["outliers"] = static_cast<double>(r.outliers.size());
  state.SetLabel(state.range(0) ? "huber + outlier rejection" : "plain least squares (= OpenCV's problem)");
}
BENCHMARK(BM_SolveTopocal)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// cv::calibrateCamera with `flags` on the shared corners.
void SolveOpenCv(benchmark::State& state, int flags, const char* label) {
  if (!HaveData(state)) return;
  const auto& c = SharedCorners();
  double rms = 0;
  cv::Mat k, d;
  for (auto _ : state) {
    std::vector<cv::Mat> rvecs, tvecs;
    rms = cv::calibrateCamera(c.object, c.image, c.size, k, d, rvecs, tvecs, flags);
  }
  state.counters["rms_px"] = rms;
  state.counters["fx_px"] = k.at<double>(0, 0);
  state.counters["fy_px"] = k.at<double>(1, 1);
  state.SetLabel(label);
}

void BM_SolveOpenCv(benchmark::State& state) { SolveOpenCv(state, 0, "cv::calibrateCamera, default flags"); }
BENCHMARK(BM_SolveOpenCv)->Unit(benchmark::kMillisecond);

// OpenCV's rational lens model (k1..k6, p1, p2) on the same corners: topocal's rational8 and
// cv::calibrateCamera(CALIB_RATIONAL_MODEL) with its default termination, side by side.
void BM_SolveTopocalRational(benchmark::State& state) {
  if (!HaveData(state)) return;
  topocal::calib::CalibrationOptions options;
  options.model = *topocal::calib::ParseDistortionModel("rational8");
  options.max_iterations = 1000;
  topocal::calib::CalibrationResult r;
  for (auto _ : state) r = topocal::calib::CalibrateMultiView(SharedCorners().views, options);
  state.counters["rms_px"] = r.rms_px;
  state.counters["fx_px"] = r.camera.fx_px;
  state.counters["iterations"] = r.solver.iterations;
  state.SetLabel(r.ok() ? "rational8" : "rational8: " + r.message);
}
BENCHMARK(BM_SolveTopocalRational)->Unit(benchmark::kMillisecond);

void BM_SolveOpenCvRational(benchmark::State& state) {
  SolveOpenCv(state, cv::CALIB_RATIONAL_MODEL, "cv::calibrateCamera, CALIB_RATIONAL_MODEL");
}
BENCHMARK(BM_SolveOpenCvRational)->Unit(benchmark::kMillisecond);

// The whole job, image files to camera, each tool with its own detector: what `topocal calibrate` does (images
// read and detected on every available core, Arg 0, or on one, Arg 1) against OpenCV's classic recipe as its
// samples write it (one image after the other).
void BM_DetectAndSolveTopocal(benchmark::State& state) {
  if (!HaveData(state)) return;
  topocal::calib::TargetDescription target;
  target.layout = topocal::calib::CheckerboardLayout{9, 6, kSquareMm, kSquareMm};
  topocal::calib::FileSetOptions options;
  options.jobs = static_cast<int>(state.range(0));
  topocal::calib::CalibrationResult r;
  for (auto _ : state) {
    std::vector<ViewObservations> views;
    for (auto& f : topocal::calib::DetectTargetInFiles(target, ImagePaths(), options)) {
      if (f.detection.view) views.push_back(std::move(*f.detection.view));
    }
    r = topocal::calib::CalibrateMultiView(views, {});
  }
  state.counters["rms_px"] = r.rms_px;
  state.counters["fx_px"] = r.camera.fx_px;
  state.counters["fy_px"] = r.camera.fy_px;
  state.SetLabel(state.range(0) == 0 ? "DetectTargetInFiles (all cores) + CalibrateMultiView"
                                     : "DetectTargetInFiles (1 core) + CalibrateMultiView");
}
BENCHMARK(BM_DetectAndSolveTopocal)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_DetectAndSolveOpenCv(benchmark::State& state) {
  if (!HaveData(state)) return;
  double rms = 0;
  cv::Mat k, d;
  for (auto _ : state) {
    std::vector<cv::Mat> images;
    for (const auto& p : ImagePaths()) images.push_back(cv::imread(p, cv::IMREAD_GRAYSCALE));
    const Corners c = DetectOpenCv(images);
    std::vector<cv::Mat> rvecs, tvecs;
    rms = cv::calibrateCamera(c.object, c.image, c.size, k, d, rvecs, tvecs);
  }
  state.counters["rms_px"] = rms;
  state.counters["fx_px"] = k.at<double>(0, 0);
  state.counters["fy_px"] = k.at<double>(1, 1);
  state.SetLabel("imread + findChessboardCorners + cornerSubPix + calibrateCamera");
}
BENCHMARK(BM_DetectAndSolveOpenCv)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

