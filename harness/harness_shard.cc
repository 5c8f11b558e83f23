#include "harness/harness.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>

#include "util/io.h"
#include "util/json_section.h"
#include "util/json_strict.h"
#include "util/version.h"

// The harness's shard files: their names, their JSON (written, read back and checked against the configuration) and
// the merge of a run's shards.
namespace topocal::harness {
namespace {

using nlohmann::json;

constexpr const char* kShardFormat = "topocal-harness-shard";
constexpr int kShardFormatVersion = 2;  // 2: the cases as rows under "case_columns"

[[noreturn]] void ShardFail(const std::string& origin, const std::string& key, const std::string& problem) {
  throw util::InputError(fmt::format("{}: {}: {}", origin, key, problem));
}

json BiconicJson(const model::BiconicParams& p) {
  return {{"rx_mm", p.rx_mm}, {"ry_mm", p.ry_mm},         {"kx", p.kx},
          {"ky", p.ky},       {"alpha_deg", p.alpha_deg}, {"z0_mm", p.z0_mm}};
}

}  // namespace

json HarnessTruthJson(const std::vector<HarnessTruth>& truth) {
  json out = json::array();
  for (const auto& t : truth) {
    out.push_back({{"cornea", t.cornea},
                   {"fit", BiconicJson(t.fit)},
                   {"covered_radius_mm", t.covered_radius_mm},
                   {"spot_field_radius_mm", t.spot_field_radius_mm},
                   {"spots", t.spots},
                   {"pv_axial_D", t.pv_axial_D},
                   {"pv_tangential_D", t.pv_tangential_D}});
  }
  return out;
}

namespace {

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

// The columns of a case row, in order. Rows instead of one object per case: keys are not repeated in every case (the
// file is 2.2 x smaller, ~265 bytes per case) and a row is read by position, without a lookup per field.
constexpr const char* kCaseColumns[] = {
    "index", "seed", "ok", "failure", "residual_max_um", "residual_rms_um", "spots_used", "undistort_failures",
    "dk_x", "dk_y", "dr_x_mm", "dr_y_mm", "dP_axial_max_D", "dP_tangential_max_D", "dpv_axial_D", "dpv_tangential_D",
    "compared_radius_mm"};
constexpr size_t kNumCaseColumns = std::size(kCaseColumns);

// A shard of a million cases is ~265 MB; beyond 1 GiB (~4 million cases in one file) split the run into shards.
constexpr size_t kMaxShardBytes = size_t{1} << 30;

json CaseRow(const HarnessCaseResult& c) {
  return json::array({c.spec.index, c.spec.seed, c.ok, c.failure, c.residual_max_um, c.residual_rms_um, c.spots_used,
                      c.undistort_failures, c.dk_x, c.dk_y, c.dr_x_mm, c.dr_y_mm, c.dP_axial_max_D,
                      c.dP_tangential_max_D, c.dpv_axial_D, c.dpv_tangential_D, c.compared_radius_mm});
}

// One case row, read by column with every value's type checked; a failure names "cases[i].column".
class CaseRowReader {
 public:
  CaseRowReader(const json& row, const std::string& origin, size_t i) : row_(row), origin_(origin), i_(i) {
    if (!row.is_array() || row.size() != kNumCaseColumns) {
      ShardFail(origin, fmt::format("cases[{}]", i), fmt::format("must be an array of {} values", kNumCaseColumns));
    }
  }
  [[noreturn]] void Fail(size_t k, const std::string& problem) const {
    ShardFail(origin_, fmt::format("cases[{}].{}", i_, kCaseColumns[k]), problem);
  }
  double Number(size_t k) const {
    const json& v = row_[k];
    if (!v.is_number() || !std::isfinite(v.get<double>())) Fail(k, "must be a finite number");
    return v.get<double>();
  }
  int Count(size_t k) const {
    const json& v = row_[k];
    if (!util::JsonIntegerWithin(v, 0, std::numeric_limits<int>::max())) Fail(k, "must be an integer >= 0");
    return static_cast<int>(v.get<long long>());
  }
  bool Bool(size_t k) const {
    if (!row_[k].is_boolean()) Fail(k, "must be true or false");
    return row_[k].get<bool>();
  }
  std::string String(size_t k) const {
    if (!row_[k].is_string()) Fail(k, "must be a string");
    return row_[k].get<std::string>();
  }
  const json& Raw(size_t k) const { return row_[k]; }

 private:
  const json& row_;
  const std::string& origin_;
  size_t i_;
};

// The shard's cases: each of this shard (index i with i mod N = its index), in increasing order, with the seed its
// case has in `all`.
void ReadCases(const json& rows, const std::string& origin, const std::vector<HarnessCaseSpec>& all, HarnessRun* run) {
  int previous = -1;
  run->cases.reserve(rows.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    const CaseRowReader c(rows[i], origin, i);
    HarnessCaseResult r;
    const int index = c.Count(0);
    if (index >= run->total_cases || index % run->shard.count != run->shard.index || index <= previous) {
      c.Fail(0, fmt::format("{} does not belong to shard {}/{} in increasing order", index, run->shard.index,
                            run->shard.count));
    }
    previous = index;
    r.spec = all[static_cast<size_t>(index)];
    if (!c.Raw(1).is_number_unsigned() || c.Raw(1).get<std::uint64_t>() != r.spec.seed) {
      c.Fail(1, "does not match the seed of the case (another seeding scheme?)");
    }
    r.ok = c.Bool(2);
    r.failure = c.String(3);
    r.residual_max_um = c.Number(4);
    r.residual_rms_um = c.Number(5);
    r.spots_used = c.Count(6);
    r.undistort_failures = c.Count(7);
    double* const errors[] = {&r.dk_x,           &r.dk_y,
                              &r.dr_x_mm,        &r.dr_y_mm,
                              &r.dP_axial_max_D, &r.dP_tangential_max_D,
                              &r.dpv_axial_D,    &r.dpv_tangential_D,
                              &r.compared_radius_mm};
    for (size_t k = 0; k < std::size(errors); ++k) *errors[k] = c.Number(8 + k);
    run->cases.push_back(std::move(r));
  }
}

// Everything of a shard but its cases, checked; `j` is the whole file.
HarnessRun ReadShardHeader(const json& j, const std::string& origin) {
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
  run.total_cases = Count(root, "total_cases");
  if (root.Array("truth").size() != run.config.corneas.size()) {
    ShardFail(origin, "truth", "must hold one entry per cornea");
  }
  for (size_t i = 0; i < run.config.corneas.size(); ++i) {
    util::JsonSection t_json = root.Element("truth", i);
    run.truth.push_back(ReadTruth(t_json));
  }
  const json& columns = root.Array("case_columns");
  if (columns.size() != kNumCaseColumns ||
      !std::equal(columns.begin(), columns.end(), std::begin(kCaseColumns),
                  [](const json& a, const char* b) { return a.is_string() && a.get_ref<const std::string&>() == b; })) {
    ShardFail(origin, "case_columns", "not the columns of this topocal version");
  }
  root.Array("cases");
  return run;
}

// The cases of the header's configuration (`all`), its shard's rows read and counted.
void ReadShardCases(const json& j, const std::string& origin, const std::vector<HarnessCaseSpec>& all,
                    HarnessRun* run) {
  if (run->total_cases != static_cast<int>(all.size())) {
    ShardFail(origin, "total_cases",
              fmt::format("{} but the configuration has {} cases", run->total_cases, all.size()));
  }
  ReadCases(j["cases"], origin, all, run);
  int expected = 0;
  for (int k = run->shard.index; k < run->total_cases; k += run->shard.count) ++expected;
  if (static_cast<int>(run->cases.size()) != expected) {
    ShardFail(origin, "cases",
              fmt::format("{} cases but shard {}/{} has {} (incomplete shard)", run->cases.size(), run->shard.index,
                          run->shard.count, expected));
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
  j["truth"] = HarnessTruthJson(run.truth);
  j["case_columns"] = kCaseColumns;
  // The cases last, one row per line (the header's dump ends in "\n}").
  std::string text = j.dump(1);
  text.resize(text.size() - 2);
  text += ",\n \"cases\": [";
  for (size_t i = 0; i < run.cases.size(); ++i) {
    text += i == 0 ? "\n  " : ",\n  ";
    text += CaseRow(run.cases[i]).dump();
  }
  text += run.cases.empty() ? "]\n}\n" : "\n ]\n}\n";
  return text;
}

HarnessRun ParseHarnessShard(const std::string& text, const std::string& origin) {
  const json j = util::ParseJsonStrictUpTo(text, origin, kMaxShardBytes);
  HarnessRun run = ReadShardHeader(j, origin);
  ReadShardCases(j, origin, EnumerateHarnessCases(run.config), &run);
  return run;
}

void HarnessShardMerger::Add(const std::string& text, const std::string& origin) {
  const json j = util::ParseJsonStrictUpTo(text, origin, kMaxShardBytes);
  HarnessRun run = ReadShardHeader(j, origin);
  // Another configuration is refused by Add(run) below, before its cases are read against this one's.
  if (!shards_.empty() && run.config_sha256 != merged_.config_sha256) return Add(std::move(run), origin);
  if (all_.empty()) all_ = EnumerateHarnessCases(run.config);
  ReadShardCases(j, origin, all_, &run);
  Add(std::move(run), origin);
}

void HarnessShardMerger::Add(HarnessRun s, const std::string& origin) {
  if (shards_.empty()) {
    merged_.config = s.config;
    merged_.config_sha256 = s.config_sha256;
    merged_.shard = s.shard;
    merged_.total_cases = s.total_cases;
    merged_.truth = s.truth;
    merged_.cases.resize(static_cast<size_t>(s.total_cases));
    filled_.assign(merged_.cases.size(), false);
    first_origin_ = origin;
  }
  if (s.config_sha256 != merged_.config_sha256) {
    throw util::InputError(fmt::format("{}: config_sha256: {} differs from {} in {} (shards of another configuration)",
                                       origin, s.config_sha256, merged_.config_sha256, first_origin_));
  }
  if (s.shard.count != merged_.shard.count) {
    throw util::InputError(fmt::format("{}: shard: split into {} shards but {} is split into {}", origin,
                                       s.shard.count, first_origin_, merged_.shard.count));
  }
  const auto [it, inserted] = shards_.emplace(s.shard.index, origin);
  if (!inserted) {
    throw util::InputError(fmt::format("{}: shard: {}/{} is given twice (also {})", origin, s.shard.index,
                                       s.shard.count, it->second));
  }
  for (size_t c = 0; c < s.truth.size() && c < merged_.truth.size(); ++c) {
    const auto& a = s.truth[c];
    const auto& b = merged_.truth[c];
    if (a.fit.kx != b.fit.kx || a.fit.ky != b.fit.ky || a.fit.rx_mm != b.fit.rx_mm || a.fit.ry_mm != b.fit.ry_mm ||
        a.covered_radius_mm != b.covered_radius_mm) {
      throw util::InputError(fmt::format("{}: truth[{}]: differs from {} (shards computed by different builds)",
                                         origin, c, first_origin_));
    }
  }
  for (auto& c : s.cases) {
    const auto i = static_cast<size_t>(c.spec.index);
    if (i >= filled_.size() || filled_[i]) {
      throw util::InputError(fmt::format("harness merge: case {} is given twice", c.spec.index));
    }
    filled_[i] = true;
    merged_.cases[i] = std::move(c);
  }
}

HarnessRun HarnessShardMerger::Finish() {
  if (shards_.empty()) throw util::InputError("harness merge: no shard given");
  // The shards are held in index order: the first index that is not its place is missing.
  int k = 0;
  for (const auto& entry : shards_) {
    if (entry.first != k) break;
    ++k;
  }
  if (k < merged_.shard.count) {
    throw util::InputError(fmt::format("harness merge: shard {}/{} is missing", k, merged_.shard.count));
  }
  for (size_t i = 0; i < filled_.size(); ++i) {
    if (!filled_[i]) throw util::InputError(fmt::format("harness merge: case {} is missing", i));
  }
  merged_.shard = util::ShardSpec{0, 1};
  // Freed before the outputs are rendered (at a million cases the enumeration alone is ~90 MB).
  shards_.clear();
  std::vector<bool>().swap(filled_);
  std::vector<HarnessCaseSpec>().swap(all_);
  return std::move(merged_);
}

HarnessRun MergeHarnessShards(const std::vector<HarnessRun>& shards, const std::vector<std::string>& origins) {
  HarnessShardMerger merger;
  for (size_t i = 0; i < shards.size(); ++i) merger.Add(shards[i], origins.at(i));
  return merger.Finish();
}

}  // namespace topocal::harness
