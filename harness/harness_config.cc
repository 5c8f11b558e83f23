#include "harness/harness_config.h"

#include <fmt/format.h>

#include <cctype>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>

#include "util/io.h"
#include "util/json_section.h"
#include "util/sha256.h"

namespace topocal::harness {
namespace {

using nlohmann::json;

// A sweep larger than this is a configuration mistake, not a plan: 1e7 cases are ~1 CPU-day at ~10 ms a case.
constexpr double kMaxCases = 1e7;

using Reader = util::JsonSection;

// A range object {"from", "to", "count", "spacing", "both_signs"} (see harness_config.h); `key` names it.
std::vector<double> ParseRange(const json& v, const std::string& origin, const std::string& key) {
  Reader r(v, origin, key);
  const double from = r.Number("from");
  const double to = r.Number("to");
  const json& count_json = r.Get("count");
  if (!count_json.is_number_integer())
    r.Fail(r.Key("count"), fmt::format("must be an integer (got {})", util::QuoteJsonValue(count_json)));
  // The 64-bit value, clamped: an unsigned count beyond LLONG_MAX must not wrap to a negative one.
  const long long count = !count_json.is_number_unsigned() ? count_json.get<long long>()
                          : count_json.get<unsigned long long>() > static_cast<unsigned long long>(kMaxCases)
                              ? static_cast<long long>(kMaxCases) + 1
                              : static_cast<long long>(count_json.get<unsigned long long>());
  const std::string spacing = r.Has("spacing") ? r.String("spacing") : "linear";
  bool both_signs = false;
  if (r.Has("both_signs")) {
    const json& b = r.Get("both_signs");
    if (!b.is_boolean())
      r.Fail(r.Key("both_signs"), fmt::format("must be true or false (got {})", util::QuoteJsonValue(b)));
    both_signs = b.get<bool>();
  }
  r.RejectUnknown();
  if (count < 1) r.Fail(r.Key("count"), fmt::format("must be >= 1 (got {})", util::QuoteJsonValue(count_json)));
  if (count > kMaxCases) {
    r.Fail(r.Key("count"), fmt::format("must be <= {:.0f} (got {})", kMaxCases, util::QuoteJsonValue(count_json)));
  }
  if (from > to) r.Fail(r.Key("from"), fmt::format("must not exceed to (got from {} > to {})", from, to));
  if (count == 1 && from != to)
    r.Fail(r.Key("count"), fmt::format("1 value needs from == to (got {} and {})", from, to));
  if (spacing != "log" && spacing != "linear") {
    r.Fail(r.Key("spacing"), fmt::format("must be \"log\" or \"linear\" (got \"{}\")", spacing));
  }
  if (spacing == "log" && !(from > 0)) {
    r.Fail(r.Key("from"), fmt::format("a log range needs 0 < from (got {}); use both_signs for negative values", from));
  }
  std::vector<double> positive;
  for (long long i = 0; i < count; ++i) {
    const double t = count == 1 ? 0.0 : static_cast<double>(i) / static_cast<double>(count - 1);
    double value = spacing == "log" ? from * std::pow(to / from, t) : from + (to - from) * t;
    if (i == count - 1) value = to;  // the stated end exactly, not pow's rounding of it
    positive.push_back(value);
  }
  if (!both_signs) return positive;
  std::vector<double> out;
  for (auto it = positive.rbegin(); it != positive.rend(); ++it) {
    if (*it != 0) out.push_back(-*it);
  }
  out.insert(out.end(), positive.begin(), positive.end());
  return out;
}

// A list of values: explicit, a range object, or a list mixing numbers and ranges (concatenated in order).
std::vector<double> ParseValues(Reader& parent, const std::string& k) {
  const json& v = parent.Get(k);
  const std::string key = parent.Key(k);
  if (v.is_object()) return ParseRange(v, parent.origin(), key);
  if (!v.is_array()) {
    parent.Fail(key, fmt::format("must be a list of numbers or a range {{\"from\", \"to\", \"count\", \"spacing\"}} "
                                 "(got {})",
                                 util::QuoteJsonValue(v)));
  }
  if (v.empty()) parent.Fail(key, "must not be empty (give at least one value)");
  std::vector<double> out;
  for (size_t i = 0; i < v.size(); ++i) {
    const std::string item = fmt::format("{}[{}]", key, i);
    if (v[i].is_object()) {
      const auto range = ParseRange(v[i], parent.origin(), item);
      out.insert(out.end(), range.begin(), range.end());
      continue;
    }
    if (!v[i].is_number() || !std::isfinite(v[i].get<double>())) {
      parent.Fail(item, fmt::format("must be a finite number or a range (got {})", util::QuoteJsonValue(v[i])));
    }
    out.push_back(v[i].get<double>());
  }
  return out;
}

bool ValidName(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  for (const char c : name) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.')) return false;
  }
  return true;
}

// The design with another cornea, validated by model::ParseConfig (the cornea must be defined where rays land).
model::Config WithCornea(const model::Config& design, const model::BiconicParams& cornea, const std::string& origin) {
  model::Config c = design;
  c.cornea = cornea;
  model::Config checked = model::ParseConfig(model::ConfigToJson(c), origin);
  return checked;
}

model::Config ParseDesign(Reader& top, const std::string& base_dir) {
  const json& d = top.Get("design");
  const std::string origin = fmt::format("{}: design", top.origin());
  if (d.is_object()) return model::ParseConfig(d.dump(), origin);
  if (!d.is_string())
    top.Fail("design", fmt::format("must be a configuration file path or object (got {})", util::QuoteJsonValue(d)));
  std::filesystem::path path(d.get<std::string>());
  if (path.is_relative() && !base_dir.empty()) path = std::filesystem::path(base_dir) / path;
  try {
    model::Config c = model::LoadConfig(path.string());
    c.path = origin;
    return c;
  } catch (const util::ConfigError& e) {
    throw util::ConfigError(fmt::format("{}: {}", origin, e.what()));
  }
}

std::vector<HarnessCornea> ParseCorneas(Reader& top, const model::Config& design) {
  std::vector<HarnessCornea> out;
  if (!top.Has("corneas")) {
    out.push_back({"design", design.cornea});
    return out;
  }
  const json& list = top.Get("corneas");
  if (!list.is_array())
    top.Fail("corneas", fmt::format("must be a list of biconics (got {})", util::QuoteJsonValue(list)));
  if (list.empty()) top.Fail("corneas", "must not be empty (leave it out for the design's own cornea)");
  std::set<std::string> names;
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string key = fmt::format("corneas[{}]", i);
    if (list[i].is_string() && list[i].get<std::string>() == "design") {
      out.push_back({"design", design.cornea});
    } else {
      Reader r(list[i], top.origin(), key);
      HarnessCornea c;
      c.name = r.Has("name") ? r.String("name") : fmt::format("cornea{}", i + 1);
      c.params.rx_mm = r.Number("rx_mm");
      c.params.ry_mm = r.Number("ry_mm");
      c.params.kx = r.Number("kx");
      c.params.ky = r.Number("ky");
      c.params.alpha_deg = r.Number("alpha_deg");
      c.params.x0_mm = r.Number("x0_mm", 0.0);
      c.params.y0_mm = r.Number("y0_mm", 0.0);
      c.params.z0_mm = r.Number("z0_mm", 0.0);
      r.RejectUnknown();
      if (!ValidName(c.name)) {
        r.Fail(r.Key("name"), fmt::format("must be 1-64 characters of A-Z a-z 0-9 _ - . (got \"{}\")", c.name));
      }
      c.params = WithCornea(design, c.params, fmt::format("{}: {}", top.origin(), key)).cornea;
      out.push_back(c);
    }
    if (!names.insert(out.back().name).second) {
      top.Fail(key, fmt::format("the name \"{}\" is used twice", out.back().name));
    }
  }
  return out;
}

json ValuesJson(const std::vector<double>& v) { return json(v); }

void ParseAssembly(Reader& top, HarnessConfig* h) {
  Reader a(top.Get("assembly"), top.origin(), "assembly");
  bool directional = false;
  for (const AssemblyAxis axis : kAssemblyAxes) {
    const std::string name = AssemblyAxisName(axis);
    if (!a.Has(name)) continue;
    auto& values = h->Errors(axis);
    values = ParseValues(a, name);
    const std::string unit = AssemblyAxisUnit(axis);
    const std::string with_unit = unit.empty() ? "" : " " + unit;
    const double max = AssemblyAxisMaximum(axis);
    for (size_t i = 0; i < values.size(); ++i) {
      const std::string key = fmt::format("{}[{}]", a.Key(name), i);
      if (IsDirectional(axis) && values[i] < 0) {
        a.Fail(key, fmt::format("must be >= 0{} (a magnitude; assembly.azimuths_deg gives its directions; got {})",
                                with_unit, values[i]));
      }
      if (!(std::abs(values[i]) <= max)) {
        a.Fail(key, fmt::format("must be within +-{}{} (got {})", max, with_unit, values[i]));
      }
    }
    directional = directional || IsDirectional(axis);
  }
  if (a.Has("azimuths_deg")) {
    if (!directional) {
      a.Fail(a.Key("azimuths_deg"),
             "applies to screen_tilt_deg, screen_decentration_mm and principal_point_offset_mm "
             "only, and none is given");
    }
    h->assembly_azimuths_deg = ParseValues(a, "azimuths_deg");
    for (size_t i = 0; i < h->assembly_azimuths_deg.size(); ++i) {
      const double phi = h->assembly_azimuths_deg[i];
      if (!(phi >= 0 && phi < 360)) {
        a.Fail(fmt::format("{}[{}]", a.Key("azimuths_deg"), i), fmt::format("must lie in [0, 360) deg (got {})", phi));
      }
    }
  } else if (directional) {
    for (int k = 0; k < 8; ++k) h->assembly_azimuths_deg.push_back(45.0 * k);
  }
  a.RejectUnknown();
  if (!h->HasAssembly()) {
    top.Fail("assembly", fmt::format("must give at least one of {}", [] {
               std::string names;
               for (const AssemblyAxis axis : kAssemblyAxes)
                 names += (names.empty() ? "" : ", ") + std::string(AssemblyAxisName(axis));
               return names;
             }()));
  }
}

}  // namespace

const char* DistortionFamilyName(DistortionFamily family) {
  switch (family) {
    case DistortionFamily::kSeidelSigma:
      return "seidel_sigma_per_mm2";
    case DistortionFamily::kBrownK1:
      return "brown_k1";
    case DistortionFamily::kBrownK2:
      return "brown_k2";
  }
  return "?";
}

const char* AssemblyAxisName(AssemblyAxis axis) {
  switch (axis) {
    case AssemblyAxis::kScreenTilt:
      return "screen_tilt_deg";
    case AssemblyAxis::kScreenRoll:
      return "screen_roll_deg";
    case AssemblyAxis::kScreenDecentration:
      return "screen_decentration_mm";
    case AssemblyAxis::kScreenAxial:
      return "screen_axial_mm";
    case AssemblyAxis::kPrincipalPoint:
      return "principal_point_offset_mm";
    case AssemblyAxis::kARelative:
      return "a_relative_error";
  }
  return "?";
}

const char* AssemblyAxisUnit(AssemblyAxis axis) {
  switch (axis) {
    case AssemblyAxis::kScreenTilt:
    case AssemblyAxis::kScreenRoll:
      return "deg";
    case AssemblyAxis::kScreenDecentration:
    case AssemblyAxis::kScreenAxial:
    case AssemblyAxis::kPrincipalPoint:
      return "mm";
    case AssemblyAxis::kARelative:
      return "";
  }
  return "";
}

bool IsDirectional(AssemblyAxis axis) {
  return axis == AssemblyAxis::kScreenTilt || axis == AssemblyAxis::kScreenDecentration ||
         axis == AssemblyAxis::kPrincipalPoint;
}

double AssemblyAxisMaximum(AssemblyAxis axis) {
  switch (axis) {
    case AssemblyAxis::kScreenTilt:
    case AssemblyAxis::kScreenRoll:
      return 10.0;  // deg: the device file's +-10 deg
    case AssemblyAxis::kScreenDecentration:
    case AssemblyAxis::kScreenAxial:
      return 10.0;  // mm: the device file's +-10 mm
    case AssemblyAxis::kPrincipalPoint:
      return 1.0;  // mm on the sensor: ~900 px, a fifth of its width
    case AssemblyAxis::kARelative:
      return 0.1;  // 10 % of a
  }
  return 0.0;
}

bool HarnessConfig::HasDistortion() const {
  return !seidel_sigma_per_mm2.empty() || !brown_k1.empty() || !brown_k2.empty();
}

bool HarnessConfig::HasAssembly() const {
  for (const auto& v : assembly) {
    if (!v.empty()) return true;
  }
  return false;
}

const std::vector<double>& HarnessConfig::Coefficients(DistortionFamily family) const {
  switch (family) {
    case DistortionFamily::kSeidelSigma:
      return seidel_sigma_per_mm2;
    case DistortionFamily::kBrownK1:
      return brown_k1;
    case DistortionFamily::kBrownK2:
      return brown_k2;
  }
  return seidel_sigma_per_mm2;
}

std::vector<double>& HarnessConfig::Coefficients(DistortionFamily family) {
  return const_cast<std::vector<double>&>(static_cast<const HarnessConfig&>(*this).Coefficients(family));
}

namespace {

void ParseDistortion(Reader& top, const std::string& origin, HarnessConfig* h) {
  Reader d(top.Get("distortion"), origin, "distortion");
  for (const DistortionFamily f : kDistortionFamilies) {
    const std::string name = DistortionFamilyName(f);
    if (!d.Has(name)) continue;
    h->Coefficients(f) = ParseValues(d, name);
  }
  d.RejectUnknown();
  if (!h->HasDistortion()) {
    top.Fail("distortion", "must give at least one of seidel_sigma_per_mm2, brown_k1, brown_k2");
  }
}

void ParseNoise(Reader& top, HarnessConfig* h) {
  h->noise_px = ParseValues(top, "noise_px");
  for (size_t i = 0; i < h->noise_px.size(); ++i) {
    if (h->noise_px[i] < 0)
      top.Fail(fmt::format("noise_px[{}]", i), fmt::format("must be >= 0 px (got {})", h->noise_px[i]));
  }
  if (top.Has("noise_draws")) {
    const json& n = top.Get("noise_draws");
    if (!n.is_number_integer())
      top.Fail("noise_draws", fmt::format("must be an integer (got {})", util::QuoteJsonValue(n)));
    const long long draws = util::JsonIntegerWithin(n, 1, static_cast<long long>(kMaxCases)) ? n.get<long long>() : -1;
    if (draws < 1 || draws > kMaxCases)
      top.Fail("noise_draws", fmt::format("must lie in [1, {:.0f}] (got {})", kMaxCases, util::QuoteJsonValue(n)));
    h->noise_draws = static_cast<int>(draws);
  }
}

void ParseCalibrationErrors(Reader& top, HarnessConfig* h) {
  if (h->HasDistortion()) {
    h->calibration_errors = ParseValues(top, "calibration_errors");
    for (size_t i = 0; i < h->calibration_errors.size(); ++i) {
      if (h->calibration_errors[i] < -1) {
        top.Fail(fmt::format("calibration_errors[{}]", i),
                 fmt::format("must be >= -1 (-1: no correction; got {})", h->calibration_errors[i]));
      }
    }
  } else if (top.Has("calibration_errors")) {
    top.Fail("calibration_errors",
             "applies to distortion coefficients only, and none is given (assembly errors are "
             "measured uncorrected)");
  }
}

void ParseLimits(Reader& top, const std::string& origin, HarnessLimits* limits) {
  Reader l(top.Get("limits"), origin, "limits");
  limits->dk = l.PositiveNumber("dk", limits->dk);
  limits->dP_D = l.PositiveNumber("dP_D", limits->dP_D);
  if (l.Has("dP_maps")) {
    const std::string maps = l.String("dP_maps");
    if (maps != "axial+tangential" && maps != "axial") {
      l.Fail(l.Key("dP_maps"), fmt::format("must be \"axial+tangential\" or \"axial\" (got \"{}\")", maps));
    }
    limits->tangential_map = maps == "axial+tangential";
  }
  l.RejectUnknown();
}

// The sweep's size must stay below kMaxCases.
void CheckCaseCount(Reader& top, const HarnessConfig& h) {
  double noise_cases = 0;
  for (const double n : h.noise_px) noise_cases += n > 0 ? h.noise_draws : 1;
  const double distortions = static_cast<double>(h.seidel_sigma_per_mm2.size() + h.brown_k1.size() + h.brown_k2.size());
  double assemblies = 0;
  for (const AssemblyAxis axis : kAssemblyAxes) {
    for (const double v : h.Errors(axis)) {
      assemblies += IsDirectional(axis) && v != 0 ? static_cast<double>(h.assembly_azimuths_deg.size()) : 1.0;
    }
  }
  const double cases = (distortions * static_cast<double>(h.calibration_errors.size()) + assemblies) *
                       static_cast<double>(h.corneas.size()) * noise_cases;
  if (cases > kMaxCases) {
    top.Fail("(top level)", fmt::format("{:.0f} cases: more than the {:.0f} a sweep may hold", cases, kMaxCases));
  }
}

}  // namespace

HarnessConfig ParseHarnessConfig(const std::string& json_text, const std::string& origin, const std::string& base_dir) {
  const json j = util::ParseJsonStrict(json_text, origin);
  HarnessConfig h;
  Reader top(j, origin, "");
  if (top.Has("description")) top.String("description");  // free text for the reader; not part of the identity
  h.design = ParseDesign(top, base_dir);
  h.pixel_pitch_um = top.PositiveNumber("pixel_pitch_um", h.pixel_pitch_um);
  if (top.Has("seed")) {
    const json& s = top.Get("seed");
    if (!s.is_number_unsigned())
      top.Fail("seed", fmt::format("must be a non-negative integer (got {})", util::QuoteJsonValue(s)));
    h.seed = s.get<std::uint64_t>();
  }
  if (top.Has("distortion")) ParseDistortion(top, origin, &h);
  if (top.Has("assembly")) ParseAssembly(top, &h);
  if (!h.HasDistortion() && !h.HasAssembly()) {
    top.Fail("distortion", "missing: give distortion coefficients, assembly errors or both");
  }
  h.corneas = ParseCorneas(top, h.design);
  ParseNoise(top, &h);
  ParseCalibrationErrors(top, &h);
  ParseLimits(top, origin, &h.limits);
  top.RejectUnknown();
  CheckCaseCount(top, h);
  return h;
}

HarnessConfig LoadHarnessConfig(const std::string& path) {
  std::string text;
  try {
    text = util::ReadFile(path);
  } catch (const util::InputError&) {
    throw util::ConfigError(fmt::format("{}: (file): cannot be opened for reading", path));
  }
  return ParseHarnessConfig(text, path, std::filesystem::path(path).parent_path().string());
}

std::string CanonicalHarnessJson(const HarnessConfig& h) {
  json j;
  j["design"] = json::parse(model::ConfigToJson(h.design));
  j["pixel_pitch_um"] = h.pixel_pitch_um;
  j["seed"] = h.seed;
  if (h.HasDistortion()) {
    json d = json::object();
    for (const DistortionFamily f : kDistortionFamilies) {
      if (!h.Coefficients(f).empty()) d[DistortionFamilyName(f)] = ValuesJson(h.Coefficients(f));
    }
    j["distortion"] = d;
  }
  if (h.HasAssembly()) {
    json a = json::object();
    bool directional = false;
    for (const AssemblyAxis axis : kAssemblyAxes) {
      if (h.Errors(axis).empty()) continue;
      a[AssemblyAxisName(axis)] = ValuesJson(h.Errors(axis));
      directional = directional || IsDirectional(axis);
    }
    if (directional) a["azimuths_deg"] = ValuesJson(h.assembly_azimuths_deg);
    j["assembly"] = a;
  }
  json corneas = json::array();
  for (const auto& c : h.corneas) {
    corneas.push_back({{"name", c.name},
                       {"rx_mm", c.params.rx_mm},
                       {"ry_mm", c.params.ry_mm},
                       {"kx", c.params.kx},
                       {"ky", c.params.ky},
                       {"alpha_deg", c.params.alpha_deg},
                       {"x0_mm", c.params.x0_mm},
                       {"y0_mm", c.params.y0_mm},
                       {"z0_mm", c.params.z0_mm}});
  }
  j["corneas"] = corneas;
  j["noise_px"] = ValuesJson(h.noise_px);
  j["noise_draws"] = h.noise_draws;
  if (h.HasDistortion()) j["calibration_errors"] = ValuesJson(h.calibration_errors);
  j["limits"] = {{"dk", h.limits.dk},
                 {"dP_D", h.limits.dP_D},
                 {"dP_maps", h.limits.tangential_map ? "axial+tangential" : "axial"}};
  return j.dump();
}

std::string HarnessConfigSha256(const HarnessConfig& config) { return util::Sha256Hex(CanonicalHarnessJson(config)); }

}  // namespace topocal::harness
