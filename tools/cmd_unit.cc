// topocal unit calibrate | calibrate-batch: the per-unit calibration workflow on the production line
// (report/unit_command.h; docs/unit-record.md).
#include <fmt/format.h>

#include <memory>
#include <string>

#include "calib/calibrate.h"
#include "report/unit_command.h"
#include "tools/commands.h"
#include "tools/data_dir.h"
#include "util/terminal_progress.h"

namespace topocal::tools {
namespace {

using pipeline::UnitRequest;

constexpr int kProgressBarWidth = 30;

void AddCommonOptions(CLI::App* cmd, UnitRequest* r) {
  cmd->add_option("--config", r->config, "Topographer design (JSON) [bundled data/paper.json]");
  cmd->add_option("--device", r->device,
                  "The unit's nominal device (JSON, docs/device.md): its camera, and where the device stage "
                  "starts [bundled data/device.json]");
  cmd->add_option("--model", r->model,
                  fmt::format("Distortion model, one of {} (as calibrate)", calib::DistortionModelNames()))
      ->capture_default_str();
  cmd->add_flag("--fit-centre", r->fit_centre, "Fit the distortion centre (seidel)");
  cmd->add_option("--fix", r->fixed, "Hold these parameters at their initial value (e.g. --fix k3 p1 p2)");
  cmd->add_option("--fix-aspect", r->fixed_aspect_ratio,
                  "Hold fx / fy at this ratio in a multi-view fit (e.g. 1 for square pixels; 0 = free)")
      ->capture_default_str();
  cmd->add_option_function<std::string>(
         "--uncertainty",
         [r](const std::string& text) { r->uncertainty = pipeline::UncertaintySetting::Parse(text, "--uncertainty"); },
         fmt::format("How the calibration covariance reaches the clinical numbers: linear (propagation, the default), "
                     "none (or 0), or N seeded Monte Carlo draws (2 to {}, a cross-check)",
                     pipeline::kMaxUncertaintySamples))
      ->check([](const std::string& text) {
        try {
          (void)pipeline::UncertaintySetting::Parse(text, "--uncertainty");
          return std::string();
        } catch (const std::exception& e) {
          return std::string(e.what());
        }
      });
  cmd->add_option("--seed", r->seed, "Seed of the Monte Carlo draws (--uncertainty N)");
  cmd->add_flag("--allow-undetermined", r->allow_undetermined,
                "Record a calibration whose views leave a parameter undetermined (listed in the record) instead of "
                "refusing it");
  cmd->add_flag("--map-csv", r->map_csv,
                "Also store each map's CSV grid beside its PNG in maps/ (~3 MB a map; without it a record is a few "
                "MB)");
  cmd->add_flag("--force", r->keep_history,
                "Replace a unit's existing record; the old one is kept under <units>/.history/<serial>/<its date>/");
}

// The batch's progress on stderr: a redrawn bar on a terminal; one line per unit in logs or with --quiet.
pipeline::UnitBatchCallbacks BatchProgress() {
  const bool tty = util::ProgressEnabled();
  const auto draw_bar = [](size_t finished, size_t failed, size_t total, const std::string& last) {
    const int filled = static_cast<int>(kProgressBarWidth * finished / total);
    fmt::print(stderr, "\r[{}{}] {}/{} units, {} failed  {:<24.24}", std::string(static_cast<size_t>(filled), '#'),
               std::string(static_cast<size_t>(kProgressBarWidth - filled), '.'), finished, total, failed, last);
    if (finished == total) fmt::print(stderr, "\n");
  };
  pipeline::UnitBatchCallbacks callbacks;
  callbacks.on_done = [=](const pipeline::UnitBatchItem& item, size_t finished, size_t failed, size_t total) {
    const std::string name = item.request ? item.request->serial : item.inputs_path;
    if (tty) {
      draw_bar(finished, failed, total, name);
    } else {
      fmt::print(stderr, "[{}/{}] {}: {}\n", finished, total, name,
                 item.error.empty() ? std::string("ok") : "FAILED: " + item.error);
    }
  };
  callbacks.on_start = [=](size_t finished, size_t total) {
    if (tty && finished == 0) draw_bar(0, 0, total, "");  // the empty bar at once: a unit takes seconds
  };
  callbacks.on_log = [=](const std::string& line) {
    if (tty) fmt::print(stderr, "\n");
    fmt::print(stderr, "topocal unit: {}\n", line);
  };
  return callbacks;
}

}  // namespace

void AddUnitCommand(CLI::App& app) {
  auto* unit = app.add_subcommand("unit", "Per-unit calibration records for the production line");
  unit->require_subcommand(1);

  auto* cal = unit->add_subcommand("calibrate",
                                   "Calibrate one unit, verify it on a reference sphere, write its unit record");
  auto c = std::make_shared<report::UnitCalibrateRequest>();
  UnitRequest* r = &c->unit;
  cal->add_option("--serial", r->serial, "Unit serial number (A-Z a-z 0-9 . _ -)")->required();
  cal->add_option("--target", r->target, "Target description (Kalibr-style YAML)")->required();
  cal->add_option("--images", c->images, "Target images, a glob(3) pattern (quote it); one image = single view")->required();
  cal->add_option("--reference-sphere", r->reference_sphere, "Raw spot image of the reference sphere");
  cal->add_option("--sphere-radius-mm", r->sphere_radius_mm, "Radius of the reference sphere, mm");
  cal->add_option("--sphere-repeats", r->sphere_repeats,
                  "Further images of the reference sphere, re-seated between captures: the repeatability the QA "
                  "report's budget uses");
  cal->add_option("--balls", r->balls,
                  "Reference-ball images for the device stage (screen pose, principal point, a, distortion; "
                  "docs/device.md); the reference sphere is then a held-out ball");
  cal->add_option("--radii-mm", r->ball_radii_mm, "Certified radius of each ball, in the order of --balls, mm");
  cal->add_option("--out", r->out, "Unit record directory (e.g. units/SN/)")->required();
  AddCommonOptions(cal, r);
  c->bundled_data_dir = DataDir;
  cal->callback([c] {
    util::Progress progress("topocal unit calibrate: " + c->unit.serial);
    report::UnitCalibrateRequest request = *c;
    request.log = [&progress](const std::string& line) { progress.Line("topocal unit: " + line); };
    report::RunUnitCalibrate(request, std::cout);
  });

  auto* batch = unit->add_subcommand(
      "calibrate-batch", "Calibrate every unit of a directory (DIR/<unit>/unit-inputs.json), in parallel");
  auto q = std::make_shared<report::UnitBatchRequest>();
  pipeline::UnitBatchOptions* b = &q->batch;
  batch->add_option("dir", b->dir, "Directory of unit directories")->required();
  batch->add_option("--out", b->out, "Where the unit records go: OUT/<serial>/")->required();
  batch->add_option("--jobs", b->jobs, "Units calibrated at once [the cores available]")->check(CLI::Range(1, 256));
  batch->add_option("--shard", b->shard, "Only shard i/N of the units (sorted by folder, index % N == i), e.g. "
                                         "from a Slurm array or a Kubernetes Indexed Job (docs/scale-out.md)");
  AddCommonOptions(batch, &b->defaults);
  q->bundled_data_dir = DataDir;
  batch->callback([q] {
    report::UnitBatchRequest request = *q;
    request.progress = BatchProgress();
    report::RunUnitCalibrateBatch(request, std::cout);
  });
}

}  // namespace topocal::tools
