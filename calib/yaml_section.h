#pragma once
// Strict reading of one YAML (or OpenCV FileStorage) mapping, shared by every YAML topocal reads — OpenCV
// calibration files (calib/calibration_file.cc), Kalibr targets (calib/target.cc), Kalibr camchains and ROS
// camera_info files (calib/camera_import.cc) — as util/json_section.h is for JSON: types, sizes and finiteness are
// checked, and every failure is one InputError "ORIGIN: KEY: problem" naming the file and the dotted key.
// The storage itself is opened by calib/file_storage.h (size, nesting and parser guards).
#include <cstddef>
#include <opencv2/core.hpp>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace topocal::calib {

class YamlSection {
 public:
  // `key_prefix` names the section in messages: "cam1." for a camchain's camera, "camera_matrix." for a matrix.
  YamlSection(cv::FileNode node, std::string origin, std::string key_prefix = "");

  // Present and not null.
  bool Has(const std::string& key) const;
  // The node of a key that must be present (marked read); "missing" otherwise.
  cv::FileNode Node(const std::string& key);
  // A mapping below this one, its keys prefixed "KEY." in messages; "missing" / "not a mapping".
  YamlSection Section(const std::string& key);

  // OpenCV keeps a trailing " # comment" in an unquoted scalar (`target_type: aprilgrid #gridtype`); String cuts
  // it off, as YAML reads it (a '#' after white space starts a comment).
  std::string String(const std::string& key);
  std::optional<std::string> OptionalString(const std::string& key);
  int Int(const std::string& key);
  // An integer in [lo, hi]: "must be in [lo, hi], got V".
  int IntIn(const std::string& key, int lo, int hi);
  int PositiveInt(const std::string& key);  // "must be > 0"
  // A finite number (a YAML integer counts: 1 is a length of one metre too).
  double Number(const std::string& key);
  std::optional<double> OptionalNumber(const std::string& key);
  // A list of exactly n finite numbers.
  std::vector<double> Numbers(const std::string& key, std::size_t n);
  // An OpenCV matrix (!!opencv-matrix) of rows x cols finite values, CV_64F; a vector (rows or cols 1) is accepted
  // as a row or a column. Its declared size is checked before OpenCV reads the data (a declared 1e5 x 1e5 matrix
  // would be allocated before the missing data were noticed). An absent optional matrix is empty.
  cv::Mat Matrix(const std::string& key, int rows, int cols);
  cv::Mat OptionalMatrix(const std::string& key, int rows, int cols);

  // Every key of the mapping must have been read: a misspelt key is an error, not a silent default.
  void RejectUnknownKeys() const;
  [[noreturn]] void Fail(const std::string& key, const std::string& problem) const;
  const std::string& Origin() const { return origin_; }

 private:
  cv::FileNode node_;
  std::string origin_;
  std::string prefix_;
  std::set<std::string> read_;
};

}  // namespace topocal::calib
