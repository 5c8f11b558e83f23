#include "model/topographer_camera.h"

#include <cmath>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "model/io.h"
#include "model/json_section.h"

namespace topocal::model {
namespace {

using nlohmann::json;

constexpr const char* kKeys[] = {"pixel_pitch_um", "width_px", "height_px", "principal_point_px", "a_mm",
                                 "orientation", "rotated_180"};

constexpr std::pair<ImageOrientation, const char*> kOrientationNames[] = {
    {ImageOrientation::kIdentity, "identity"},   {ImageOrientation::kRotate90, "rotate_90"},
    {ImageOrientation::kRotate180, "rotate_180"}, {ImageOrientation::kRotate270, "rotate_270"},
    {ImageOrientation::kFlipU, "flip_u"},         {ImageOrientation::kFlipV, "flip_v"},
    {ImageOrientation::kTranspose, "transpose"},  {ImageOrientation::kTransverse, "transverse"}};

std::string Key(const std::string& prefix, const std::string& key) { return prefix.empty() ? key : prefix + "." + key; }

[[noreturn]] void Fail(const std::string& origin, const std::string& key, const std::string& problem) {
  throw InputError(fmt::format("{}: {}: {}", origin, key, problem));
}

double Number(const json& j, const std::string& origin, const std::string& key) {
  if (!j.contains(key)) Fail(origin, key, "missing");
  const json& v = j.at(key);
  if (!v.is_number()) Fail(origin, key, fmt::format("must be a number (got {})", QuoteJsonValue(v)));
  const double d = v.get<double>();
  if (!std::isfinite(d)) Fail(origin, key, "must be finite");
  return d;
}

int Integer(const json& j, const std::string& origin, const std::string& key) {
  if (!j.contains(key)) Fail(origin, key, "missing");
  const json& v = j.at(key);
  if (!v.is_number_integer()) Fail(origin, key, fmt::format("must be an integer (got {})", QuoteJsonValue(v)));
  if (v.is_number_unsigned() ? v.get<unsigned long long>() > 100000ULL
                             : (v.get<long long>() < 1 || v.get<long long>() > 100000)) {
    Fail(origin, key, fmt::format("must be in [1, 100000] (got {})", QuoteJsonValue(v)));
  }
  return v.get<int>();
}

}  // namespace

Eigen::Matrix2d OrientationMatrix(ImageOrientation o) noexcept {
  Eigen::Matrix2d m;
  switch (o) {
    case ImageOrientation::kIdentity: m << 1, 0, 0, 1; break;
    case ImageOrientation::kRotate90: m << 0, -1, 1, 0; break;
    case ImageOrientation::kRotate180: m << -1, 0, 0, -1; break;
    case ImageOrientation::kRotate270: m << 0, 1, -1, 0; break;
    case ImageOrientation::kFlipU: m << -1, 0, 0, 1; break;
    case ImageOrientation::kFlipV: m << 1, 0, 0, -1; break;
    case ImageOrientation::kTranspose: m << 0, 1, 1, 0; break;
    case ImageOrientation::kTransverse: m << 0, -1, -1, 0; break;
  }
  return m;
}

const char* OrientationName(ImageOrientation o) noexcept {
  for (const auto& [value, name] : kOrientationNames) {
    if (value == o) return name;
  }
  return "identity";
}

std::optional<ImageOrientation> OrientationFromName(const std::string& name) noexcept {
  for (const auto& [value, n] : kOrientationNames) {
    if (name == n) return value;
  }
  return std::nullopt;
}

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

TopographerCamera CameraFromJson(const json& j, const std::string& origin, const std::string& prefix) {
  if (!j.is_object()) Fail(origin, prefix.empty() ? "(top level)" : prefix, "must be a JSON object");
  const std::set<std::string> known(std::begin(kKeys), std::end(kKeys));
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (!known.count(it.key())) Fail(origin, Key(prefix, it.key()), "unknown key");
  }
  const std::string where = prefix.empty() ? origin : origin + ": " + prefix;
  TopographerCamera c;
  c.pixel_pitch_um = Number(j, where, "pixel_pitch_um");
  c.width_px = Integer(j, where, "width_px");
  c.height_px = Integer(j, where, "height_px");
  c.a_mm = Number(j, where, "a_mm");
  if (!j.contains("principal_point_px")) Fail(where, "principal_point_px", "missing");
  const json& pp = j.at("principal_point_px");
  if (!pp.is_array() || pp.size() != 2 || !pp[0].is_number() || !pp[1].is_number()) {
    Fail(where, "principal_point_px", fmt::format("must be an array of two numbers [u, v] (got {})", QuoteJsonValue(pp)));
  }
  c.principal_point_px = {pp[0].get<double>(), pp[1].get<double>()};
  if (j.contains("orientation") && j.contains("rotated_180")) {
    Fail(where, "rotated_180", "give either orientation or the older rotated_180, not both");
  }
  if (j.contains("rotated_180")) {
    if (!j.at("rotated_180").is_boolean()) {
      Fail(where, "rotated_180", fmt::format("must be true or false (got {})", QuoteJsonValue(j.at("rotated_180"))));
    }
    c.orientation = j.at("rotated_180").get<bool>() ? ImageOrientation::kRotate180 : ImageOrientation::kIdentity;
  }
  if (j.contains("orientation")) {
    const json& o = j.at("orientation");
    const auto value = o.is_string() ? OrientationFromName(o.get<std::string>()) : std::nullopt;
    if (!value) {
      Fail(where, "orientation",
           fmt::format("must be one of identity, rotate_90, rotate_180, rotate_270, flip_u, flip_v, transpose, "
                       "transverse (got {})", QuoteJsonValue(o)));
    }
    c.orientation = *value;
  }
  if (const auto why = c.Invalid()) throw InputError(fmt::format("{}: {}", where, *why));
  return c;
}

json CameraToJson(const TopographerCamera& c) {
  return {{"pixel_pitch_um", c.pixel_pitch_um},
          {"width_px", c.width_px},
          {"height_px", c.height_px},
          {"principal_point_px", {c.principal_point_px.x(), c.principal_point_px.y()}},
          {"a_mm", c.a_mm},
          {"orientation", OrientationName(c.orientation)}};
}

TopographerCamera ParseTopographerCamera(const std::string& json_text, const std::string& origin) {
  const json j = ParseJsonStrict(json_text, origin);
  // A device file (model/device.h) carries the camera in its "camera" section.
  if (j.is_object() && j.contains("format") && j.contains("camera")) return CameraFromJson(j.at("camera"), origin, "camera");
  return CameraFromJson(j, origin, "");
}

TopographerCamera LoadTopographerCamera(const std::string& path) {
  return ParseTopographerCamera(ReadFile(path), path);
}

std::string TopographerCameraToJson(const TopographerCamera& c) { return CameraToJson(c).dump(2) + "\n"; }

}  // namespace topocal::model
