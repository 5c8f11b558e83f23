#include "report/unit_record_writer.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include <fmt/format.h>

#include "model/io.h"
#include "model/sha256.h"
#include "model/version.h"
#include "report/unit_record_reader.h"

namespace topocal::report {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

void CheckFinite(const json& j, const std::string& where) {
  if (j.is_object()) {
    for (const auto& [k, v] : j.items()) CheckFinite(v, where.empty() ? k : where + "." + k);
  } else if (j.is_array()) {
    for (size_t i = 0; i < j.size(); ++i) CheckFinite(j[i], fmt::format("{}[{}]", where, i));
  } else if (j.is_number_float() && !std::isfinite(j.get<double>())) {
    throw std::runtime_error(fmt::format("{}: not a finite number", where));
  }
}

// Every file under `dir` but unit.json, sorted, with its digest.
json FileDigests(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    std::string name = fs::relative(e.path(), dir).generic_string();
    if (name != "unit.json") names.push_back(std::move(name));
  }
  std::sort(names.begin(), names.end());
  json files = json::array();
  for (const auto& n : names) files.push_back({{"name", n}, {"sha256", model::Sha256HexOfFile((dir / n).string())}});
  return files;
}

// Replaces `out` by the complete directory `staged`: the old record (if any) is moved aside first and removed
// only after the new one is in place, so every moment either the old or the new record is whole.
void CommitDirectory(const fs::path& staged, const fs::path& out) {
  const model::DeferSignalCleanup defer;  // a signal between the two renames would lose both records
  std::error_code ec;
  const fs::path aside = out.string() + fmt::format(".old-{}", ::getpid());
  const bool had_old = fs::exists(out);
  if (had_old) {
    fs::rename(out, aside, ec);
    if (ec) throw model::InputError(fmt::format("{}: cannot replace the existing record: {}", out.string(), ec.message()));
  }
  fs::rename(staged, out, ec);
  if (ec) {
    if (had_old) fs::rename(aside, out, ec);
    throw model::InputError(fmt::format("{}: cannot write the record: {}", out.string(), ec.message()));
  }
  if (had_old) fs::remove_all(aside, ec);
}

}  // namespace

void RequireFiniteNumbers(const json& j) { CheckFinite(j, ""); }

namespace {
// "units/SN/" and "units/SN" are the same record: without the trailing separator, so that the staging directory
// ("units/SN.tmp-PID") is a sibling of the record and not inside it (which made every such run fail).
fs::path RecordPath(fs::path out) {
  out = out.lexically_normal();
  if (out.filename().empty() && out.has_parent_path()) out = out.parent_path();
  return out;
}
}  // namespace

UnitRecordWriter::UnitRecordWriter(fs::path out)
    : out_(RecordPath(std::move(out))), staging_(out_.string() + fmt::format(".tmp-{}", ::getpid())) {
  std::error_code ec;
  fs::remove_all(staging_, ec);
  model::RegisterCleanupPath(staging_.string());  // SIGINT/SIGTERM remove it (issue 16: 8 of 8 kills left it)
  fs::create_directories(staging_ / "maps", ec);
  if (ec) throw model::InputError(fmt::format("{}: cannot create the record directory: {}", out_.string(), ec.message()));
}

UnitRecordWriter::~UnitRecordWriter() {
  std::error_code ec;
  if (!committed_) fs::remove_all(staging_, ec);
  model::UnregisterCleanupPath(staging_.string());
}

void UnitRecordWriter::WriteFile(const std::string& name, std::string_view bytes) const {
  const fs::path path = staging_ / name;
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  if (ec) throw model::InputError(fmt::format("{}: cannot create directory: {}", path.parent_path().string(), ec.message()));
  model::WriteFileAtomic(path.string(), bytes);
}

void UnitRecordWriter::Commit(json body) {
  body["format"] = kUnitRecordFormat;
  body["format_version"] = kUnitRecordFormatVersion;
  body["tool_version"] = kVersion;
  body["files"] = FileDigests(staging_);
  CheckFinite(body, "");
  model::WriteFileAtomic((staging_ / "unit.json").string(), body.dump(2) + "\n");
  CommitDirectory(staging_, out_);
  committed_ = true;
}

}  // namespace topocal::report
