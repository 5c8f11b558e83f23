#include "model/topographer_camera.h"

#include <cmath>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "model/io.h"

namespace topocal::model {
namespace {

using nlohmann::json;

constexpr const char* kKeys[] = {"pixel_pitch_um", "width_px", "height_px", "principal_point_px", "a_mm",
                                 "rotated_180"};

[[noreturn]] void Fail(const std::string& origin, const std::string& key, const std::string& problem) {
  throw InputError(fmt::format("{}: {}: {}", origin, key, problem));
}

double Number(const json& j, const std::string& origin, const std::string& key) {
  if (!j.contains(key)) Fail(origin, key, "missing");
  const json& v = j.at(key);
  if (!v.is_number()) Fail(origin, key, fmt::format("must be a number (got {})", v.dump()));
  const double d = v.get<double>();
  if (!std::isfinite(d)) Fail(origin, key, "must be finite");
  return d;
}

int Integer(const json& j, const std::string& origin, const std::string& key) {
  if (!j.contains(key)) Fail(origin, key, "missing");
  const json& v = j.at(key);
  if (!v.is_number_integer()) Fail(origin, key, fmt::format("must be an integer (got {})", v.dump()));
  const auto i = v.get<long long>();
  if (i < 1 || i > 100000) Fail(origin, key, fmt::format("must be in [1, 100000] (got {})", i));
  return static_cast<int>(i);
}

}  // namespace

std::optional<std::string> TopographerCamera::Invalid() const {
  if (!(pixel_pitch_um > 0) || !std::isfinite(pixel_pitch_um)) {
    return fmt::format("pixel_pitch_um: must be > 0 (got {})", pixel_pitch_um);
  }
  if (width_px < 1 || height_px < 1) return fmt::format("width_px/height_px: must be >= 1 (got {} x {})", width_px, height_px);
  if (!(a_mm > 0) || !std::isfinite(a_mm)) return fmt::format("a_mm: must be > 0 (got {})", a_mm);
  if (!principal_point_px.allFinite()) return "principal_point_px: must be finite";
  if (!OnSensor(principal_point_px)) {
    return fmt::format("principal_point_px: ({}, {}) lies outside the {} x {} sensor", principal_point_px.x(),
                       principal_point_px.y(), width_px, height_px);
  }
  return std::nullopt;
}

TopographerCamera ParseTopographerCamera(const std::string& json_text, const std::string& origin) {
  json j;
  try {
    j = json::parse(json_text);
  } catch (const json::parse_error& e) {
    throw InputError(fmt::format("{}: not valid JSON (byte {})", origin, e.byte));
  } catch (const json::exception& e) {  // out_of_range for a number like 1e999: bad input too
    throw InputError(fmt::format("{}: not valid JSON: {}", origin, e.what()));
  }
  if (!j.is_object()) Fail(origin, "(top level)", "must be a JSON object");
  const std::set<std::string> known(std::begin(kKeys), std::end(kKeys));
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (!known.count(it.key())) Fail(origin, it.key(), "unknown key");
  }
  TopographerCamera c;
  c.pixel_pitch_um = Number(j, origin, "pixel_pitch_um");
  c.width_px = Integer(j, origin, "width_px");
  c.height_px = Integer(j, origin, "height_px");
  c.a_mm = Number(j, origin, "a_mm");
  if (!j.contains("principal_point_px")) Fail(origin, "principal_point_px", "missing");
  const json& pp = j.at("principal_point_px");
  if (!pp.is_array() || pp.size() != 2 || !pp[0].is_number() || !pp[1].is_number()) {
    Fail(origin, "principal_point_px", fmt::format("must be an array of two numbers [u, v] (got {})", pp.dump()));
  }
  c.principal_point_px = {pp[0].get<double>(), pp[1].get<double>()};
  if (j.contains("rotated_180")) {
    if (!j.at("rotated_180").is_boolean()) {
      Fail(origin, "rotated_180", fmt::format("must be true or false (got {})", j.at("rotated_180").dump()));
    }
    c.rotated_180 = j.at("rotated_180").get<bool>();
  }
  if (const auto why = c.Invalid()) throw InputError(fmt::format("{}: {}", origin, *why));
  return c;
}

TopographerCamera LoadTopographerCamera(const std::string& path) {
  return ParseTopographerCamera(ReadFile(path), path);
}

std::string TopographerCameraToJson(const TopographerCamera& c) {
  json j = {{"pixel_pitch_um", c.pixel_pitch_um},
            {"width_px", c.width_px},
            {"height_px", c.height_px},
            {"principal_point_px", {c.principal_point_px.x(), c.principal_point_px.y()}},
            {"a_mm", c.a_mm},
            {"rotated_180", c.rotated_180}};
  return j.dump(2) + "\n";
}

}  // namespace topocal::model
