#include "calib/target.h"

#include <fmt/format.h>

#include <cmath>
#include <opencv2/aruco/dictionary.hpp>
#include <opencv2/core.hpp>

#include "calib/file_storage.h"
#include "calib/yaml_section.h"
#include "util/io.h"

namespace topocal::calib {
namespace {

constexpr double kMmPerMetre = 1000.0;
// Physical sanity of a printed target (colSpacingMeters 1e308 passed the finiteness check in metres and
// overflowed to an SVG width="infmm" in mm): lengths up to 10 m, grids up to 1000 per side, ids up to 1e6.
constexpr double kMaxTargetLengthMm = 10000.0;
constexpr int kMaxGridSide = 1000;
constexpr int kMaxTagId = 1000000;

// A grid's side (columns or rows of corners, squares or tags).
int GridSide(YamlSection& map, const std::string& key) { return map.IntIn(key, 1, kMaxGridSide); }

int OptionalTagId(YamlSection& map, const std::string& key, int fallback) {
  return map.Has(key) ? map.IntIn(key, 0, kMaxTagId) : fallback;
}

double PositiveNumber(YamlSection& map, const std::string& key) {
  const double value = map.Number(key);
  if (value <= 0) map.Fail(key, fmt::format("must be a positive number, got {}", value));
  return value;
}

// A length given in metres (Kalibr's unit), returned in mm and checked after the conversion.
double LengthMm(YamlSection& map, const std::string& key) {
  const double mm = PositiveNumber(map, key) * kMmPerMetre;
  if (!(std::isfinite(mm) && mm <= kMaxTargetLengthMm)) {
    map.Fail(key, fmt::format("must be at most {:g} m, got {:g} m", kMaxTargetLengthMm / kMmPerMetre, mm / kMmPerMetre));
  }
  return mm;
}

CheckerboardLayout ParseCheckerboard(YamlSection& map) {
  CheckerboardLayout b;
  b.cols = GridSide(map, "targetCols");
  b.rows = GridSide(map, "targetRows");
  b.row_spacing_mm = LengthMm(map, "rowSpacingMeters");
  b.col_spacing_mm = LengthMm(map, "colSpacingMeters");
  // OpenCV's board detectors need at least 2 x 2 inner corners (3 x 3 squares).
  if (b.cols < 2) map.Fail("targetCols", fmt::format("must be at least 2, got {}", b.cols));
  if (b.rows < 2) map.Fail("targetRows", fmt::format("must be at least 2, got {}", b.rows));
  return b;
}

AprilGridLayout ParseAprilGrid(YamlSection& map) {
  AprilGridLayout g;
  g.tag_cols = GridSide(map, "tagCols");
  g.tag_rows = GridSide(map, "tagRows");
  g.tag_size_mm = LengthMm(map, "tagSize");
  g.tag_spacing_ratio = PositiveNumber(map, "tagSpacing");
  constexpr double kMaxTagSpacingRatio = 10;  // Kalibr's boards use 0.3; a gap ten tags wide is no grid
  if (g.tag_spacing_ratio > kMaxTagSpacingRatio) {
    map.Fail("tagSpacing", fmt::format("must be at most {:g} (a fraction of tagSize), got {:g}", kMaxTagSpacingRatio,
                                       g.tag_spacing_ratio));
  }
  if (map.Has("tagFamily")) {
    g.family = map.String("tagFamily");
    if (g.family != "tag36h11") map.Fail("tagFamily", fmt::format("only tag36h11 is supported, got '{}'", g.family));
  }
  g.first_tag_id = OptionalTagId(map, "firstTagId", 0);
  g.border_bits = OptionalTagId(map, "tagBorderBits", 2);
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

CharucoLayout ParseCharuco(YamlSection& map) {
  CharucoLayout c;
  c.squares_x = GridSide(map, "squaresX");
  c.squares_y = GridSide(map, "squaresY");
  c.square_size_mm = LengthMm(map, "squareSizeMeters");
  c.marker_size_mm = LengthMm(map, "markerSizeMeters");
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
    YamlSection map(fs.root(), name);
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
