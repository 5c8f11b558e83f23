#include "calib/calibration_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <stdexcept>

#include "calib/file_storage.h"
#include "calib/yaml_section.h"
#include "calib/opencv_camera.h"
#include "calib/opencv_equivalent.h"
#include "calib/parameter_range.h"
#include "util/io.h"
#include "util/utc_date.h"
#include "util/version.h"
#include "util/json_section.h"

namespace topocal::calib {
namespace {

std::optional<double> SingleViewDistance(const CalibrationResult& r) {
  if (!r.single_view || r.cam_from_target.empty()) return std::nullopt;
  return r.cam_from_target.front().translation_mm.z();
}

// ---- strict reading ----------------------------------------------------------------------------------------------

void SetIntrinsics(const cv::Mat& k, YamlSection& yaml, const std::string& key, model::CameraModel& cam) {
  if (k.at<double>(0, 1) != 0 || k.at<double>(1, 0) != 0 || k.at<double>(2, 0) != 0 || k.at<double>(2, 1) != 0 ||
      k.at<double>(2, 2) != 1) {
    yaml.Fail(key, "not a pinhole camera matrix [fx 0 cx; 0 fy cy; 0 0 1]");
  }
  if (!(k.at<double>(0, 0) > 0 && k.at<double>(1, 1) > 0)) yaml.Fail(key, "focal lengths must be > 0");
  cam.fx_px = k.at<double>(0, 0);
  cam.fy_px = k.at<double>(1, 1);
  cam.cx_px = k.at<double>(0, 2);
  cam.cy_px = k.at<double>(1, 2);
}

CalibrationFile ReadCalibration(YamlSection& yaml);

// The coefficients (a row or column) into the camera, with the smallest lens model that holds them.
void SetDistortion(const cv::Mat& d, model::CameraModel& cam) {
  cam.dist = {};
  for (int i = 0; i < static_cast<int>(d.total()); ++i) cam.dist[static_cast<size_t>(i)] = d.at<double>(i);
  cam.lens = model::SmallestLensModelFor(cam.dist);
}

// OpenCV writes 4, 5, 8, 12 or 14 distortion coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]]) depending
// on the calibration flags of the tool that made the file. topocal's lens models hold the first eight (brown5 the
// first five, rational8 all eight): a shorter vector means the later ones are 0, a longer one is accepted only when
// the thin-prism and tilt terms are all zero. Returned as a row of at most kMaxLensParams.
cv::Mat ReadOpenCvDistortion(YamlSection& yaml, const std::string& key) {
  const cv::FileNode node = yaml.Node(key);
  cv::Mat d;
  try {
    node >> d;
  } catch (const cv::Exception&) {
    yaml.Fail(key, "not an OpenCV matrix");
  }
  const int n = static_cast<int>(d.total());
  if (d.empty() || d.channels() != 1 || (d.rows != 1 && d.cols != 1) || (n != 4 && n != 5 && n != 8 && n != 12 && n != 14)) {
    yaml.Fail(key, fmt::format("expected 4, 5, 8, 12 or 14 coefficients in a row or column, found {}x{}", d.rows, d.cols));
  }
  if (n == 5) return yaml.Matrix(key, 1, 5);
  d.convertTo(d, CV_64F);
  cv::Mat held = cv::Mat::zeros(1, std::min(n, model::kMaxLensParams), CV_64F);
  for (int i = 0; i < n; ++i) {
    const double v = d.at<double>(i);
    if (!std::isfinite(v)) yaml.Fail(key, "non-finite value");
    if (i < model::kMaxLensParams) {
      held.at<double>(i) = v;
    } else if (v != 0) {
      yaml.Fail(key, fmt::format("coefficient {} is {} but topocal's lens models end at k6 (OpenCV's thin-prism and "
                                 "tilt terms must be 0)", i + 1, v));
    }
  }
  return held;
}

}  // namespace

std::string CalibrationFileText(const CalibrationResult& result, const CalibrationProvenance& provenance) {
  if (!result.ok()) throw util::InputError("calibration file requested for a failed calibration");
  const auto equivalent = ToOpenCvModel(result.camera);
  if (!equivalent) {
    throw std::runtime_error("the calibrated camera has no OpenCV equivalent over the image (distortion not "
                             "invertible at the image border)");
  }
  cv::FileStorage fs(".yml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  fs << "calibration_tool" << "topocal";
  fs << "tool_version" << topocal::kVersion;
  fs << "calibration_date" << (provenance.date_utc.empty() ? util::FileDateUtc() : provenance.date_utc);
  fs << "model" << std::string(ToString(result.model));
  fs << "single_view" << (result.single_view ? 1 : 0);
  fs << "image_width" << result.camera.width_px;
  fs << "image_height" << result.camera.height_px;
  fs << "camera_matrix" << cv::Mat(OpenCvCameraMatrix(equivalent->camera));
  fs << "distortion_coefficients" << OpenCvDistCoeffs(equivalent->camera);
  fs << "distortion_centre"
     << (cv::Mat_<double>(1, 2) << result.camera.distortion_centre.x(), result.camera.distortion_centre.y());
  if (!result.camera.distortion_centre.isZero(0)) {
    fs << "topocal_camera_matrix" << cv::Mat(OpenCvCameraMatrix(result.camera));
    fs << "topocal_distortion_coefficients" << OpenCvDistCoeffs(result.camera);
    fs << "opencv_equivalent_max_error_px" << equivalent->max_error_px;
  }
  fs << "parameter_names" << "[";
  for (const auto& p : result.parameters) fs << p.name;
  fs << "]";
  cv::Mat values(1, static_cast<int>(result.parameters.size()), CV_64F);
  cv::Mat stddev(1, static_cast<int>(result.parameters.size()), CV_64F);
  for (size_t i = 0; i < result.parameters.size(); ++i) {
    values.at<double>(static_cast<int>(i)) = result.parameters[i].value;
    stddev.at<double>(static_cast<int>(i)) = result.parameters[i].stddev;
  }
  fs << "parameter_values" << values;
  fs << "parameter_stddev" << stddev;
  if (result.covariance.rows() == static_cast<Eigen::Index>(result.parameters.size()) &&
      result.covariance.cols() == result.covariance.rows()) {
    cv::Mat cov(result.covariance.rows(), result.covariance.cols(), CV_64F);
    for (int i = 0; i < cov.rows; ++i) {
      for (int j = 0; j < cov.cols; ++j) cov.at<double>(i, j) = result.covariance(i, j);
    }
    fs << "parameter_covariance" << cov;
  }
  fs << "rms_px" << result.rms_px;
  fs << "per_view_rms_px" << result.per_view_rms_px;
  fs << "views_used" << static_cast<int>(result.views_used.size());
  fs << "images" << "[";
  for (const int v : result.views_used) {
    fs << (static_cast<size_t>(v) < provenance.image_paths.size() && !provenance.image_paths[static_cast<size_t>(v)].empty()
               ? provenance.image_paths[static_cast<size_t>(v)]
               : fmt::format("view {}", v));
  }
  fs << "]";
  fs << "outliers" << static_cast<int>(result.outliers.size());
  if (result.fixed_aspect_ratio > 0) fs << "fixed_aspect_ratio" << result.fixed_aspect_ratio;
  if (result.seidel) {
    fs << "seidel_sigma_per_mm2" << result.seidel->sigma_per_mm2;
    fs << "seidel_sigma_stddev_per_mm2" << result.seidel->sigma_stddev_per_mm2;
    fs << "magnification" << result.seidel->magnification;
  }
  // The sensor geometry whenever it is known (the correction maps pixels to mm with it).
  if (result.focal_mm > 0) fs << "focal_mm" << result.focal_mm;
  if (result.pixel_pitch_um > 0) fs << "pixel_pitch_um" << result.pixel_pitch_um;
  if (const auto d = SingleViewDistance(result)) fs << "target_distance_mm" << *d;
  if (!provenance.target_path.empty()) fs << "target" << provenance.target_path;
  const DistortionValidRegion region = ValidRegionOf(result.camera);
  fs << "valid_radius_px" << region.radius_px;
  fs << "valid_region_covers_sensor" << (region.covers_sensor ? 1 : 0);
  return fs.releaseAndGetString();
}

void WriteCalibrationFile(const std::string& path, const CalibrationResult& result,
                          const CalibrationProvenance& provenance) {
  util::WriteFileAtomic(path, CalibrationFileText(result, provenance));
}

CalibrationFile LoadCalibrationFile(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) throw util::InputError(fmt::format("{}: cannot be opened", path));
  return ParseCalibrationFile(util::ReadFile(path), path);
}

CalibrationFile ParseCalibrationFile(const std::string& text, const std::string& path) {
  const cv::FileStorage fs = OpenFileStorage(text, path);
  // A node of an unexpected type deep in the file: bad input, not a crash.
  return ReadFileStorage(path, "a calibration", [&] {
    YamlSection yaml(fs.root(), path);
    return ReadCalibration(yaml);
  });
}

namespace {

Eigen::MatrixXd ReadCovariance(YamlSection& yaml, int n) {
  const cv::Mat cov = yaml.Matrix("parameter_covariance", n, n);
  Eigen::MatrixXd m(n, n);
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) m(r, c) = cov.at<double>(r, c);
  }
  // Written symmetric to full precision; anything beyond rounding is a corrupt file.
  constexpr double kSymmetryTolerance = 1e-9;
  if (!m.allFinite()) yaml.Fail("parameter_covariance", "non-finite entry");
  if ((m - m.transpose()).cwiseAbs().maxCoeff() > kSymmetryTolerance * m.cwiseAbs().maxCoeff()) {
    yaml.Fail("parameter_covariance", "not symmetric");
  }
  for (int d = 0; d < n; ++d) {
    if (m(d, d) < 0) yaml.Fail("parameter_covariance", "negative variance on the diagonal");
  }
  return m;
}

// The fields only topocal writes: its model, the exact camera, the fit's quality, parameters and provenance.
void ReadTopocalFields(YamlSection& yaml, CalibrationFile& out) {
  const model::CameraModel& cv_cam = out.opencv_camera;
  out.model = yaml.OptionalString("model").value_or("");
  if (out.model.empty()) yaml.Fail("model", "missing");
  const auto kind = ParseDistortionModel(out.model);
  if (!kind) yaml.Fail("model", fmt::format("'{}' is not one of {}", out.model, DistortionModelNames()));
  if (model::LensParameterCount(cv_cam.lens) > model::LensParameterCount(kind->lens)) {
    yaml.Fail("distortion_coefficients", fmt::format("more coefficients than model {} has", out.model));
  }
  out.opencv_camera.lens = out.camera.lens = kind->lens;
  const cv::Mat centre = yaml.Matrix("distortion_centre", 1, 2);
  if (centre.at<double>(0) != 0 || centre.at<double>(1) != 0) {
    model::CameraModel exact = out.camera;
    SetIntrinsics(yaml.Matrix("topocal_camera_matrix", 3, 3), yaml, "topocal_camera_matrix", exact);
    SetDistortion(yaml.Matrix("topocal_distortion_coefficients", 1, model::LensParameterCount(kind->lens)), exact);
    exact.lens = kind->lens;
    exact.distortion_centre = {centre.at<double>(0), centre.at<double>(1)};
    out.camera = exact;
  }
  out.single_view = yaml.OptionalNumber("single_view").value_or(0) != 0;
  out.rms_px = yaml.OptionalNumber("rms_px");
  if (!out.rms_px) yaml.Fail("rms_px", "missing");
  if (yaml.Has("per_view_rms_px")) {
    const cv::FileNode per_view = yaml.Node("per_view_rms_px");
    if (!per_view.isSeq()) yaml.Fail("per_view_rms_px", "not a sequence");
    for (const auto& n : per_view) out.per_view_rms_px.push_back(static_cast<double>(n));
  }
  if (yaml.Has("parameter_names")) {
    const cv::FileNode names = yaml.Node("parameter_names");
    const cv::Mat sd = yaml.Matrix("parameter_stddev", 1, static_cast<int>(names.size()));
    int i = 0;
    for (const auto& n : names) {
      out.parameter_names.push_back(static_cast<std::string>(n));
      out.stddev[out.parameter_names.back()] = sd.at<double>(i++);
    }
  }
  // Absent in files from before topocal 0.1.0 stored it; ParameterCovarianceOf then falls back to the diagonal.
  if (yaml.Has("parameter_covariance")) {
    out.covariance = ReadCovariance(yaml, static_cast<int>(out.parameter_names.size()));
  }
  out.sigma_per_mm2 = yaml.OptionalNumber("seidel_sigma_per_mm2");
  out.sigma_stddev_per_mm2 = yaml.OptionalNumber("seidel_sigma_stddev_per_mm2");
  out.magnification = yaml.OptionalNumber("magnification");
  out.focal_mm = yaml.OptionalNumber("focal_mm");
  out.pixel_pitch_um = yaml.OptionalNumber("pixel_pitch_um");
  out.target = yaml.OptionalString("target").value_or("");
  out.date = yaml.OptionalString("calibration_date").value_or("");
  out.tool_version = yaml.OptionalString("tool_version").value_or("");
}

// The valid region: stored by topocal since it states it, computed for older and plain OpenCV files.
void ReadValidRegion(YamlSection& yaml, CalibrationFile& out) {
  const auto radius_px = yaml.OptionalNumber("valid_radius_px");
  if (radius_px) {
    if (!(*radius_px > 0)) yaml.Fail("valid_radius_px", "must be > 0");
    out.valid_region.radius_px = *radius_px;
    out.valid_region.covers_sensor = *radius_px >= FarthestSensorPixelPx(out.camera);
    const auto covers = yaml.OptionalNumber("valid_region_covers_sensor");
    if (covers && (*covers != 0) != out.valid_region.covers_sensor) {
      yaml.Fail("valid_region_covers_sensor", "contradicts valid_radius_px and the image size");
    }
  } else {
    out.valid_region = ValidRegionOf(out.camera);
  }
}

CalibrationFile ReadCalibration(YamlSection& yaml) {
  if (!yaml.Has("camera_matrix") && !yaml.Has("distortion_coefficients")) {
    yaml.Fail("camera_matrix", "missing: not a topocal or OpenCV calibration file");
  }
  CalibrationFile out;
  const std::string tool = yaml.OptionalString("calibration_tool").value_or("");
  out.written_by_topocal = tool == "topocal";
  if (!tool.empty() && !out.written_by_topocal) yaml.Fail("calibration_tool", "'" + tool + "' is not topocal");

  model::CameraModel cv_cam;
  cv_cam.width_px = yaml.PositiveInt("image_width");
  cv_cam.height_px = yaml.PositiveInt("image_height");
  SetIntrinsics(yaml.Matrix("camera_matrix", 3, 3), yaml, "camera_matrix", cv_cam);
  SetDistortion(ReadOpenCvDistortion(yaml, "distortion_coefficients"), cv_cam);
  out.opencv_camera = cv_cam;
  out.camera = cv_cam;

  if (out.written_by_topocal) ReadTopocalFields(yaml, out);
  ReadValidRegion(yaml, out);
  return out;
}

}  // namespace

ParameterCovariance ParameterCovarianceOf(const CalibrationFile& file) {
  ParameterCovariance c;
  c.names = file.parameter_names;
  if (file.covariance) {
    c.matrix = *file.covariance;
    c.full = true;
    return c;
  }
  c.matrix = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(c.names.size()), static_cast<Eigen::Index>(c.names.size()));
  for (size_t i = 0; i < c.names.size(); ++i) {
    const auto it = file.stddev.find(c.names[i]);
    if (it != file.stddev.end()) c.matrix(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(i)) = it->second * it->second;
  }
  return c;
}

namespace {

// Free parameters the views do not determine (calib/parameter_range.h): empty when all are.
nlohmann::json UndeterminedJson(const CalibrationResult& result) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& u : UndeterminedParameters(result)) {
    out.push_back({{"name", u.name}, {"value", u.value}, {"stddev", u.stddev},
                   {"plausible_half_range", u.plausible_half_range}});
  }
  return out;
}

}  // namespace

std::string CalibrationReportJson(const CalibrationResult& result, const CalibrationProvenance& provenance) {
  using nlohmann::json;
  const auto image = [&](int v) {
    return static_cast<size_t>(v) < provenance.image_paths.size() ? provenance.image_paths[static_cast<size_t>(v)]
                                                                  : fmt::format("view {}", v);
  };
  json j;
  j["status"] = std::string(ToString(result.status));
  j["message"] = result.message;
  j["model"] = std::string(ToString(result.model));
  j["single_view"] = result.single_view;
  j["skipped_views"] = json::array();
  for (const auto& s : result.skipped_views) j["skipped_views"].push_back({{"image", image(s.view)}, {"reason", s.reason}});
  if (!result.ok()) return util::JsonFileText(j);
  const auto& c = result.camera;
  j["image_width"] = c.width_px;
  j["image_height"] = c.height_px;
  j["rms_px"] = result.rms_px;
  j["camera_matrix"] = {{c.fx_px, 0.0, c.cx_px}, {0.0, c.fy_px, c.cy_px}, {0.0, 0.0, 1.0}};
  j["dist_coeffs"] = std::vector<double>(c.dist.begin(), c.dist.begin() + model::LensParameterCount(c.lens));
  j["distortion_centre"] = {c.distortion_centre.x(), c.distortion_centre.y()};
  j["stddev"] = json::object();
  j["fixed"] = json::array();
  for (const auto& p : result.parameters) {
    j["stddev"][p.name] = p.stddev;
    if (p.fixed) j["fixed"].push_back(p.name);
  }
  j["undetermined"] = UndeterminedJson(result);
  if (result.covariance.size() > 0) {
    j["covariance"] = json::array();
    for (Eigen::Index r = 0; r < result.covariance.rows(); ++r) {
      json row = json::array();
      for (Eigen::Index col = 0; col < result.covariance.cols(); ++col) row.push_back(result.covariance(r, col));
      j["covariance"].push_back(row);
    }
  }
  j["views_used"] = result.views_used.size();
  j["images_used"] = json::array();
  for (const int v : result.views_used) j["images_used"].push_back(image(v));
  j["per_view_rms_px"] = result.per_view_rms_px;
  j["corners_used"] = result.corners_used;
  j["residual_sigma_px"] = std::sqrt(result.residual_variance_px2);
  j["outliers"] = json::array();
  for (const auto& o : result.outliers) {
    j["outliers"].push_back({{"image", image(o.view)},
                             {"corner_id", o.corner_id},
                             {"observed_px", {o.observed_px.x(), o.observed_px.y()}},
                             {"residual_px", {o.residual_px.x(), o.residual_px.y()}}});
  }
  if (result.seidel) {
    j["seidel"] = {{"sigma_per_mm2", result.seidel->sigma_per_mm2},
                   {"sigma_stddev_per_mm2", result.seidel->sigma_stddev_per_mm2},
                   {"magnification", result.seidel->magnification},
                   {"focal_mm", result.seidel->focal_mm}};
  }
  if (result.fixed_aspect_ratio > 0) j["fixed_aspect_ratio"] = result.fixed_aspect_ratio;
  if (result.board_warp) {
    const auto& w = *result.board_warp;
    j["board_warp"] = {{"sag_x_mm", w.sag_x_mm},
                       {"sag_x_stddev_mm", w.sag_x_stddev_mm},
                       {"sag_y_mm", w.sag_y_mm},
                       {"sag_y_stddev_mm", w.sag_y_stddev_mm},
                       {"centre_mm", {w.centre_mm.x(), w.centre_mm.y()}},
                       {"half_size_mm", {w.half_size_mm.x(), w.half_size_mm.y()}}};
  }
  if (const auto d = SingleViewDistance(result)) j["target_distance_mm"] = *d;
  if (result.focal_mm > 0) j["focal_mm"] = result.focal_mm;
  if (result.pixel_pitch_um > 0) j["pixel_pitch_um"] = result.pixel_pitch_um;
  j["solver"] = {{"converged", result.solver.converged},
                 {"iterations", result.solver.iterations},
                 {"initial_cost", result.solver.initial_cost},
                 {"final_cost", result.solver.final_cost},
                 {"outlier_rounds", result.outlier_rounds},
                 {"message", result.solver.message}};
  return util::JsonFileText(j);
}

}  // namespace topocal::calib
