// topocal unit calibrate | calibrate-batch: the per-unit calibration workflow on the production line
// (pipeline/unit_workflow.h computes, report/unit_record_writer.h writes; docs/unit-record.md).
#include <algorithm>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <glog/logging.h>
#include <opencv2/core/utility.hpp>

#include "model/config.h"
#include "model/file_glob.h"
#include "model/io.h"
#include "model/parallel.h"
#include "pipeline/harness.h"
#include "pipeline/unit_workflow.h"
#include "report/unit_record_writer.h"
#include "tools/commands.h"
#include "tools/data_dir.h"
#include "tools/output_dir.h"
#include "tools/progress.h"

namespace topocal::tools {
namespace {

namespace fs = std::filesystem;
using pipeline::UnitRequest;

// The bundled design and camera (tools/data_dir.h), the defaults of --config and --camera, filled in when the
// command runs (so that other verbs never depend on finding the data).
void FillDefaults(UnitRequest* r) {
  if (r->config.empty()) r->config = DataDir() + "/paper.json";
  if (r->camera.empty()) r->camera = DataDir() + "/camera.json";
}
constexpr const char* kUnitInputsFile = "unit-inputs.json";
constexpr int kProgressBarWidth = 30;

void QuietCeres() {
  // Ceres logs through glog (e.g. a rank-deficient covariance); the workflow reports failures in one line.
  FLAGS_minloglevel = google::GLOG_FATAL;
}

void AddCommonOptions(CLI::App* cmd, UnitRequest* r) {
  cmd->add_option("--config", r->config, "Topographer design (JSON) [bundled data/paper.json]");
  cmd->add_option("--camera", r->camera, "Topographer camera (JSON) [bundled data/camera.json]");
  cmd->add_option("--model", r->model, "Distortion model: seidel or brown5")->check(CLI::IsMember({"seidel", "brown5"}));
  cmd->add_flag("--fit-centre", r->fit_centre, "Fit the distortion centre (seidel)");
  cmd->add_option("--fix", r->fixed, "Hold these parameters at their initial value (e.g. --fix k3 p1 p2)");
  cmd->add_option("--fix-aspect", r->fixed_aspect_ratio,
                  "Hold fx / fy at this ratio in a multi-view fit (e.g. 1 for square pixels; 0 = free)")
      ->capture_default_str();
  cmd->add_option("--uncertainty", r->uncertainty_samples,
                  "Monte Carlo draws of the calibration covariance carried to the clinical numbers (0 = none)")
      ->check(CLI::Range(0, pipeline::kMaxUncertaintySamples));
  cmd->add_option("--seed", r->seed, "Seed of the Monte Carlo draws");
}

struct BatchArgs {
  std::string dir, out, shard;
  int jobs = model::AvailableCores();
  UnitRequest defaults;
};

struct BatchItem {
  std::string inputs_path;
  std::optional<UnitRequest> request;
  std::string error;  // set when the unit failed
  bool bad_input = false;  // the failure was bad input (exit 2 when every failure is)
  std::vector<std::string> summary;
  bool done = false;
};

void RunBatch(const BatchArgs& a) {
  QuietCeres();
  if (!fs::is_directory(a.dir)) throw model::InputError(fmt::format("{}: not a directory", a.dir));
  std::vector<BatchItem> items;
  for (const auto& e : fs::directory_iterator(a.dir)) {
    if (e.is_directory() && fs::exists(e.path() / kUnitInputsFile)) {
      items.push_back({(e.path() / kUnitInputsFile).string(), std::nullopt, {}, false, {}, false});
    }
  }
  if (items.empty()) {
    throw model::InputError(fmt::format("{}: no unit directory (none has a {})", a.dir, kUnitInputsFile));
  }
  std::sort(items.begin(), items.end(), [](const auto& x, const auto& y) { return x.inputs_path < y.inputs_path; });
  // Shard i of N: the units whose place in the sorted list is i modulo N. Each unit's record depends only on its
  // own inputs, so the shards' OUT/<serial>/ folders together are the unsharded run's (docs/scale-out.md).
  if (!a.shard.empty()) {
    const pipeline::ShardSpec spec = pipeline::ParseShardSpec(a.shard);
    std::vector<BatchItem> mine;
    for (size_t i = 0; i < items.size(); ++i) {
      if (static_cast<int>(i % static_cast<size_t>(spec.count)) == spec.index) mine.push_back(std::move(items[i]));
    }
    items = std::move(mine);
    if (items.empty()) {
      fmt::print("shard {}/{}: no unit (fewer units than shards)\n", spec.index, spec.count);
      return;
    }
  }

  // Read every unit's inputs first: a bad one fails that unit only; two units with one serial both fail.
  std::map<std::string, size_t> first_with_serial;
  for (size_t i = 0; i < items.size(); ++i) {
    auto& item = items[i];
    try {
      item.request = pipeline::ReadUnitInputs(item.inputs_path, a.defaults);
      item.request->out = (fs::path(a.out) / item.request->serial).string();
      const auto [it, inserted] = first_with_serial.emplace(item.request->serial, i);
      if (!inserted) {
        item.error = fmt::format("serial {} is also used by {}", item.request->serial, items[it->second].inputs_path);
        item.bad_input = true;
      }
    } catch (const model::InputError& e) {
      item.error = e.what();
      item.bad_input = true;
    } catch (const std::exception& e) {
      item.error = e.what();
    }
  }

  const unsigned jobs = static_cast<unsigned>(std::max(1, a.jobs));
  // Parallel across units, one core each: OpenCV's own thread pool would only compete with the workers.
  if (jobs > 1) cv::setNumThreads(1);
  // The cores the concurrent units leave over go to each unit's Monte Carlo draws (same record either way).
  const int draw_jobs = static_cast<int>(std::max<size_t>(1, jobs / std::max<size_t>(1, std::min<size_t>(jobs, items.size()))));
  for (auto& item : items) {
    if (item.request) item.request->jobs = draw_jobs;
  }
  const bool tty = ProgressEnabled();  // a redrawn bar on a terminal; one line per unit in logs or with --quiet
  std::mutex mutex;
  size_t finished = 0, failed = 0;
  const auto draw_bar = [&](const std::string& last) {  // under the mutex
    const int filled = static_cast<int>(kProgressBarWidth * finished / items.size());
    fmt::print(stderr, "\r[{}{}] {}/{} units, {} failed  {:<24.24}", std::string(static_cast<size_t>(filled), '#'),
               std::string(static_cast<size_t>(kProgressBarWidth - filled), '.'), finished, items.size(), failed, last);
    if (finished == items.size()) fmt::print(stderr, "\n");
  };
  const auto report = [&](const BatchItem& item) {  // under the mutex
    ++finished;
    if (!item.error.empty()) ++failed;
    const std::string name = item.request ? item.request->serial : item.inputs_path;
    if (tty) {
      draw_bar(name);
    } else {
      fmt::print(stderr, "[{}/{}] {}: {}\n", finished, items.size(), name,
                 item.error.empty() ? std::string("ok") : "FAILED: " + item.error);
    }
  };
  {
    std::lock_guard lock(mutex);
    for (auto& item : items) {
      if (!item.error.empty()) report(item);
    }
    if (tty && finished == 0) draw_bar("");  // the empty bar at once: a unit takes seconds
  }
  model::ParallelFor(items.size(), static_cast<int>(jobs), [&](size_t i) {
    auto& item = items[i];
    if (!item.error.empty()) return;
    try {
      const auto computed = pipeline::CalibrateUnit(*item.request, [&](const std::string& line) {
        std::lock_guard lock(mutex);
        if (tty) fmt::print(stderr, "\n");
        fmt::print(stderr, "topocal unit: {}\n", line);
      });
      report::WriteUnitRecord(computed);
      item.summary = pipeline::UnitSummary(computed);
    } catch (const model::InputError& e) {
      item.error = e.what();
      item.bad_input = true;
    } catch (const std::exception& e) {
      item.error = e.what();
    }
    std::lock_guard lock(mutex);
    report(item);
  });

  for (const auto& item : items) {
    for (const auto& line : item.summary) fmt::print("{}\n", line);
  }
  fmt::print("{} unit(s): {} calibrated, {} failed\n", items.size(), items.size() - failed, failed);
  for (const auto& item : items) {
    if (!item.error.empty()) fmt::print("  FAILED {}: {}\n", item.inputs_path, item.error);
  }
  if (failed > 0) {
    const std::string what = fmt::format("calibrate-batch: {} of {} unit(s) failed", failed, items.size());
    // Exit 2 when every failure was bad input (the operator fixes the inputs), 1 when a computation failed.
    if (std::all_of(items.begin(), items.end(), [](const BatchItem& i) { return i.error.empty() || i.bad_input; })) {
      throw model::InputError(what + " (bad input)");
    }
    throw std::runtime_error(what);
  }
}

}  // namespace

void AddUnitCommand(CLI::App& app) {
  auto* unit = app.add_subcommand("unit", "Per-unit calibration records for the production line");
  unit->require_subcommand(1);

  auto* cal = unit->add_subcommand("calibrate",
                                   "Calibrate one unit, verify it on a reference sphere, write its unit record");
  auto r = std::make_shared<UnitRequest>();
  auto images = std::make_shared<std::string>();
  cal->add_option("--serial", r->serial, "Unit serial number (A-Z a-z 0-9 . _ -)")->required();
  cal->add_option("--target", r->target, "Target description (Kalibr-style YAML)")->required();
  cal->add_option("--images", *images, "Target images, a glob(3) pattern (quote it); one image = single view")->required();
  cal->add_option("--reference-sphere", r->reference_sphere, "Raw spot image of the reference sphere");
  cal->add_option("--sphere-radius-mm", r->sphere_radius_mm, "Radius of the reference sphere, mm");
  cal->add_option("--balls", r->balls,
                  "Reference-ball images for the device stage (screen pose, principal point, a, distortion; "
                  "docs/device.md); the reference sphere is then a held-out ball");
  cal->add_option("--radii-mm", r->ball_radii_mm, "Certified radius of each ball, in the order of --balls, mm");
  cal->add_option("--device", r->device, "Nominal device (JSON) the device stage starts from [the camera, nominal]");
  cal->add_option("--out", r->out, "Unit record directory (e.g. units/SN/)")->required();
  AddCommonOptions(cal, r.get());
  cal->callback([r, images] {
    const NewDirectoryGuard out_guard(r->out);  // a failed unit leaves no empty units/ behind
    QuietCeres();
    UnitRequest request = *r;
    FillDefaults(&request);
    request.images = model::Glob(*images);
    Progress progress("topocal unit calibrate: " + request.serial);
    const auto computed = pipeline::CalibrateUnit(
        request, [&progress](const std::string& line) { progress.Line("topocal unit: " + line); });
    report::WriteUnitRecord(computed);
    for (const auto& line : pipeline::UnitSummary(computed)) fmt::print("{}\n", line);
  });

  auto* batch = unit->add_subcommand(
      "calibrate-batch", "Calibrate every unit of a directory (DIR/<unit>/unit-inputs.json), in parallel");
  auto b = std::make_shared<BatchArgs>();
  batch->add_option("dir", b->dir, "Directory of unit directories")->required();
  batch->add_option("--out", b->out, "Where the unit records go: OUT/<serial>/")->required();
  batch->add_option("--jobs", b->jobs, "Units calibrated at once [the cores available]")->check(CLI::Range(1, 256));
  batch->add_option("--shard", b->shard, "Only shard i/N of the units (sorted by folder, index % N == i), e.g. "
                                         "from a Slurm array or a Kubernetes Indexed Job (docs/scale-out.md)");
  AddCommonOptions(batch, &b->defaults);
  batch->callback([b] {
    const NewDirectoryGuard out_guard(b->out);
    FillDefaults(&b->defaults);
    RunBatch(*b);
  });
}

}  // namespace topocal::tools
