// unit-inputs.json, one unit of `unit calibrate-batch` (docs/unit-record.md, "Batch"): read strictly, every key
// checked by name, paths relative to the file.
#include <fmt/format.h>

#include <cstdint>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/unit_workflow.h"
#include "util/file_glob.h"
#include "util/io.h"
#include "util/json_section.h"

namespace topocal::pipeline {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// uncertainty_samples, the values --uncertainty takes: "linear", "none" or a number of draws as a string; 0 (none) or
// 2 to kMaxUncertaintySamples Monte Carlo draws as a number.
UncertaintySetting ReadUncertainty(util::JsonSection& s) {
  const json& v = s.Get("uncertainty_samples");
  const std::string text = v.is_string()
                               ? v.get<std::string>()
                               : std::to_string(s.IntegerInRange("uncertainty_samples", 0, kMaxUncertaintySamples));
  try {
    return UncertaintySetting::Parse(text, "uncertainty_samples");
  } catch (const util::InputError&) {
    s.Fail("uncertainty_samples", fmt::format("expected \"linear\", \"none\", 0 or 2 to {} (got {})",
                                             kMaxUncertaintySamples, util::QuoteJsonValue(v)));
  }
}

}  // namespace

UnitRequest ReadUnitInputs(const std::string& path, const UnitRequest& defaults) {
  const json j = util::ParseJsonStrict(util::ReadFile(path), path);
  util::JsonSection s(j, path, "");
  // Unknown keys first: a misspelt key is the likelier cause of whatever would fail next.
  for (const char* key : {"serial", "target", "images", "reference_sphere", "sphere_radius_mm", "model", "fit_centre",
                          "fix", "fix_aspect", "allow_undetermined", "config", "device", "uncertainty_samples", "seed",
                          "sphere_repeats"}) {
    s.MarkSeen(key);
  }
  s.RejectUnknown();
  const fs::path base = fs::path(path).parent_path();
  const auto relative = [&](const std::string& p) { return fs::path(p).is_absolute() ? p : (base / p).string(); };
  const auto str = [&](const char* key, bool required) -> std::optional<std::string> {
    if (!s.Has(key)) {
      if (required) s.Get(key);  // fails: missing
      return std::nullopt;
    }
    const std::string v = s.String(key);
    if (v.empty()) s.Fail(key, "expected a non-empty string");
    return v;
  };
  // A list of non-empty strings.
  const auto strings = [&](const char* key, const char* what) {
    const json& v = s.Get(key);
    const auto bad = [&] { s.Fail(key, fmt::format("expected a list of {} (got {})", what, util::QuoteJsonValue(v))); };
    if (!v.is_array()) bad();
    std::vector<std::string> out;
    for (const auto& f : v) {
      if (!f.is_string() || f.get<std::string>().empty()) bad();
      out.push_back(f.get<std::string>());
    }
    return out;
  };
  UnitRequest r = defaults;
  r.serial = *str("serial", true);
  r.target = relative(*str("target", true));
  r.images = util::Glob(relative(*str("images", true)), fmt::format("{}: images", path));
  if (const auto v = str("reference_sphere", false)) r.reference_sphere = relative(*v);
  if (s.Has("sphere_radius_mm")) r.sphere_radius_mm = s.PositiveNumber("sphere_radius_mm", 0);
  if (s.Has("sphere_repeats")) {
    r.sphere_repeats = strings("sphere_repeats", "image paths");
    for (auto& p : r.sphere_repeats) p = relative(p);
  }
  if (const auto v = str("model", false)) r.model = *v;
  if (const auto v = str("config", false)) r.config = relative(*v);
  if (const auto v = str("device", false)) r.device = relative(*v);
  if (s.Has("fit_centre")) {
    const json& v = s.Get("fit_centre");
    if (!v.is_boolean()) s.Fail("fit_centre", fmt::format("expected true or false (got {})", util::QuoteJsonValue(v)));
    r.fit_centre = v.get<bool>();
  }
  if (s.Has("fix")) r.fixed = strings("fix", "parameter names");
  if (s.Has("fix_aspect")) r.fixed_aspect_ratio = s.Number("fix_aspect");  // range checked with the options
  if (s.Has("allow_undetermined")) {
    const json& v = s.Get("allow_undetermined");
    if (!v.is_boolean()) {
      s.Fail("allow_undetermined", fmt::format("expected true or false (got {})", util::QuoteJsonValue(v)));
    }
    r.allow_undetermined = v.get<bool>();
  }
  if (s.Has("uncertainty_samples")) r.uncertainty = ReadUncertainty(s);
  if (s.Has("seed")) {
    const json& v = s.Get("seed");
    if (!util::JsonIntegerWithin(v, 0, std::numeric_limits<std::uint32_t>::max())) {
      s.Fail("seed", fmt::format("expected an integer in [0, {}] (got {})", std::numeric_limits<std::uint32_t>::max(),
                                 util::QuoteJsonValue(v)));
    }
    r.seed = static_cast<unsigned>(v.get<unsigned long long>());
  }
  return r;
}


}  // namespace topocal::pipeline
