#pragma once
// `topocal unit calibrate` and `calibrate-batch` as library calls: the per-unit calibration workflow on the
// production line, computed by pipeline/unit_workflow.h and pipeline/unit_batch.h, each unit record written by
// report/unit_record_writer.h (docs/unit-record.md).
#include <functional>
#include <ostream>
#include <string>

#include "pipeline/unit_batch.h"
#include "pipeline/unit_workflow.h"
#include "util/parallel.h"
#include "util/progress_display.h"

namespace topocal::report {

// Where the bundled design and device lie (data/paper.json, data/device.json), asked only when the request leaves
// its config or device empty; throws util::InputError when there is none.
using BundledDataDir = std::function<std::string()>;

struct UnitCalibrateRequest {
  pipeline::UnitRequest unit;  // its images are filled from `images`
  std::string images;          // glob(3) pattern of the target images; one image = single view
  BundledDataDir bundled_data_dir;
  util::LogLine log;  // the workflow's warning lines (skipped images)
};

struct UnitBatchRequest {
  pipeline::UnitBatchOptions batch = [] {
    pipeline::UnitBatchOptions options;
    options.jobs = util::AvailableCores();  // units at once
    return options;
  }();
  BundledDataDir bundled_data_dir;
  // How the batch's progress is shown (on_done, on_start, on_log); write_record is the run's own.
  pipeline::UnitBatchCallbacks progress;
};

// Calibrates one unit, writes its record and prints its summary to `out`.
void RunUnitCalibrate(const UnitCalibrateRequest& request, std::ostream& out);

// Calibrates every unit of the batch's directory, writes their records and prints every unit's summary and the
// failures to `out`; throws (pipeline::ThrowIfUnitsFailed) when units failed.
void RunUnitCalibrateBatch(const UnitBatchRequest& request, std::ostream& out);

}  // namespace topocal::report
