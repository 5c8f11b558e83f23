#include "calib/target.h"

#include <cctype>
#include <cmath>
#include <set>

#include <fmt/format.h>
#include <opencv2/core.hpp>

#include "model/io.h"

namespace topocal::calib {
namespace {

constexpr double kMmPerMetre = 1000.0;

// Reads the keys of one YAML mapping strictly: every key must be consumed exactly as its expected type.
class StrictMap {
 public:
  StrictMap(const cv::FileNode& root, std::string name) : root_(root), name_(std::move(name)) {}

  std::string String(const std::string& key) {
    const cv::FileNode node = Find(key);
    if (!node.isString()) Fail(key, "must be a string");
    // OpenCV keeps a trailing "# comment" in an unquoted scalar (`target_type: aprilgrid #gridtype`); none of
    // our string values contains '#', so cut it off.
    std::string value = node.string();
    if (const auto hash = value.find('#'); hash != std::string::npos) value.erase(hash);
    while (!value.empty() && std::isspace(static_cast<unsigned char>(value.back()))) value.pop_back();
    return value;
  }
  int PositiveInt(const std::string& key) {
    const cv::FileNode node = Find(key);
    if (!node.isInt()) Fail(key, "must be an integer");
    const int value = static_cast<int>(node);
    if (value <= 0) Fail(key, fmt::format("must be positive, got {}", value));
    return value;
  }
  int NonNegativeInt(const std::string& key, int fallback) {
    if (!Has(key)) return fallback;
    const cv::FileNode node = Find(key);
    if (!node.isInt()) Fail(key, "must be an integer");
    const int value = static_cast<int>(node);
    if (value < 0) Fail(key, fmt::format("must not be negative, got {}", value));
    return value;
  }
  double PositiveReal(const std::string& key) {
    const cv::FileNode node = Find(key);
    // YAML writes 1 as an integer; a length of exactly one metre is still a number.
    if (!node.isReal() && !node.isInt()) Fail(key, "must be a number");
    const double value = static_cast<double>(node);
    if (!std::isfinite(value) || value <= 0) Fail(key, fmt::format("must be a positive number, got {}", value));
    return value;
  }
  bool Has(const std::string& key) const {
    const cv::FileNode node = root_[key];
    return !node.empty() && !node.isNone();
  }
  // Every key of the file must have been read: a misspelt key is an error, not a silent default.
  void RejectUnknownKeys() const {
    for (auto it = root_.begin(); it != root_.end(); ++it) {
      const std::string key = (*it).name();
      if (!used_.count(key)) Fail(key, "unknown key");
    }
  }
  [[noreturn]] void Fail(const std::string& key, const std::string& problem) const {
    throw model::InputError(fmt::format("{}: {}: {}", name_, key, problem));
  }

 private:
  cv::FileNode Find(const std::string& key) {
    const cv::FileNode node = root_[key];
    if (node.empty() || node.isNone()) Fail(key, "missing");
    used_.insert(key);
    return node;
  }

  cv::FileNode root_;
  std::string name_;
  std::set<std::string> used_;
};

CheckerboardLayout ParseCheckerboard(StrictMap& map) {
  CheckerboardLayout b;
  b.cols = map.PositiveInt("targetCols");
  b.rows = map.PositiveInt("targetRows");
  b.row_spacing_mm = map.PositiveReal("rowSpacingMeters") * kMmPerMetre;
  b.col_spacing_mm = map.PositiveReal("colSpacingMeters") * kMmPerMetre;
  // OpenCV's board detectors need at least 2 x 2 inner corners (3 x 3 squares).
  if (b.cols < 2) map.Fail("targetCols", fmt::format("must be at least 2, got {}", b.cols));
  if (b.rows < 2) map.Fail("targetRows", fmt::format("must be at least 2, got {}", b.rows));
  return b;
}

AprilGridLayout ParseAprilGrid(StrictMap& map) {
  AprilGridLayout g;
  g.tag_cols = map.PositiveInt("tagCols");
  g.tag_rows = map.PositiveInt("tagRows");
  g.tag_size_mm = map.PositiveReal("tagSize") * kMmPerMetre;
  g.tag_spacing_ratio = map.PositiveReal("tagSpacing");
  if (map.Has("tagFamily")) {
    g.family = map.String("tagFamily");
    if (g.family != "tag36h11") map.Fail("tagFamily", fmt::format("only tag36h11 is supported, got '{}'", g.family));
  }
  g.first_tag_id = map.NonNegativeInt("firstTagId", 0);
  // tag36h11 has 587 codes (ids 0..586).
  constexpr int kTag36h11Codes = 587;
  if (g.first_tag_id + g.NumTags() > kTag36h11Codes) {
    map.Fail("firstTagId", fmt::format("ids {}..{} exceed tag36h11's {} codes", g.first_tag_id,
                                       g.first_tag_id + g.NumTags() - 1, kTag36h11Codes));
  }
  return g;
}

}  // namespace

TargetDescription ParseTargetDescription(std::string_view yaml_text, const std::string& name) {
  // cv::FileStorage only reads YAML that starts with a "%YAML" directive; Kalibr's files have none.
  std::string text(yaml_text);
  const auto first = text.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) throw model::InputError(fmt::format("{}: empty target description", name));
  if (text.compare(first, 5, "%YAML") != 0) text = "%YAML:1.0\n---\n" + text;

  cv::FileStorage fs;
  try {
    fs.open(text, cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
  } catch (const cv::Exception& e) {
    throw model::InputError(fmt::format("{}: not valid YAML ({})", name, e.err));
  }
  if (!fs.isOpened() || !fs.root().isMap()) {
    throw model::InputError(fmt::format("{}: not a YAML mapping of target keys", name));
  }
  StrictMap map(fs.root(), name);
  TargetDescription target;
  target.source = name;
  const std::string type = map.String("target_type");
  if (type == "checkerboard") {
    target.layout = ParseCheckerboard(map);
  } else if (type == "aprilgrid") {
    target.layout = ParseAprilGrid(map);
  } else {
    map.Fail("target_type", fmt::format("must be checkerboard or aprilgrid, got '{}'", type));
  }
  map.RejectUnknownKeys();
  return target;
}

TargetDescription LoadTargetDescription(const std::string& path) {
  return ParseTargetDescription(model::ReadFile(path), path);
}

std::vector<int> TargetDescription::CornerIds() const {
  int count = 0;
  if (const auto* b = std::get_if<CheckerboardLayout>(&layout)) count = b->cols * b->rows;
  if (const auto* g = std::get_if<AprilGridLayout>(&layout)) count = 4 * g->NumTags();
  std::vector<int> ids(static_cast<size_t>(count));
  for (int i = 0; i < count; ++i) ids[static_cast<size_t>(i)] = i;
  return ids;
}

std::optional<Eigen::Vector3d> TargetDescription::CornerMm(int id) const {
  if (id < 0) return std::nullopt;
  if (const auto* b = std::get_if<CheckerboardLayout>(&layout)) {
    if (id >= b->cols * b->rows) return std::nullopt;
    const int r = id / b->cols, c = id % b->cols;
    return Eigen::Vector3d(c * b->col_spacing_mm, r * b->row_spacing_mm, 0.0);
  }
  const auto& g = std::get<AprilGridLayout>(layout);
  if (id >= 4 * g.NumTags()) return std::nullopt;
  const int tag = id / 4, k = id % 4;
  const double x0 = (tag % g.tag_cols) * g.PitchMm(), y0 = (tag / g.tag_cols) * g.PitchMm();
  const double s = g.tag_size_mm;
  // Corner k as drawn in target.h: 0 bottom-left, 1 bottom-right, 2 top-right, 3 top-left (y down).
  const double dx[4] = {0, s, s, 0};
  const double dy[4] = {s, s, 0, 0};
  return Eigen::Vector3d(x0 + dx[k], y0 + dy[k], 0.0);
}

TargetExtent TargetDescription::PatternExtent() const {
  if (const auto* b = std::get_if<CheckerboardLayout>(&layout)) {
    return {-b->col_spacing_mm, -b->row_spacing_mm, b->cols * b->col_spacing_mm, b->rows * b->row_spacing_mm};
  }
  const auto& g = std::get<AprilGridLayout>(layout);
  return {0.0, 0.0, (g.tag_cols - 1) * g.PitchMm() + g.tag_size_mm, (g.tag_rows - 1) * g.PitchMm() + g.tag_size_mm};
}

TargetExtent TargetDescription::PaperExtent() const {
  TargetExtent e = PatternExtent();
  double margin_x_mm = 0, margin_y_mm = 0;
  if (const auto* b = std::get_if<CheckerboardLayout>(&layout)) {
    // One square of white around the outer squares: the board detectors need a light frame around the board.
    margin_x_mm = b->col_spacing_mm;
    margin_y_mm = b->row_spacing_mm;
  } else {
    // Half a tag = 4 bit cells of white; libapriltag needs at least the one-cell white border of the tag.
    margin_x_mm = margin_y_mm = 0.5 * std::get<AprilGridLayout>(layout).tag_size_mm;
  }
  return {e.min_x_mm - margin_x_mm, e.min_y_mm - margin_y_mm, e.max_x_mm + margin_x_mm, e.max_y_mm + margin_y_mm};
}

std::string TargetDescription::Describe() const {
  if (const auto* b = std::get_if<CheckerboardLayout>(&layout)) {
    return fmt::format("checkerboard {}x{} inner corners, {:g} x {:g} mm squares", b->cols, b->rows,
                       b->col_spacing_mm, b->row_spacing_mm);
  }
  const auto& g = std::get<AprilGridLayout>(layout);
  return fmt::format("aprilgrid {}x{} {} tags from id {}, {:g} mm tags, spacing {:g}", g.tag_cols, g.tag_rows,
                     g.family, g.first_tag_id, g.tag_size_mm, g.tag_spacing_ratio);
}

}  // namespace topocal::calib
