#include "harness/harness.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>

#include "util/io.h"
#include "util/json_section.h"
#include "util/version.h"

// The harness's shard files: their names, their JSON (written, read back and checked against the configuration) and
// the merge of a run's shards.
namespace topocal::harness {
namespace {

using nlohmann::json;

constexpr const char* kShardFormat = "topocal-harness-shard";
constexpr int kShardFormatVersion = 1;

[[noreturn]] void ShardFail(const std::string& origin, const std::string& key, const std::string& problem) {
  throw util::InputError(fmt::format("{}: {}: {}", origin, key, problem));
}

json BiconicJson(const model::BiconicParams& p) {
  return {{"rx_mm", p.rx_mm}, {"ry_mm", p.ry_mm},         {"kx", p.kx},
          {"ky", p.ky},       {"alpha_deg", p.alpha_deg}, {"z0_mm", p.z0_mm}};
}

// Every integer of a shard is a count or an index well inside int; beyond it is a corrupt shard, not a wrap.
int Count(util::JsonSection& s, const char* key) { return s.IntegerInRange(key, 0, std::numeric_limits<int>::max()); }

HarnessTruth ReadTruth(util::JsonSection& t_json) {
  HarnessTruth t;
  t.cornea = t_json.String("cornea");
  util::JsonSection fit = t_json.Child("fit");
  t.fit.rx_mm = fit.Number("rx_mm");
  t.fit.ry_mm = fit.Number("ry_mm");
  t.fit.kx = fit.Number("kx");
  t.fit.ky = fit.Number("ky");
  t.fit.alpha_deg = fit.Number("alpha_deg");
  t.fit.z0_mm = fit.Number("z0_mm");
  t.covered_radius_mm = t_json.Number("covered_radius_mm");
  t.spot_field_radius_mm = t_json.Number("spot_field_radius_mm");
  t.spots = Count(t_json, "spots");
  t.pv_axial_D = t_json.Number("pv_axial_D");
  t.pv_tangential_D = t_json.Number("pv_tangential_D");
  return t;
}

// The shard's cases: each of this shard (index i with i mod N = its index), in increasing order, with the seed its
// case has in `all`.
void ReadCases(util::JsonSection& root, const std::vector<HarnessCaseSpec>& all, HarnessRun* run) {
  const size_t n_cases = root.Array("cases").size();
  int previous = -1;
  for (size_t i = 0; i < n_cases; ++i) {
    util::JsonSection c = root.Element("cases", i);
    HarnessCaseResult r;
    const int index = Count(c, "index");
    if (index >= run->total_cases || index % run->shard.count != run->shard.index || index <= previous) {
      c.Fail(c.Key("index"), fmt::format("{} does not belong to shard {}/{} in increasing order", index,
                                         run->shard.index, run->shard.count));
    }
    previous = index;
    r.spec = all[static_cast<size_t>(index)];
    const json& seed = c.Get("seed");
    if (!seed.is_number_unsigned() || seed.get<std::uint64_t>() != r.spec.seed) {
      c.Fail(c.Key("seed"), "does not match the seed of the case (another seeding scheme?)");
    }
    r.ok = c.Bool("ok");
    r.failure = c.String("failure");
    r.residual_max_um = c.Number("residual_max_um");
    r.residual_rms_um = c.Number("residual_rms_um");
    r.spots_used = Count(c, "spots_used");
    r.undistort_failures = Count(c, "undistort_failures");
    r.dk_x = c.Number("dk_x");
    r.dk_y = c.Number("dk_y");
    r.dr_x_mm = c.Number("dr_x_mm");
    r.dr_y_mm = c.Number("dr_y_mm");
    r.dP_axial_max_D = c.Number("dP_axial_max_D");
    r.dP_tangential_max_D = c.Number("dP_tangential_max_D");
    r.dpv_axial_D = c.Number("dpv_axial_D");
    r.dpv_tangential_D = c.Number("dpv_tangential_D");
    r.compared_radius_mm = c.Number("compared_radius_mm");
    run->cases.push_back(r);
  }
}

}  // namespace

std::vector<std::string> ShardFilesIn(const std::string& arg) {
  std::error_code ec;
  if (!std::filesystem::exists(arg, ec))
    throw util::InputError(fmt::format("{}: shard: no such file or directory", arg));
  if (!std::filesystem::is_directory(arg, ec)) return {arg};
  std::vector<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(arg, ec)) {
    const std::string name = entry.path().filename().string();
    if (entry.is_regular_file() && name.rfind("shard-", 0) == 0 && name.size() > 5 &&
        name.compare(name.size() - 5, 5, ".json") == 0) {
      files.push_back(entry.path().string());
    }
  }
  if (ec) throw util::InputError(fmt::format("{}: shard: cannot be listed: {}", arg, ec.message()));
  if (files.empty()) throw util::InputError(fmt::format("{}: shard: no shard-<i>-of-<N>.json file in it", arg));
  std::sort(files.begin(), files.end());
  return files;
}

std::string HarnessShardFileName(util::ShardSpec shard) {
  return fmt::format("shard-{}-of-{}.json", shard.index, shard.count);
}

std::string HarnessShardJson(const HarnessRun& run) {
  json j;
  j["format"] = kShardFormat;
  j["format_version"] = kShardFormatVersion;
  j["topocal_version"] = kVersion;
  j["config_sha256"] = run.config_sha256;
  j["config"] = json::parse(CanonicalHarnessJson(run.config));
  j["shard"] = {{"index", run.shard.index}, {"count", run.shard.count}};
  j["total_cases"] = run.total_cases;
  json truth = json::array();
  for (const auto& t : run.truth) {
    truth.push_back({{"cornea", t.cornea},
                     {"fit", BiconicJson(t.fit)},
                     {"covered_radius_mm", t.covered_radius_mm},
                     {"spot_field_radius_mm", t.spot_field_radius_mm},
                     {"spots", t.spots},
                     {"pv_axial_D", t.pv_axial_D},
                     {"pv_tangential_D", t.pv_tangential_D}});
  }
  j["truth"] = truth;
  json cases = json::array();
  for (const auto& c : run.cases) {
    cases.push_back({{"index", c.spec.index},
                     {"seed", c.spec.seed},
                     {"ok", c.ok},
                     {"failure", c.failure},
                     {"residual_max_um", c.residual_max_um},
                     {"residual_rms_um", c.residual_rms_um},
                     {"spots_used", c.spots_used},
                     {"undistort_failures", c.undistort_failures},
                     {"dk_x", c.dk_x},
                     {"dk_y", c.dk_y},
                     {"dr_x_mm", c.dr_x_mm},
                     {"dr_y_mm", c.dr_y_mm},
                     {"dP_axial_max_D", c.dP_axial_max_D},
                     {"dP_tangential_max_D", c.dP_tangential_max_D},
                     {"dpv_axial_D", c.dpv_axial_D},
                     {"dpv_tangential_D", c.dpv_tangential_D},
                     {"compared_radius_mm", c.compared_radius_mm}});
  }
  j["cases"] = cases;
  return j.dump(1) + "\n";
}

HarnessRun ParseHarnessShard(const std::string& text, const std::string& origin) {
  const json j = util::ParseJsonStrict(text, origin);
  if (!j.is_object() || !j.contains("format") || j["format"] != kShardFormat) {
    ShardFail(origin, "format", fmt::format("not a harness shard (expected \"{}\")", kShardFormat));
  }
  // The project's strict JSON reader (util/json_section.h): every failure names the shard and the dotted key.
  util::JsonSection root(j, origin, "");
  if (Count(root, "format_version") != kShardFormatVersion) {
    ShardFail(origin, "format_version",
              fmt::format("must be {} (written by another topocal version)", kShardFormatVersion));
  }
  HarnessRun run;
  try {
    run.config = ParseHarnessConfig(root.Child("config").raw().dump(), origin + ": config", "");
  } catch (const util::ConfigError& e) {
    throw util::InputError(e.what());
  }
  run.config_sha256 = root.String("config_sha256");
  if (run.config_sha256 != HarnessConfigSha256(run.config)) {
    ShardFail(origin, "config_sha256", "does not match the configuration stored in the shard (file edited?)");
  }
  util::JsonSection shard = root.Child("shard");
  run.shard.index = Count(shard, "index");
  run.shard.count = Count(shard, "count");
  if (run.shard.count < 1 || run.shard.index < 0 || run.shard.index >= run.shard.count) {
    ShardFail(origin, "shard",
              fmt::format("{}/{} is not a shard i/N with 0 <= i < N", run.shard.index, run.shard.count));
  }
  const auto all = EnumerateHarnessCases(run.config);
  run.total_cases = Count(root, "total_cases");
  if (run.total_cases != static_cast<int>(all.size())) {
    ShardFail(origin, "total_cases", fmt::format("{} but the configuration has {} cases", run.total_cases, all.size()));
  }
  if (root.Array("truth").size() != run.config.corneas.size()) {
    ShardFail(origin, "truth", "must hold one entry per cornea");
  }
  for (size_t i = 0; i < run.config.corneas.size(); ++i) {
    util::JsonSection t_json = root.Element("truth", i);
    run.truth.push_back(ReadTruth(t_json));
  }
  ReadCases(root, all, &run);
  int expected = 0;
  for (int k = run.shard.index; k < run.total_cases; k += run.shard.count) ++expected;
  if (static_cast<int>(run.cases.size()) != expected) {
    ShardFail(origin, "cases",
              fmt::format("{} cases but shard {}/{} has {} (incomplete shard)", run.cases.size(), run.shard.index,
                          run.shard.count, expected));
  }
  return run;
}

HarnessRun MergeHarnessShards(const std::vector<HarnessRun>& shards, const std::vector<std::string>& origins) {
  if (shards.empty()) throw util::InputError("harness merge: no shard given");
  const HarnessRun& first = shards.front();
  std::map<int, size_t> by_index;
  for (size_t i = 0; i < shards.size(); ++i) {
    const HarnessRun& s = shards[i];
    if (s.config_sha256 != first.config_sha256) {
      throw util::InputError(
          fmt::format("{}: config_sha256: {} differs from {} in {} (shards of another "
                      "configuration)",
                      origins[i], s.config_sha256, first.config_sha256, origins[0]));
    }
    if (s.shard.count != first.shard.count) {
      throw util::InputError(fmt::format("{}: shard: split into {} shards but {} is split into {}", origins[i],
                                         s.shard.count, origins[0], first.shard.count));
    }
    const auto [it, inserted] = by_index.emplace(s.shard.index, i);
    if (!inserted) {
      throw util::InputError(fmt::format("{}: shard: {}/{} is given twice (also {})", origins[i], s.shard.index,
                                         s.shard.count, origins[it->second]));
    }
    for (size_t c = 0; c < s.truth.size(); ++c) {
      const auto& a = s.truth[c];
      const auto& b = first.truth[c];
      if (a.fit.kx != b.fit.kx || a.fit.ky != b.fit.ky || a.fit.rx_mm != b.fit.rx_mm || a.fit.ry_mm != b.fit.ry_mm ||
          a.covered_radius_mm != b.covered_radius_mm) {
        throw util::InputError(fmt::format("{}: truth[{}]: differs from {} (shards computed by different builds)",
                                           origins[i], c, origins[0]));
      }
    }
  }
  for (int k = 0; k < first.shard.count; ++k) {
    if (!by_index.count(k)) {
      throw util::InputError(fmt::format("harness merge: shard {}/{} is missing", k, first.shard.count));
    }
  }
  HarnessRun merged;
  merged.config = first.config;
  merged.config_sha256 = first.config_sha256;
  merged.shard = util::ShardSpec{0, 1};
  merged.total_cases = first.total_cases;
  merged.truth = first.truth;
  merged.cases.resize(static_cast<size_t>(merged.total_cases));
  std::vector<bool> filled(merged.cases.size(), false);
  for (const auto& s : shards) {
    for (const auto& c : s.cases) {
      const auto i = static_cast<size_t>(c.spec.index);
      if (i >= filled.size() || filled[i]) {
        throw util::InputError(fmt::format("harness merge: case {} is given twice", c.spec.index));
      }
      filled[i] = true;
      merged.cases[i] = c;
    }
  }
  for (size_t i = 0; i < filled.size(); ++i) {
    if (!filled[i]) throw util::InputError(fmt::format("harness merge: case {} is missing", i));
  }
  return merged;
}

}  // namespace topocal::harness
