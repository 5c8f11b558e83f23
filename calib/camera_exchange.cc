#include "calib/camera_exchange.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <vector>

#include "calib/distortion_valid_region.h"
#include "calib/file_storage.h"
#include "util/io.h"

namespace topocal::calib {
namespace {

// A real number that reads back bit for bit and that every consumer takes as a float: PyYAML (YAML 1.1) reads
// "1e-05" as a string, so the mantissa always carries a decimal point ("1.0e-05").
std::string Real(double v) {
  if (!std::isfinite(v)) throw std::invalid_argument("non-finite value in a calibration export");
  std::string s = fmt::format("{:.17g}", v);
  if (s.find_first_of(".") == std::string::npos) {
    const auto e = s.find_first_of("eE");
    if (e == std::string::npos) {
      s += ".0";
    } else {
      s.insert(e, ".0");
    }
  }
  return s;
}

std::string List(const std::vector<double>& values) {
  std::string s = "[";
  for (size_t i = 0; i < values.size(); ++i) s += (i ? ", " : "") + Real(values[i]);
  return s + "]";
}

void RequireOpenCvModel(const model::CameraModel& c) {
  if (!c.distortion_centre.isZero(0)) {
    throw std::invalid_argument("export needs OpenCV's model (distortion centre 0): use CalibrationFile::opencv_camera");
  }
}

[[noreturn]] void Bad(const std::string& path, const std::string& key, const std::string& problem) {
  throw util::InputError(fmt::format("{}: {}: {}", path, key, problem));
}

std::vector<double> ReadNumbers(const cv::FileNode& map, const std::string& path, const std::string& key, size_t n) {
  const cv::FileNode node = map[key];
  if (node.empty()) Bad(path, key, "missing");
  if (!node.isSeq() || node.size() != n) Bad(path, key, fmt::format("expected a list of {} numbers", n));
  std::vector<double> out;
  for (const auto& v : node) {
    if (!v.isReal() && !v.isInt()) Bad(path, key, "not a number");
    out.push_back(static_cast<double>(v));
    if (!std::isfinite(out.back())) Bad(path, key, "non-finite value");
  }
  return out;
}

std::string ReadString(const cv::FileNode& map, const std::string& path, const std::string& key) {
  const cv::FileNode node = map[key];
  if (node.empty()) Bad(path, key, "missing");
  if (!node.isString()) Bad(path, key, "not a string");
  return static_cast<std::string>(node);
}

// PyYAML (which writes Kalibr's camchains) puts a block sequence at the indentation of its key:
//   T_cn_cnm1:
//   - [1.0, 0.0, 0.0, 0.1]
// YAML allows it; cv::FileStorage's parser does not. Such a sequence (its items and their continuation lines) is
// indented by two more spaces, which means the same to YAML and reads in cv::FileStorage.
std::string IndentCompactSequences(const std::string& text) {
  std::vector<std::string> lines;
  for (size_t start = 0; start <= text.size();) {
    const size_t end = text.find('\n', start);
    lines.push_back(text.substr(start, end == std::string::npos ? std::string::npos : end - start));
    if (end == std::string::npos) break;
    start = end + 1;
  }
  const auto indent = [](const std::string& l) { return l.find_first_not_of(' '); };
  const auto is_item = [&](const std::string& l) {
    const size_t i = indent(l);
    return i != std::string::npos && l[i] == '-' && (i + 1 == l.size() || l[i + 1] == ' ');
  };
  std::string out;
  for (size_t i = 0; i < lines.size(); ++i) {
    out += lines[i] + (i + 1 < lines.size() ? "\n" : "");
    const size_t key_indent = indent(lines[i]);
    const auto trimmed_end = lines[i].find_last_not_of(" \t\r");
    if (key_indent == std::string::npos || is_item(lines[i]) || trimmed_end == std::string::npos ||
        lines[i][trimmed_end] != ':' || i + 1 >= lines.size() || !is_item(lines[i + 1]) ||
        indent(lines[i + 1]) != key_indent) {
      continue;
    }
    // The sequence: items at the key's indentation and anything indented deeper, up to the next line at or left of
    // the key that is not an item.
    size_t j = i + 1;
    for (; j < lines.size(); ++j) {
      const size_t n = indent(lines[j]);
      if (n == std::string::npos) continue;  // blank
      if (n < key_indent || (n == key_indent && !is_item(lines[j]))) break;
      lines[j] = "  " + lines[j];
    }
  }
  return out;
}

}  // namespace

std::optional<ExportFormat> ParseExportFormat(const std::string& name) {
  if (name == "ros") return ExportFormat::kRos;
  if (name == "kalibr") return ExportFormat::kKalibr;
  if (name == "mrcal") return ExportFormat::kMrcal;
  if (name == "opencv") return ExportFormat::kOpenCv;
  return std::nullopt;
}

// ROS camera_calibration_parsers' YAML (sensor_msgs/CameraInfo). Monocular: R = I and P = [K | 0], i.e. the
// rectified image keeps the camera matrix (what image_proc's rectify then produces with cv::undistort).
std::string RosCameraInfoYaml(const model::CameraModel& c, const std::string& camera_name) {
  RequireOpenCvModel(c);
  std::string s;
  s += fmt::format("image_width: {}\nimage_height: {}\ncamera_name: {}\n", c.width_px, c.height_px, camera_name);
  s += "camera_matrix:\n  rows: 3\n  cols: 3\n  data: " +
       List({c.fx_px, 0, c.cx_px, 0, c.fy_px, c.cy_px, 0, 0, 1}) + "\n";
  s += "distortion_model: plumb_bob\n";
  s += "distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: " +
       List({c.dist[0], c.dist[1], c.dist[2], c.dist[3], c.dist[4]}) + "\n";
  s += "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: " + List({1, 0, 0, 0, 1, 0, 0, 0, 1}) + "\n";
  s += "projection_matrix:\n  rows: 3\n  cols: 4\n  data: " +
       List({c.fx_px, 0, c.cx_px, 0, 0, c.fy_px, c.cy_px, 0, 0, 0, 1, 0}) + "\n";
  return s;
}

// Kalibr's camchain (kalibr_calibrate_cameras output, one camera): pinhole + radtan [k1 k2 r1 r2], which is
// OpenCV's plumb_bob without k3.
std::string KalibrCamchainYaml(const model::CameraModel& c, const std::string& ros_topic) {
  RequireOpenCvModel(c);
  std::string s = "cam0:\n";
  s += "  camera_model: pinhole\n";
  s += "  intrinsics: " + List({c.fx_px, c.fy_px, c.cx_px, c.cy_px}) + "\n";
  s += "  distortion_model: radtan\n";
  s += "  distortion_coeffs: " + List({c.dist[0], c.dist[1], c.dist[2], c.dist[3]}) + "\n";
  s += fmt::format("  resolution: [{}, {}]\n", c.width_px, c.height_px);
  s += "  rostopic: " + ros_topic + "\n";
  return s;
}

// mrcal's .cameramodel (a Python literal dict). LENSMODEL_OPENCV5 is exactly OpenCV's 5-coefficient model
// (fx fy cx cy k1 k2 p1 p2 k3); the extrinsics are the identity (rt_cam_ref = 0): one camera, its own frame.
std::string MrcalCameraModelText(const model::CameraModel& c, const DistortionValidRegion* valid_region) {
  RequireOpenCvModel(c);
  std::string s = "# generated by topocal (calib/camera_exchange.cc)\n{\n";
  s += "    'lensmodel':  'LENSMODEL_OPENCV5',\n";
  s += "    # fx fy cx cy k1 k2 p1 p2 k3\n";
  s += "    'intrinsics': " +
       List({c.fx_px, c.fy_px, c.cx_px, c.cy_px, c.dist[0], c.dist[1], c.dist[2], c.dist[3], c.dist[4]}) + ",\n";
  s += "    'extrinsics': " + List({0, 0, 0, 0, 0, 0}) + ",\n";
  s += fmt::format("    'imagersize': [{}, {}],\n", c.width_px, c.height_px);
  if (valid_region) {
    constexpr int kContourPoints = 64;
    s += "    'valid_intrinsics_region': [\n";
    for (int k = 0; k <= kContourPoints; ++k) {  // closed: the last point is the first
      const double a = 2.0 * std::numbers::pi * (k % kContourPoints) / kContourPoints;
      s += "        " + List({c.cx_px + valid_region->radius_px * std::cos(a),
                             c.cy_px + valid_region->radius_px * std::sin(a)}) + ",\n";
    }
    s += "    ],\n";
  }
  s += "}\n";
  return s;
}

std::string OpenCvCalibrationText(const model::CameraModel& c, const std::string& imported_from) {
  RequireOpenCvModel(c);
  cv::FileStorage fs(".yml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  fs << "image_width" << c.width_px;
  fs << "image_height" << c.height_px;
  fs << "camera_matrix" << (cv::Mat_<double>(3, 3) << c.fx_px, 0, c.cx_px, 0, c.fy_px, c.cy_px, 0, 0, 1);
  fs << "distortion_coefficients" << (cv::Mat_<double>(1, 5) << c.dist[0], c.dist[1], c.dist[2], c.dist[3], c.dist[4]);
  const DistortionValidRegion region = ValidRegionOf(c);
  fs << "valid_radius_px" << region.radius_px;
  fs << "valid_region_covers_sensor" << (region.covers_sensor ? 1 : 0);
  if (!imported_from.empty()) fs << "imported_from" << imported_from;
  return fs.releaseAndGetString();
}

double DropK3ShiftPx(const model::CameraModel& camera) {
  if (camera.dist[4] == 0) return 0;
  model::CameraModel without = camera;
  without.dist[4] = 0;
  // The border carries the largest radius; 64 samples per side resolve a shift that grows smoothly with radius.
  constexpr int kSamplesPerSide = 64;
  const double w = camera.width_px - 1.0, h = camera.height_px - 1.0;
  double worst = 0;
  int converged = 0;
  for (int i = 0; i <= kSamplesPerSide; ++i) {
    const double t = static_cast<double>(i) / kSamplesPerSide;
    for (const Eigen::Vector2d& px : {Eigen::Vector2d(t * w, 0), Eigen::Vector2d(t * w, h), Eigen::Vector2d(0, t * h),
                                     Eigen::Vector2d(w, t * h)}) {
      const auto u = camera.PixelToNormalized(px);
      if (!u) continue;
      ++converged;
      worst = std::max(worst, (without.Project(Eigen::Vector3d(u->x(), u->y(), 1)) - px).norm());
    }
  }
  return converged > 0 ? worst : std::numeric_limits<double>::infinity();
}

std::string ExportCalibration(const CalibrationFile& calibration, ExportFormat format, const std::string& source,
                              const ExportOptions& options) {
  const model::CameraModel& c = calibration.opencv_camera;
  switch (format) {
    case ExportFormat::kRos:
      return RosCameraInfoYaml(c, options.camera_name);
    case ExportFormat::kKalibr: {
      const double shift_px = DropK3ShiftPx(c);
      if (!(shift_px <= kKalibrDropK3TolerancePx)) {
        throw util::InputError(fmt::format(
            "{}: distortion_coefficients: Kalibr's radtan model has no k3, and dropping k3 = {:.6g} moves the image "
            "border by {:.3g} px (> {} px); calibrate with --fix k3, or export to ros or mrcal",
            source, c.dist[4], shift_px, kKalibrDropK3TolerancePx));
      }
      return KalibrCamchainYaml(c, options.ros_topic);
    }
    case ExportFormat::kMrcal:
      return MrcalCameraModelText(c, calibration.valid_region.covers_sensor ? nullptr : &calibration.valid_region);
    case ExportFormat::kOpenCv:
      return OpenCvCalibrationText(c, source);
  }
  throw std::invalid_argument("unknown export format");
}

model::CameraModel ReadKalibrCamchain(const std::string& path, const std::string& camera_key) {
  // cv::FileStorage only reads YAML that starts with a "%YAML" directive; Kalibr writes none (as calib/target.cc).
  std::string text = util::ReadFile(path);
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) Bad(path, "file", "empty");
  if (text.compare(first, 5, "%YAML") != 0) text = "%YAML:1.0\n---\n" + text;
  text = IndentCompactSequences(text);
  const cv::FileStorage fs = OpenFileStorage(text, path);  // the one door: size and nesting checked first
  return ReadFileStorage(path, "a Kalibr camchain", [&]() -> model::CameraModel {
    if (!fs.isOpened() || !fs.root().isMap()) Bad(path, "file", "not a YAML mapping (a Kalibr camchain has cam0: ...)");
    const cv::FileNode cam = fs[camera_key];
    if (cam.empty()) Bad(path, camera_key, "missing: not a Kalibr camchain, or no such camera");
    if (!cam.isMap()) Bad(path, camera_key, "not a mapping");
    const std::string where = camera_key + ".";
    const std::string model_name = ReadString(cam, path, "camera_model");
    if (model_name != "pinhole") {
      Bad(path, where + "camera_model", fmt::format("'{}': only pinhole is supported (OpenCV's model)", model_name));
    }
    const std::string distortion = ReadString(cam, path, "distortion_model");
    if (distortion != "radtan") {
      Bad(path, where + "distortion_model",
          fmt::format("'{}': only radtan is supported (equidistant is a fisheye model topocal does not fit)",
                      distortion));
    }
    const auto intrinsics = ReadNumbers(cam, path, "intrinsics", 4);
    const auto coeffs = ReadNumbers(cam, path, "distortion_coeffs", 4);
    const auto resolution = ReadNumbers(cam, path, "resolution", 2);
    model::CameraModel c;
    for (int i = 0; i < 2; ++i) {
      const double v = resolution[static_cast<size_t>(i)];
      if (!(v >= 1) || v != std::floor(v) || v > std::numeric_limits<int>::max()) {
        Bad(path, where + "resolution", "must be two positive integers [width, height]");
      }
    }
    c.width_px = static_cast<int>(resolution[0]);
    c.height_px = static_cast<int>(resolution[1]);
    if (!(intrinsics[0] > 0 && intrinsics[1] > 0)) Bad(path, where + "intrinsics", "focal lengths fu, fv must be > 0");
    c.fx_px = intrinsics[0];
    c.fy_px = intrinsics[1];
    c.cx_px = intrinsics[2];
    c.cy_px = intrinsics[3];
    c.dist = {coeffs[0], coeffs[1], coeffs[2], coeffs[3], 0.0};
    return c;
  });
}

}  // namespace topocal::calib
