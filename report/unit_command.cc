#include "report/unit_command.h"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <utility>

#include "report/unit_record_writer.h"
#include "util/file_glob.h"
#include "util/shard.h"
#include "util/new_directory_guard.h"

namespace topocal::report {
namespace {

// The bundled design and nominal device, the defaults of config and device; the record names them "bundled:<file>",
// not the tree they lie in.
void FillDefaults(pipeline::UnitRequest* r, const BundledDataDir& data_dir) {
  for (auto [path, name] : {std::pair{&r->config, "paper.json"}, std::pair{&r->device, "device.json"}}) {
    if (!path->empty()) continue;
    *path = data_dir() + "/" + name;
    r->input_names[*path] = std::string("bundled:") + name;
  }
}

}  // namespace

void RunUnitCalibrate(const UnitCalibrateRequest& a, std::ostream& out) {
  const util::NewDirectoryGuard out_guard(a.unit.out);  // a failed unit leaves no empty units/ behind
  pipeline::UnitRequest request = a.unit;
  FillDefaults(&request, a.bundled_data_dir);
  request.images = util::Glob(a.images);
  const auto computed = pipeline::CalibrateUnit(request, [&a](const std::string& line) { util::Log(a.log, line); });
  WriteUnitRecord(computed);
  for (const auto& line : pipeline::UnitSummary(computed)) fmt::print(out, "{}\n", line);
}

void RunUnitCalibrateBatch(const UnitBatchRequest& a, std::ostream& out) {
  const util::NewDirectoryGuard out_guard(a.batch.out);
  pipeline::UnitBatchOptions options = a.batch;
  FillDefaults(&options.defaults, a.bundled_data_dir);
  pipeline::UnitBatchCallbacks callbacks = a.progress;
  callbacks.write_record = [](const pipeline::UnitResult& unit) { WriteUnitRecord(unit); };
  const pipeline::UnitBatchResult result = pipeline::RunUnitBatch(options, callbacks);
  if (result.items.empty()) {
    const util::ShardSpec spec = util::ParseShardSpec(options.shard);
    fmt::print(out, "shard {}/{}: no unit (fewer units than shards)\n", spec.index, spec.count);
    return;
  }
  for (const auto& item : result.items) {
    for (const auto& line : item.summary) fmt::print(out, "{}\n", line);
  }
  fmt::print(out, "{} unit(s): {} calibrated, {} failed\n", result.items.size(), result.items.size() - result.failed,
             result.failed);
  for (const auto& item : result.items) {
    if (!item.error.empty()) fmt::print(out, "  FAILED {}: {}\n", item.inputs_path, item.error);
  }
  pipeline::ThrowIfUnitsFailed(result);
}

}  // namespace topocal::report
