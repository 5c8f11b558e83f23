#include "calib/yaml_section.h"

#include <fmt/format.h>

#include <cctype>
#include <cmath>
#include <utility>

#include "util/io.h"

namespace topocal::calib {

YamlSection::YamlSection(cv::FileNode node, std::string origin, std::string key_prefix)
    : node_(std::move(node)), origin_(std::move(origin)), prefix_(std::move(key_prefix)) {}

bool YamlSection::Has(const std::string& key) const {
  const cv::FileNode node = node_[key];
  return !node.empty() && !node.isNone();
}

cv::FileNode YamlSection::Node(const std::string& key) {
  if (!Has(key)) Fail(key, "missing");
  read_.insert(key);
  return node_[key];
}

YamlSection YamlSection::Section(const std::string& key) {
  const cv::FileNode node = Node(key);
  if (!node.isMap()) Fail(key, "not a mapping");
  return YamlSection(node, origin_, prefix_ + key + ".");
}

std::string YamlSection::String(const std::string& key) {
  const cv::FileNode node = Node(key);
  if (!node.isString()) Fail(key, "not a string");
  std::string value = node.string();
  for (std::size_t hash = value.find('#'); hash != std::string::npos; hash = value.find('#', hash + 1)) {
    if (hash > 0 && std::isspace(static_cast<unsigned char>(value[hash - 1]))) {
      value.erase(hash);
      break;
    }
  }
  while (!value.empty() && std::isspace(static_cast<unsigned char>(value.back()))) value.pop_back();
  return value;
}

std::optional<std::string> YamlSection::OptionalString(const std::string& key) {
  if (!Has(key)) return std::nullopt;
  return String(key);
}

int YamlSection::Int(const std::string& key) {
  const cv::FileNode node = Node(key);
  if (!node.isInt()) Fail(key, "not an integer");
  return static_cast<int>(node);
}

int YamlSection::IntIn(const std::string& key, int lo, int hi) {
  const int value = Int(key);
  if (value < lo || value > hi) Fail(key, fmt::format("must be in [{}, {}], got {}", lo, hi, value));
  return value;
}

int YamlSection::PositiveInt(const std::string& key) {
  const int value = Int(key);
  if (value <= 0) Fail(key, "must be > 0");
  return value;
}

double YamlSection::Number(const std::string& key) {
  const cv::FileNode node = Node(key);
  if (!node.isReal() && !node.isInt()) Fail(key, "not a number");
  const double value = static_cast<double>(node);
  if (!std::isfinite(value)) Fail(key, "non-finite value");
  return value;
}

std::optional<double> YamlSection::OptionalNumber(const std::string& key) {
  if (!Has(key)) return std::nullopt;
  return Number(key);
}

std::vector<double> YamlSection::Numbers(const std::string& key, std::size_t n) {
  const cv::FileNode node = Node(key);
  if (!node.isSeq() || node.size() != n) Fail(key, fmt::format("expected a list of {} numbers", n));
  std::vector<double> out;
  for (const auto& v : node) {
    if (!v.isReal() && !v.isInt()) Fail(key, "not a number");
    out.push_back(static_cast<double>(v));
    if (!std::isfinite(out.back())) Fail(key, "non-finite value");
  }
  return out;
}

cv::Mat YamlSection::OptionalMatrix(const std::string& key, int rows, int cols) {
  if (!Has(key)) return {};
  return Matrix(key, rows, cols);
}

cv::Mat YamlSection::Matrix(const std::string& key, int rows, int cols) {
  const cv::FileNode node = Node(key);
  const bool is_vector = rows == 1 || cols == 1;
  if (node.isMap()) {
    const cv::FileNode r = node["rows"], c = node["cols"];
    if (!r.isInt() || !c.isInt()) Fail(key, "not an OpenCV matrix (rows, cols)");
    const int nr = static_cast<int>(r), nc = static_cast<int>(c);
    const bool vector_shape = is_vector && (nr == 1 || nc == 1) &&
                              static_cast<long long>(nr) * nc == static_cast<long long>(rows) * cols;
    if (!(nr == rows && nc == cols) && !vector_shape) {
      Fail(key, fmt::format("expected {}x{}, found {}x{}", rows, cols, nr, nc));
    }
  }
  cv::Mat m;
  try {
    node >> m;
  } catch (const cv::Exception&) {
    Fail(key, "not an OpenCV matrix");
  }
  if (m.empty()) Fail(key, "not an OpenCV matrix");
  const bool vector_ok = is_vector && static_cast<int>(m.total()) == rows * cols && m.channels() == 1;
  if (!(m.rows == rows && m.cols == cols) && !vector_ok) {
    Fail(key, fmt::format("expected {}x{}, found {}x{}", rows, cols, m.rows, m.cols));
  }
  m.convertTo(m, CV_64F);
  for (int i = 0; i < static_cast<int>(m.total()); ++i) {
    if (!std::isfinite(m.at<double>(i))) Fail(key, "non-finite value");
  }
  return m.reshape(1, rows);
}

void YamlSection::RejectUnknownKeys() const {
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    const std::string key = (*it).name();
    if (!read_.count(key)) Fail(key, "unknown key");
  }
}

void YamlSection::Fail(const std::string& key, const std::string& problem) const {
  throw util::InputError(fmt::format("{}: {}{}: {}", origin_, prefix_, key, problem));
}

}  // namespace topocal::calib
