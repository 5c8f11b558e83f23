#pragma once
// `topocal unit calibrate-batch`: every unit of a directory (DIR/<unit>/unit-inputs.json) calibrated in parallel,
// one unit per core, optionally one shard i/N of them (docs/scale-out.md). A unit that fails is counted and reported
// with its reason; the others go on. The record is written by the caller's `write_record` (report::WriteUnitRecord:
// report/ links pipeline, never the other way).
#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/unit_workflow.h"

namespace topocal::pipeline {

inline constexpr const char* kUnitInputsFile = "unit-inputs.json";

struct UnitBatchOptions {
  std::string dir;    // holds the unit directories
  std::string out;    // records go to OUT/<serial>/
  std::string shard;  // "i/N" or empty = every unit
  int jobs = 1;       // units at once; the cores left over go to each unit's Monte Carlo draws
  UnitRequest defaults;
};

struct UnitBatchItem {
  std::string inputs_path;
  std::optional<UnitRequest> request;
  std::string error;       // set when the unit failed
  bool bad_input = false;  // the failure was bad input (exit 2 when every failure is)
  std::vector<std::string> summary;
};

struct UnitBatchCallbacks {
  std::function<void(const UnitResult&)> write_record;  // required
  // Called once per unit when it is done (failed or calibrated), one call at a time, with the counts so far.
  std::function<void(const UnitBatchItem&, size_t finished, size_t failed, size_t total)> on_done;
  // A warning line of one unit's workflow (skipped images), one call at a time.
  std::function<void(const std::string&)> on_log;
  // Called once, before the first unit is calibrated, after the units whose inputs failed were reported.
  std::function<void(size_t finished, size_t total)> on_start;
};

struct UnitBatchResult {
  std::vector<UnitBatchItem> items;  // sorted by inputs path; empty for a shard with no unit
  size_t failed = 0;
};

// Runs the batch. Throws util::InputError when DIR is not a directory of units or the shard is malformed; a unit's
// failure is recorded in its item, not thrown.
UnitBatchResult RunUnitBatch(const UnitBatchOptions& options, const UnitBatchCallbacks& callbacks);

// Throws when units failed: util::InputError "(bad input)" when every failure was bad input (exit 2), else
// std::runtime_error (exit 1); `what` is "calibrate-batch: F of N unit(s) failed".
void ThrowIfUnitsFailed(const UnitBatchResult& result);

}  // namespace topocal::pipeline
