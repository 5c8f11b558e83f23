#include "pipeline/design_command.h"

#include <fmt/format.h>
#include <fmt/ostream.h>

#include <filesystem>
#include <stdexcept>

#include "model/config.h"
#include "model/null_screen.h"
#include "model/null_screen_layout.h"
#include "pipeline/screen_design.h"
#include "plot/null_screen_svg.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

// The printable screen; the spots its layout could not place beyond the design's own failures are logged.
std::string ScreenSvg(const model::Config& cfg, const model::NullScreenDesign& design, const DesignRequest& a,
                      const std::string& title) {
  const auto layout = model::LayoutNullScreen(cfg.ideal_image, cfg.topographer);
  for (size_t k = design.failures.size(); k < layout.failures.size(); ++k) {
    const auto& f = layout.failures[k];
    util::Log(a.log, fmt::format("spot ({}, {}): {}", f.id.ring, f.id.index, f.reason));
  }
  if (layout.overlapping_pairs > 0) {
    util::Log(a.log, fmt::format("warning: {} pairs of spot circles overlap (ideal_image.spot_radius_um = {}); their "
                                 "ellipses merge on the sheet",
                                 layout.overlapping_pairs, cfg.ideal_image.spot_radius_um));
  }
  return plot::NullScreenSvg(layout, {.title = title});
}

// The designed targets (CSV, and the printable screen with svg; with optimize, the configuration too), published
// together or not at all.
void WriteDesign(const model::Config& cfg, const DesignRequest& a, const std::string& title, std::ostream& out) {
  const auto design = model::DesignNullScreen(cfg.ideal_image, cfg.topographer);
  for (const auto& f : design.failures) {
    util::Log(a.log, fmt::format("spot ({}, {}): {}", f.id.ring, f.id.index, f.reason));
  }
  if (design.targets.empty()) throw std::runtime_error(fmt::format("{}: no target point could be designed", a.config));
  // The points to print: the orientation key's gaps are left out, as in the SVG (a screen built from a CSV that
  // listed them would be silently unkeyed).
  std::string csv = "ring,index,x_mm,y_mm,z_mm\n";
  int printed = 0;
  for (const auto& t : design.targets) {
    if (model::IsOrientationKeySpot(cfg.ideal_image, t.id)) continue;
    csv += fmt::format("{},{},{},{},{}\n", t.id.ring, t.id.index, t.on_cone_mm.x(), t.on_cone_mm.y(), t.on_cone_mm.z());
    ++printed;
  }
  const std::string svg_text = a.svg.empty() ? std::string() : ScreenSvg(cfg, design, a, title);
  util::StagedOutputs outputs;
  outputs.AddFile(a.out, csv);
  if (!a.svg.empty()) outputs.AddFile(a.svg, svg_text);
  if (!a.config_out.empty()) outputs.AddFile(a.config_out, model::ConfigToJson(cfg) + "\n");
  outputs.Commit();
  const int key = static_cast<int>(design.targets.size()) - printed;
  fmt::print(out, "designed {} target points ({} failed{}) -> {}\n", printed, design.failures.size(),
             key > 0 ? fmt::format(", {} left out as the orientation key", key) : "", a.out);
  if (!a.svg.empty()) fmt::print(out, "printable null screen (unrolled cone, 1:1, print at 100 %) -> {}\n", a.svg);
  if (!a.config_out.empty()) fmt::print(out, "configuration of the chosen design -> {}\n", a.config_out);
}

// The trade-off table to `out`, the chosen design's configuration; a goal no candidate meets is refused
// (ConfigError naming the goal's key) before anything is written.
model::Config Optimize(const model::Config& base, const DesignRequest& a, std::ostream& out) {
  const auto goal = a.goal.empty() ? ScreenDesignGoal{} : LoadScreenDesignGoal(a.goal);
  if (a.jobs < 1) throw util::InputError(fmt::format("--jobs: must be >= 1 (got {})", a.jobs));
  ScreenDesignResult result;
  {
    const auto progress = util::StartProgress(a.progress, "corneas x candidates");
    ScreenDesignOptions options{a.jobs, {}};
    if (progress) options.progress = [&progress](size_t done, size_t total) { progress->Update(done, total); };
    result = OptimizeScreenDesign(base, goal, options);
  }
  fmt::print(out, "{}", ScreenDesignTable(result, goal));
  if (!result.chosen) {
    throw util::ConfigError(fmt::format("{}: {}", a.goal.empty() ? "(default goal)" : a.goal, result.why));
  }
  return result.config;
}

}  // namespace

void RunDesign(const DesignRequest& a, std::ostream& out) {
  auto cfg = model::LoadConfig(a.config);
  std::string title = std::filesystem::path(a.config).stem().string();
  if (a.optimize) {
    if (a.config_out.empty()) throw util::InputError("--optimize: needs --config-out (the chosen design's configuration)");
    cfg = Optimize(cfg, a, out);
    title = std::filesystem::path(a.config_out).stem().string();
  }
  WriteDesign(cfg, a, title, out);
}

}  // namespace topocal::pipeline
