#include "pipeline/unit_batch.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <mutex>
#include <opencv2/core/utility.hpp>
#include <stdexcept>

#include "util/io.h"
#include "util/parallel.h"
#include "util/shard.h"

namespace topocal::pipeline {
namespace {

namespace fs = std::filesystem;

std::vector<UnitBatchItem> ListUnits(const UnitBatchOptions& o) {
  if (!fs::is_directory(o.dir)) throw util::InputError(fmt::format("{}: not a directory", o.dir));
  std::vector<UnitBatchItem> items;
  for (const auto& e : fs::directory_iterator(o.dir)) {
    if (e.is_directory() && fs::exists(e.path() / kUnitInputsFile)) {
      items.push_back({(e.path() / kUnitInputsFile).string(), std::nullopt, {}, false, {}});
    }
  }
  if (items.empty()) {
    throw util::InputError(fmt::format("{}: no unit directory (none has a {})", o.dir, kUnitInputsFile));
  }
  std::sort(items.begin(), items.end(), [](const auto& x, const auto& y) { return x.inputs_path < y.inputs_path; });
  // Shard i of N: the units whose place in the sorted list is i modulo N. Each unit's record depends only on its
  // own inputs, so the shards' OUT/<serial>/ folders together are the unsharded run's (docs/scale-out.md).
  if (!o.shard.empty()) {
    const util::ShardSpec spec = util::ParseShardSpec(o.shard);
    std::vector<UnitBatchItem> mine;
    for (size_t i = 0; i < items.size(); ++i) {
      if (static_cast<int>(i % static_cast<size_t>(spec.count)) == spec.index) mine.push_back(std::move(items[i]));
    }
    items = std::move(mine);
  }
  return items;
}

void RecordFailure(UnitBatchItem* item, const std::exception& e, bool bad_input) {
  item->error = e.what();
  item->bad_input = bad_input;
}

}  // namespace

UnitBatchResult RunUnitBatch(const UnitBatchOptions& o, const UnitBatchCallbacks& cb) {
  UnitBatchResult result;
  result.items = ListUnits(o);
  auto& items = result.items;
  if (items.empty()) return result;

  // Read every unit's inputs first: a bad one fails that unit only; two units with one serial both fail.
  std::map<std::string, size_t> first_with_serial;
  for (size_t i = 0; i < items.size(); ++i) {
    auto& item = items[i];
    try {
      item.request = ReadUnitInputs(item.inputs_path, o.defaults);
      item.request->out = (fs::path(o.out) / item.request->serial).string();
      const auto [it, inserted] = first_with_serial.emplace(item.request->serial, i);
      if (!inserted) {
        item.error = fmt::format("serial {} is also used by {}", item.request->serial, items[it->second].inputs_path);
        item.bad_input = true;
      }
    } catch (const util::InputError& e) {
      RecordFailure(&item, e, true);
    } catch (const std::exception& e) {
      RecordFailure(&item, e, false);
    }
  }

  const unsigned jobs = static_cast<unsigned>(std::max(1, o.jobs));
  // Parallel across units, one core each: OpenCV's own thread pool would only compete with the workers.
  if (jobs > 1) cv::setNumThreads(1);
  // The cores the concurrent units leave over go to each unit's Monte Carlo draws (same record either way).
  const int draw_jobs =
      static_cast<int>(std::max<size_t>(1, jobs / std::max<size_t>(1, std::min<size_t>(jobs, items.size()))));
  for (auto& item : items) {
    if (item.request) item.request->jobs = draw_jobs;
  }
  std::mutex mutex;
  size_t finished = 0;
  const auto done = [&](const UnitBatchItem& item) {  // under the mutex
    ++finished;
    if (!item.error.empty()) ++result.failed;
    if (cb.on_done) cb.on_done(item, finished, result.failed, items.size());
  };
  {
    std::lock_guard lock(mutex);
    for (auto& item : items) {
      if (!item.error.empty()) done(item);
    }
    if (cb.on_start) cb.on_start(finished, items.size());
  }
  util::ParallelFor(items.size(), static_cast<int>(jobs), [&](size_t i) {
    auto& item = items[i];
    if (!item.error.empty()) return;
    try {
      const auto computed = CalibrateUnit(*item.request, [&](const std::string& line) {
        std::lock_guard lock(mutex);
        if (cb.on_log) cb.on_log(line);
      });
      cb.write_record(computed);
      item.summary = UnitSummary(computed);
    } catch (const util::InputError& e) {
      RecordFailure(&item, e, true);
    } catch (const std::exception& e) {
      RecordFailure(&item, e, false);
    }
    std::lock_guard lock(mutex);
    done(item);
  });
  return result;
}

void ThrowIfUnitsFailed(const UnitBatchResult& result) {
  if (result.failed == 0) return;
  const auto& items = result.items;
  const std::string what = fmt::format("calibrate-batch: {} of {} unit(s) failed", result.failed, items.size());
  // Exit 2 when every failure was bad input (the operator fixes the inputs), 1 when a computation failed.
  if (std::all_of(items.begin(), items.end(), [](const UnitBatchItem& i) { return i.error.empty() || i.bad_input; })) {
    throw util::InputError(what + " (bad input)");
  }
  throw std::runtime_error(what);
}

}  // namespace topocal::pipeline
