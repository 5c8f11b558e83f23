// The goal of `topocal design --optimize` (pipeline/screen_design.h): validation and the JSON reader. Schema:
// docs/screen-design.md.
#include <fmt/format.h>

#include <cmath>
#include <algorithm>
#include <stdexcept>

#include "model/freeform_test_set.h"
#include "pipeline/screen_design.h"
#include "util/io.h"
#include "util/json_section.h"

namespace topocal::pipeline {
namespace {

// The grid stays small enough to search in well under a minute on one core (~0.1-0.4 s per cornea and candidate).
constexpr size_t kMaxCandidates = 60;
constexpr int kMaxRings = 40, kMaxEta = 64;
constexpr size_t kMaxCorneas = 20;
// The densest candidate: the reconstruction's cost grows with the spots (1,360 spots ~0.15 s per cornea, 5,000 ~1 s).
constexpr long kMaxCandidateSpots = 5000;

}  // namespace

bool ScreenDesignGoal::IsValid(std::string* why) const {
  const auto fail = [&](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  const auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (corneas.empty() || corneas.size() > kMaxCorneas) {
    return fail(fmt::format("corneas: must name 1 to {} test corneas (got {})", kMaxCorneas, corneas.size()));
  }
  if (max_tangential_rms_D && !positive(*max_tangential_rms_D)) return fail("max_tangential_rms_D: must be > 0");
  if (surface_model != "polynomial" && surface_model != "spline" && surface_model != "auto") {
    return fail("surface_model: must be \"polynomial\", \"spline\" or \"auto\" (got \"" + surface_model + "\")");
  }
  if (!positive(steepest_radius_mm)) return fail("steepest_radius_mm: must be > 0");
  if (!(flattest_radius_mm >= steepest_radius_mm) || !std::isfinite(flattest_radius_mm)) {
    return fail(fmt::format("flattest_radius_mm: must be at least steepest_radius_mm = {} (got {})",
                            steepest_radius_mm, flattest_radius_mm));
  }
  if (steepest_radius_mm < kScanSteepestMm || flattest_radius_mm > kScanFlattestMm) {
    return fail(fmt::format("steepest_radius_mm, flattest_radius_mm: must lie within [{}, {}] mm (got {} - {})",
                            kScanSteepestMm, kScanFlattestMm, steepest_radius_mm, flattest_radius_mm));
  }
  if (!positive(pixel_pitch_um)) return fail("pixel_pitch_um: must be > 0");
  if (!(min_gap_px >= 0) || !std::isfinite(min_gap_px)) return fail("min_gap_px: must be >= 0");
  if (!positive(min_spot_radius_um)) return fail("min_spot_radius_um: must be > 0");
  if (!(max_spot_radius_um >= min_spot_radius_um) || !std::isfinite(max_spot_radius_um)) {
    return fail(fmt::format("max_spot_radius_um: must be at least min_spot_radius_um = {} (got {})",
                            min_spot_radius_um, max_spot_radius_um));
  }
  if (!(min_printed_feature_mm >= 0) || !std::isfinite(min_printed_feature_mm)) {
    return fail("min_printed_feature_mm: must be >= 0");
  }
  if (max_page_mm.size() != 2 || !positive(max_page_mm[0]) || !positive(max_page_mm[1])) {
    return fail("max_page_mm: must be two sizes > 0 (mm)");
  }
  if (rings.empty() || eta.empty() || GridSize() > kMaxCandidates) {
    return fail(fmt::format("rings, eta, spline_spacing_mm: the grid must hold 1 to {} candidates (got {} x {} x {})",
                            kMaxCandidates, rings.size(), eta.size(), std::max<size_t>(1, spline_spacing_mm.size())));
  }
  for (double h : spline_spacing_mm) {
    // The configuration's own range (reconstruction.spline_spacing_mm).
    if (!(h >= 0.1 && h <= 2.0)) {
      return fail(fmt::format("spline_spacing_mm: each must lie in [0.1, 2] mm (got {})", h));
    }
  }
  if (!(spot_noise_px >= 0 && spot_noise_px <= 1)) {
    return fail(fmt::format("spot_noise_px: must lie in [0, 1] px (got {})", spot_noise_px));
  }
  for (int r : rings) {
    if (r < 2 || r > kMaxRings) return fail(fmt::format("rings: each must be in [2, {}] (got {})", kMaxRings, r));
  }
  for (int e : eta) {
    if (e < 1 || e > kMaxEta) return fail(fmt::format("eta: each must be in [1, {}] (got {})", kMaxEta, e));
  }
  const long densest = long{*std::max_element(eta.begin(), eta.end())} * *std::max_element(rings.begin(), rings.end()) *
                       (*std::max_element(rings.begin(), rings.end()) + 1) / 2;
  if (densest > kMaxCandidateSpots) {
    return fail(fmt::format("rings, eta: the densest candidate has {} spots; at most {}", densest, kMaxCandidateSpots));
  }
  return true;
}

namespace {

std::vector<int> Integers(util::JsonSection& s, const std::string& key) {
  const auto& a = s.Array(key);
  std::vector<int> out;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!util::JsonIntegerWithin(a[i], 1, 1000)) {
      s.Fail(fmt::format("{}[{}]", s.Key(key), i), fmt::format("must be an integer in [1, 1000] (got {})",
                                                                 util::QuoteJsonValue(a[i])));
    }
    out.push_back(a[i].get<int>());
  }
  return out;
}

std::vector<double> Spacings(util::JsonSection& s, const std::string& key) {
  const auto& a = s.Array(key);
  std::vector<double> out;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!a[i].is_number()) {
      s.Fail(fmt::format("{}[{}]", s.Key(key), i),
             fmt::format("must be a number (got {})", util::QuoteJsonValue(a[i])));
    }
    out.push_back(a[i].get<double>());
  }
  if (out.empty()) s.Fail(s.Key(key), "must hold at least one spacing (leave it out for the configuration's own)");
  return out;
}

std::vector<std::string> CorneaNames(util::JsonSection& s) {
  const auto& a = s.Array("corneas");
  std::vector<std::string> known;
  for (const auto& c : model::FreeformTestSet()) known.push_back(c.name);
  std::vector<std::string> out;
  for (size_t i = 0; i < a.size(); ++i) {
    const std::string key = fmt::format("{}[{}]", s.Key("corneas"), i);
    if (!a[i].is_string()) s.Fail(key, fmt::format("must be a string (got {})", util::QuoteJsonValue(a[i])));
    const auto name = a[i].get<std::string>();
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      s.Fail(key, fmt::format("no test cornea named \"{}\" (model/freeform_test_set.h: {})", name,
                              fmt::join(known, ", ")));
    }
    out.push_back(name);
  }
  return out;
}

}  // namespace

ScreenDesignGoal ParseScreenDesignGoal(const std::string& json_text, const std::string& origin) {
  const auto j = util::ParseJsonStrict(json_text, origin);
  util::JsonSection s(j, origin, "");
  ScreenDesignGoal g;
  if (s.Has("corneas")) g.corneas = CorneaNames(s);
  if (!s.AbsentOrNull("max_tangential_rms_D")) g.max_tangential_rms_D = s.Number("max_tangential_rms_D");
  s.MarkSeen("max_tangential_rms_D");
  g.surface_model = s.String("surface_model", g.surface_model);
  g.steepest_radius_mm = s.Number("steepest_radius_mm", g.steepest_radius_mm);
  g.flattest_radius_mm = s.Number("flattest_radius_mm", g.flattest_radius_mm);
  g.pixel_pitch_um = s.Number("pixel_pitch_um", g.pixel_pitch_um);
  g.min_gap_px = s.Number("min_gap_px", g.min_gap_px);
  g.max_spot_radius_um = s.Number("max_spot_radius_um", g.max_spot_radius_um);
  g.min_spot_radius_um = s.Number("min_spot_radius_um", g.min_spot_radius_um);
  g.min_printed_feature_mm = s.Number("min_printed_feature_mm", g.min_printed_feature_mm);
  if (s.Has("max_page_mm")) g.max_page_mm = s.Numbers("max_page_mm", 2);
  if (s.Has("rings")) g.rings = Integers(s, "rings");
  if (s.Has("eta")) g.eta = Integers(s, "eta");
  if (s.Has("spline_spacing_mm")) g.spline_spacing_mm = Spacings(s, "spline_spacing_mm");
  g.spot_noise_px = s.Number("spot_noise_px", g.spot_noise_px);
  s.RejectUnknown();
  std::string why;
  if (!g.IsValid(&why)) throw util::ConfigError(origin + ": " + why);
  return g;
}

ScreenDesignGoal LoadScreenDesignGoal(const std::string& path) {
  return ParseScreenDesignGoal(util::ReadFile(path), path);
}

}  // namespace topocal::pipeline
