#include "calib/target.h"

#include <fmt/format.h>

#include <cctype>
#include <cmath>
#include <opencv2/aruco/dictionary.hpp>
#include <opencv2/core.hpp>
#include <set>

#include "calib/file_storage.h"
#include "util/io.h"

namespace topocal::calib {
namespace {

constexpr double kMmPerMetre = 1000.0;
// Physical sanity of a printed target (colSpacingMeters 1e308 passed the finiteness check in metres and
// overflowed to an SVG width="infmm" in mm): lengths up to 10 m, grids up to 1000 per side, ids up to 1e6.
constexpr double kMaxTargetLengthMm = 10000.0;
constexpr int kMaxGridSide = 1000;
constexpr int kMaxTagId = 1000000;

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
  int PositiveInt(const std::string& key, int max = kMaxGridSide) {
    const cv::FileNode node = Find(key);
    if (!node.isInt()) Fail(key, "must be an integer");
    const int value = static_cast<int>(node);
    if (value <= 0 || value > max) Fail(key, fmt::format("must be in [1, {}], got {}", max, value));
    return value;
  }
  int NonNegativeInt(const std::string& key, int fallback) {
    if (!Has(key)) return fallback;
    const cv::FileNode node = Find(key);
    if (!node.isInt()) Fail(key, "must be an integer");
    const int value = static_cast<int>(node);
    if (value < 0 || value > kMaxTagId) Fail(key, fmt::format("must be in [0, {}], got {}", kMaxTagId, value));
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
  // A length given in metres (Kalibr's unit), returned in mm and checked after the conversion.
  double LengthMm(const std::string& key) {
    const double mm = PositiveReal(key) * kMmPerMetre;
    if (!(std::isfinite(mm) && mm <= kMaxTargetLengthMm)) {
      Fail(key, fmt::format("must be at most {:g} m, got {:g} m", kMaxTargetLengthMm / kMmPerMetre, mm / kMmPerMetre));
    }
    return mm;
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
    throw util::InputError(fmt::format("{}: {}: {}", name_, key, problem));
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
  b.row_spacing_mm = map.LengthMm("rowSpacingMeters");
  b.col_spacing_mm = map.LengthMm("colSpacingMeters");
  // OpenCV's board detectors need at least 2 x 2 inner corners (3 x 3 squares).
  if (b.cols < 2) map.Fail("targetCols", fmt::format("must be at least 2, got {}", b.cols));
  if (b.rows < 2) map.Fail("targetRows", fmt::format("must be at least 2, got {}", b.rows));
  return b;
}

AprilGridLayout ParseAprilGrid(StrictMap& map) {
  AprilGridLayout g;
  g.tag_cols = map.PositiveInt("tagCols");
  g.tag_rows = map.PositiveInt("tagRows");
  g.tag_size_mm = map.LengthMm("tagSize");
  g.tag_spacing_ratio = map.PositiveReal("tagSpacing");
  constexpr double kMaxTagSpacingRatio = 10;  // Kalibr's boards use 0.3; a gap ten tags wide is no grid
  if (g.tag_spacing_ratio > kMaxTagSpacingRatio) {
    map.Fail("tagSpacing", fmt::format("must be at most {:g} (a fraction of tagSize), got {:g}", kMaxTagSpacingRatio,
                                       g.tag_spacing_ratio));
  }
  if (map.Has("tagFamily")) {
    g.family = map.String("tagFamily");
    if (g.family != "tag36h11") map.Fail("tagFamily", fmt::format("only tag36h11 is supported, got '{}'", g.family));
  }
  g.first_tag_id = map.NonNegativeInt("firstTagId", 0);
  g.border_bits = map.NonNegativeInt("tagBorderBits", 2);
  if (g.border_bits != 1 && g.border_bits != 2) {
    map.Fail("tagBorderBits", fmt::format("must be 1 or 2 (Kalibr prints 2), got {}", g.border_bits));
  }
  // tag36h11 has 587 codes (ids 0..586).
  constexpr int kTag36h11Codes = 587;
  if (g.first_tag_id + g.NumTags() > kTag36h11Codes) {
    map.Fail("firstTagId", fmt::format("ids {}..{} exceed tag36h11's {} codes", g.first_tag_id,
                                       g.first_tag_id + g.NumTags() - 1, kTag36h11Codes));
  }
  return g;
}

CharucoLayout ParseCharuco(StrictMap& map) {
  CharucoLayout c;
  c.squares_x = map.PositiveInt("squaresX");
  c.squares_y = map.PositiveInt("squaresY");
  c.square_size_mm = map.LengthMm("squareSizeMeters");
  c.marker_size_mm = map.LengthMm("markerSizeMeters");
  if (map.Has("arucoDictionary")) c.dictionary = map.String("arucoDictionary");
  // At least 2 x 2 inner corners, as for checkerboards.
  if (c.squares_x < 3) map.Fail("squaresX", fmt::format("must be at least 3, got {}", c.squares_x));
  if (c.squares_y < 3) map.Fail("squaresY", fmt::format("must be at least 3, got {}", c.squares_y));
  if (!(c.marker_size_mm < c.square_size_mm)) {
    map.Fail("markerSizeMeters", fmt::format("must be smaller than squareSizeMeters ({:g} >= {:g} mm)",
                                             c.marker_size_mm, c.square_size_mm));
  }
  const auto dictionary = ArucoDictionaryId(c.dictionary);
  if (!dictionary) map.Fail("arucoDictionary", fmt::format("unknown dictionary '{}' (e.g. DICT_4X4_50)", c.dictionary));
  if (c.NumMarkers() > ArucoDictionarySize(*dictionary)) {
    map.Fail("arucoDictionary", fmt::format("{} has {} markers, the board needs {}", c.dictionary,
                                            ArucoDictionarySize(*dictionary), c.NumMarkers()));
  }
  return c;
}

}  // namespace

std::optional<int> ArucoDictionaryId(std::string_view name) {
  struct Named {
    std::string_view name;
    int id;
  };
  static constexpr Named kDictionaries[] = {
      {"DICT_4X4_50", cv::aruco::DICT_4X4_50},     {"DICT_4X4_100", cv::aruco::DICT_4X4_100},
      {"DICT_4X4_250", cv::aruco::DICT_4X4_250},   {"DICT_4X4_1000", cv::aruco::DICT_4X4_1000},
      {"DICT_5X5_50", cv::aruco::DICT_5X5_50},     {"DICT_5X5_100", cv::aruco::DICT_5X5_100},
      {"DICT_5X5_250", cv::aruco::DICT_5X5_250},   {"DICT_5X5_1000", cv::aruco::DICT_5X5_1000},
      {"DICT_6X6_50", cv::aruco::DICT_6X6_50},     {"DICT_6X6_100", cv::aruco::DICT_6X6_100},
      {"DICT_6X6_250", cv::aruco::DICT_6X6_250},   {"DICT_6X6_1000", cv::aruco::DICT_6X6_1000},
      {"DICT_7X7_50", cv::aruco::DICT_7X7_50},     {"DICT_7X7_100", cv::aruco::DICT_7X7_100},
      {"DICT_7X7_250", cv::aruco::DICT_7X7_250},   {"DICT_7X7_1000", cv::aruco::DICT_7X7_1000},
      {"DICT_ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL},
  };
  for (const auto& d : kDictionaries) {
    if (d.name == name) return d.id;
  }
  return std::nullopt;
}

int ArucoDictionarySize(int dictionary_id) {
  return cv::aruco::getPredefinedDictionary(dictionary_id)->bytesList.rows;
}

TargetDescription ParseTargetDescription(std::string_view yaml_text, const std::string& name) {
  const std::string text(yaml_text);
  if (text.find_first_not_of(" \t\r\n") == std::string::npos) {
    throw util::InputError(fmt::format("{}: empty target description", name));
  }
  const cv::FileStorage fs = OpenFileStorage(text, name);
  if (!fs.isOpened() || !fs.root().isMap()) {
    throw util::InputError(fmt::format("{}: not a YAML mapping of target keys", name));
  }
  return ReadFileStorage(name, "a target description", [&] {
    StrictMap map(fs.root(), name);
    TargetDescription target;
    target.source = name;
    const std::string type = map.String("target_type");
    if (type == "checkerboard") {
      target.layout = ParseCheckerboard(map);
    } else if (type == "aprilgrid") {
      target.layout = ParseAprilGrid(map);
    } else if (type == "charuco") {
      target.layout = ParseCharuco(map);
    } else {
      map.Fail("target_type", fmt::format("must be checkerboard, aprilgrid or charuco, got '{}'", type));
    }
    map.RejectUnknownKeys();
    return target;
  });
}

TargetDescription LoadTargetDescription(const std::string& path) {
  return ParseTargetDescription(util::ReadFile(path), path);
}

std::vector<int> TargetDescription::CornerIds() const {
  int count = 0;
  if (const auto* b = std::get_if<CheckerboardLayout>(&layout)) count = b->cols * b->rows;
  if (const auto* g = std::get_if<AprilGridLayout>(&layout)) count = 4 * g->NumTags();
  if (const auto* c = std::get_if<CharucoLayout>(&layout)) count = c->InnerCols() * c->InnerRows();
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
  if (const auto* ch = std::get_if<CharucoLayout>(&layout)) {
    if (id >= ch->InnerCols() * ch->InnerRows()) return std::nullopt;
    return Eigen::Vector3d((id % ch->InnerCols() + 1) * ch->square_size_mm,
                           (id / ch->InnerCols() + 1) * ch->square_size_mm, 0.0);
  }
  const auto& g = std::get<AprilGridLayout>(layout);
  if (id >= 4 * g.NumTags()) return std::nullopt;
  const int tag = id / 4, k = id % 4;
  const Eigen::Vector2d origin = g.TagOriginMm(tag);
  const double x0 = origin.x(), y0 = origin.y();
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
  if (const auto* c = std::get_if<CharucoLayout>(&layout)) {
    return {0.0, 0.0, c->squares_x * c->square_size_mm, c->squares_y * c->square_size_mm};
  }
  const auto& g = std::get<AprilGridLayout>(layout);
  // Kalibr's corner squares stick out by one gap beyond the outer tags.
  const double squares_mm = g.KalibrLayout() ? g.GapMm() : 0.0;
  return {-squares_mm, -squares_mm, (g.tag_cols - 1) * g.PitchMm() + g.tag_size_mm + squares_mm,
          (g.tag_rows - 1) * g.PitchMm() + g.tag_size_mm + squares_mm};
}

TargetExtent TargetDescription::PaperExtent() const {
  TargetExtent e = PatternExtent();
  double margin_x_mm = 0, margin_y_mm = 0;
  if (const auto* b = std::get_if<CheckerboardLayout>(&layout)) {
    // One square of white around the outer squares: the board detectors need a light frame around the board.
    margin_x_mm = b->col_spacing_mm;
    margin_y_mm = b->row_spacing_mm;
  } else if (const auto* c = std::get_if<CharucoLayout>(&layout)) {
    // The markers identify the corners; half a square of white is only a printing margin.
    margin_x_mm = margin_y_mm = 0.5 * c->square_size_mm;
  } else {
    // Half a tag (>= 4 bit cells) of white: both detectors need a white ring around each tag's black border.
    margin_x_mm = margin_y_mm = 0.5 * std::get<AprilGridLayout>(layout).tag_size_mm;
  }
  return {e.min_x_mm - margin_x_mm, e.min_y_mm - margin_y_mm, e.max_x_mm + margin_x_mm, e.max_y_mm + margin_y_mm};
}

std::string TargetDescription::Describe() const {
  if (const auto* b = std::get_if<CheckerboardLayout>(&layout)) {
    return fmt::format("checkerboard {}x{} inner corners, {:g} x {:g} mm squares", b->cols, b->rows,
                       b->col_spacing_mm, b->row_spacing_mm);
  }
  if (const auto* c = std::get_if<CharucoLayout>(&layout)) {
    return fmt::format("charuco {}x{} squares of {:g} mm, {:g} mm {} markers", c->squares_x, c->squares_y,
                       c->square_size_mm, c->marker_size_mm, c->dictionary);
  }
  const auto& g = std::get<AprilGridLayout>(layout);
  return fmt::format("aprilgrid {}x{} {} tags from id {}, {:g} mm tags, spacing {:g}, {}", g.tag_cols, g.tag_rows,
                     g.family, g.first_tag_id, g.tag_size_mm, g.tag_spacing_ratio,
                     g.KalibrLayout() ? "Kalibr layout (2-cell border, corner squares)" : "1-cell border");
}

}  // namespace topocal::calib
