#include "model/topographer_camera.h"

#include <fmt/format.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <vector>

#include "util/io.h"
#include "util/json_section.h"

namespace topocal::model {
namespace {

using nlohmann::json;

// Sensor sides beyond this are a corrupt file, not a camera.
constexpr int kMaxSidePx = 100000;
// Pixel aspect (pitch_v / pitch_u) a camera file may declare: real sensors calibrate to |fx / fy - 1| ~ 1e-4, an
// anamorphic squeeze to a few percent; beyond these bounds the file is corrupt or the calibration failed.
constexpr double kMinPixelAspect = 0.5, kMaxPixelAspect = 2.0;

constexpr std::pair<ImageOrientation, const char*> kOrientationNames[] = {
    {ImageOrientation::kIdentity, "identity"},   {ImageOrientation::kRotate90, "rotate_90"},
    {ImageOrientation::kRotate180, "rotate_180"}, {ImageOrientation::kRotate270, "rotate_270"},
    {ImageOrientation::kFlipU, "flip_u"},         {ImageOrientation::kFlipV, "flip_v"},
    {ImageOrientation::kTranspose, "transpose"},  {ImageOrientation::kTransverse, "transverse"}};

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
  if (!(pixel_aspect >= kMinPixelAspect && pixel_aspect <= kMaxPixelAspect)) {
    return fmt::format("pixel_aspect: must be in [{}, {}] (got {})", kMinPixelAspect, kMaxPixelAspect, pixel_aspect);
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
  // The project's strict JSON reader: every failure "ORIGIN: KEY: problem", an unknown key refused.
  util::JsonSection section(j, origin, prefix);
  TopographerCamera c;
  c.pixel_pitch_um = section.Number("pixel_pitch_um");
  c.pixel_aspect = section.Number("pixel_aspect", 1.0);
  c.width_px = section.IntegerInRange("width_px", 1, kMaxSidePx);
  c.height_px = section.IntegerInRange("height_px", 1, kMaxSidePx);
  c.a_mm = section.Number("a_mm");
  const std::vector<double> pp = section.Numbers("principal_point_px", 2);
  c.principal_point_px = {pp[0], pp[1]};
  if (section.Has("orientation") && section.Has("rotated_180")) {
    section.Fail(section.Key("rotated_180"), "give either orientation or the older rotated_180, not both");
  }
  if (section.Has("rotated_180")) {
    c.orientation = section.Bool("rotated_180") ? ImageOrientation::kRotate180 : ImageOrientation::kIdentity;
  }
  if (section.Has("orientation")) {
    const json& o = section.Get("orientation");
    const auto value = o.is_string() ? OrientationFromName(o.get<std::string>()) : std::nullopt;
    if (!value) {
      section.Fail(section.Key("orientation"),
                   fmt::format("must be one of identity, rotate_90, rotate_180, rotate_270, flip_u, flip_v, transpose, "
                               "transverse (got {})",
                               util::QuoteJsonValue(o)));
    }
    c.orientation = *value;
  }
  section.RejectUnknown();
  const std::string where = prefix.empty() ? origin : origin + ": " + prefix;
  if (const auto why = c.Invalid()) throw util::InputError(fmt::format("{}: {}", where, *why));
  return c;
}

json CameraToJson(const TopographerCamera& c) {
  json j = {{"pixel_pitch_um", c.pixel_pitch_um},
            {"width_px", c.width_px},
            {"height_px", c.height_px},
            {"principal_point_px", {c.principal_point_px.x(), c.principal_point_px.y()}},
            {"a_mm", c.a_mm},
            {"orientation", OrientationName(c.orientation)}};
  // Square pixels are the default and stay unwritten, so every square-pixel file reads and writes as before.
  if (c.pixel_aspect != 1.0) j["pixel_aspect"] = c.pixel_aspect;
  return j;
}

TopographerCamera ParseTopographerCamera(const std::string& json_text, const std::string& origin) {
  const json j = util::ParseJsonStrict(json_text, origin);
  // A device file (model/device.h) carries the camera in its "camera" section.
  if (j.is_object() && j.contains("format") && j.contains("camera")) return CameraFromJson(j.at("camera"), origin, "camera");
  return CameraFromJson(j, origin, "");
}

std::string TopographerCameraToJson(const TopographerCamera& c) { return CameraToJson(c).dump(2) + "\n"; }

}  // namespace topocal::model
