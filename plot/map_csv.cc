// The map CSV (plot/map_image.h): its writer and its reader, the one format in one place.
#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "plot/map_image.h"
#include "plot/map_text.h"
#include "util/io.h"

namespace topocal::plot {
namespace {

// The largest grid read (the maps topocal writes are 241 x 241; 4 M samples is a 2000 x 2000 grid).
constexpr size_t kMaxSamples = 4'000'000;

bool ParseDouble(std::string_view field, double* out) {
  const char* end = field.data() + field.size();
  const auto r = std::from_chars(field.data(), end, *out);
  return r.ec == std::errc() && r.ptr == end && std::isfinite(*out);
}

}  // namespace

std::string GridMapCsv(const GridMap& map) {
  std::string why;
  if (!map.IsValid(&why)) throw util::InputError("GridMap: " + why);
  std::string column = "value";
  const std::string unit = Transliterate(map.unit);
  if (!unit.empty()) column += '_';
  for (char c : unit) {
    if (c == '\x01')
      column += 'u';
    else if (std::isalnum(static_cast<unsigned char>(c)))
      column += c;
    else
      column += '_';
  }
  std::string csv = "x_mm,y_mm," + column + "\n";
  csv.reserve(csv.size() + map.values.size() * 32);
  // Each column's x is the same double in every row: formatted once (with its comma) rather than once per value,
  // which was two thirds of the formatting. The text is the same.
  std::vector<std::string> x_text(static_cast<size_t>(map.nx));
  for (int i = 0; i < map.nx; ++i) {
    const double x = map.x_min_mm + i * (map.x_max_mm - map.x_min_mm) / (map.nx - 1);
    x_text[static_cast<size_t>(i)] = fmt::format("{},", x);
  }
  std::string y_text;
  for (int j = 0; j < map.ny; ++j) {
    const double y = map.y_min_mm + j * (map.y_max_mm - map.y_min_mm) / (map.ny - 1);
    y_text = fmt::format("{},", y);
    for (int i = 0; i < map.nx; ++i) {
      const double v = map.At(i, j);
      csv += x_text[static_cast<size_t>(i)];
      csv += y_text;
      // Formatted into a stack buffer: a temporary string per value was a third of the time of writing a unit
      // record's maps. 32 characters hold any double's shortest round-trip form.
      if (std::isfinite(v)) {
        char text[32];
        csv.append(text, fmt::format_to_n(text, sizeof text, "{}", v).out);
      }
      csv += '\n';
    }
  }
  return csv;
}

void WriteMapCsv(const std::string& path, const GridMap& map) { util::WriteFileAtomic(path, GridMapCsv(map)); }

GridMap ReadMapCsv(const std::string& path) {
  const std::string text = util::ReadFile(path);
  const auto bad = [&](size_t line, const std::string& why) {
    return util::InputError(fmt::format("{}: line {}: {}", path, line, why));
  };
  size_t pos = text.find('\n');
  if (pos == std::string::npos) throw bad(1, "no header line (x_mm,y_mm,value_<unit>)");
  const std::string_view header(text.data(), pos);
  constexpr std::string_view kPrefix = "x_mm,y_mm,value";
  if (header.substr(0, kPrefix.size()) != kPrefix) throw bad(1, "the header is not x_mm,y_mm,value_<unit>");
  GridMap map;
  std::string_view unit = header.substr(kPrefix.size());
  if (!unit.empty()) {
    if (unit.front() != '_') throw bad(1, "the header is not x_mm,y_mm,value_<unit>");
    unit.remove_prefix(1);
  }
  map.unit = unit == "um" ? "\u00b5m" : std::string(unit);  // GridMapCsv writes µ as u
  std::vector<double> xs, ys;
  size_t line = 1;
  for (size_t start = pos + 1; start < text.size(); start = pos + 1) {
    ++line;
    pos = text.find('\n', start);
    if (pos == std::string::npos) pos = text.size();
    const std::string_view row(text.data() + start, pos - start);
    const size_t c1 = row.find(','), c2 = c1 == std::string_view::npos ? c1 : row.find(',', c1 + 1);
    if (c2 == std::string_view::npos || row.find(',', c2 + 1) != std::string_view::npos) {
      throw bad(line, "expected x_mm,y_mm,value");
    }
    double x = 0, y = 0, v = std::numeric_limits<double>::quiet_NaN();
    if (!ParseDouble(row.substr(0, c1), &x) || !ParseDouble(row.substr(c1 + 1, c2 - c1 - 1), &y)) {
      throw bad(line, "x_mm and y_mm must be finite numbers");
    }
    const std::string_view value = row.substr(c2 + 1);
    if (!value.empty() && !ParseDouble(value, &v)) throw bad(line, "the value must be a finite number or empty");
    if (map.values.size() >= kMaxSamples) throw bad(line, fmt::format("more than {} samples", kMaxSamples));
    xs.push_back(x);
    ys.push_back(y);
    map.values.push_back(v);
  }
  // The grid: x ascending within a row, rows of one y, y ascending (GridMapCsv's order).
  size_t nx = 1;
  while (nx < ys.size() && ys[nx] == ys[0]) ++nx;
  if (nx < 2 || ys.size() % nx != 0 || ys.size() / nx < 2) {
    throw util::InputError(fmt::format("{}: not a grid of at least 2 x 2 samples in rows of one y", path));
  }
  map.nx = static_cast<int>(nx);
  map.ny = static_cast<int>(ys.size() / nx);
  map.x_min_mm = xs.front();
  map.x_max_mm = xs[nx - 1];
  map.y_min_mm = ys.front();
  map.y_max_mm = ys.back();
  const double tol_x = 1e-9 * (map.x_max_mm - map.x_min_mm), tol_y = 1e-9 * (map.y_max_mm - map.y_min_mm);
  for (size_t k = 0; k < xs.size(); ++k) {
    const size_t i = k % nx, j = k / nx;
    const double x = map.x_min_mm + static_cast<double>(i) * (map.x_max_mm - map.x_min_mm) / (map.nx - 1);
    const double y = map.y_min_mm + static_cast<double>(j) * (map.y_max_mm - map.y_min_mm) / (map.ny - 1);
    if (!(std::abs(xs[k] - x) <= tol_x) || !(std::abs(ys[k] - y) <= tol_y)) {
      throw bad(k + 2, "the sample is not on the map's regular grid");
    }
  }
  std::string why;
  if (!map.IsValid(&why)) throw util::InputError(fmt::format("{}: {}", path, why));
  return map;
}

}  // namespace topocal::plot
