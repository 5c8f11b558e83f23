#include <fmt/format.h>

#include <filesystem>

#include "model/config.h"
#include "model/null_screen.h"
#include "model/null_screen_layout.h"
#include "pipeline/screen_design.h"
#include "plot/null_screen_svg.h"
#include "tools/commands.h"
#include "tools/progress.h"
#include "util/io.h"
#include "util/parallel.h"

namespace topocal::tools {
namespace {

struct DesignArgs {
  std::string config, out, svg;
  bool optimize = false;
  std::string goal, config_out;
  int jobs = util::AvailableCores();
};

// The designed targets (CSV, and the printable screen with --svg; with --optimize, the configuration too), published
// together or not at all.
void WriteDesign(const model::Config& cfg, const DesignArgs& a, const std::string& title) {
  const auto design = model::DesignNullScreen(cfg.ideal_image, cfg.topographer);
  for (const auto& f : design.failures) {
    fmt::print(stderr, "topocal design: spot ({}, {}): {}\n", f.id.ring, f.id.index, f.reason);
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
  std::string svg_text;
  if (!a.svg.empty()) {
    const auto layout = model::LayoutNullScreen(cfg.ideal_image, cfg.topographer);
    for (size_t k = design.failures.size(); k < layout.failures.size(); ++k) {
      const auto& f = layout.failures[k];
      fmt::print(stderr, "topocal design: spot ({}, {}): {}\n", f.id.ring, f.id.index, f.reason);
    }
    if (layout.overlapping_pairs > 0) {
      fmt::print(stderr, "topocal design: warning: {} pairs of spot circles overlap (ideal_image.spot_radius_um = {}); "
                 "their ellipses merge on the sheet\n", layout.overlapping_pairs, cfg.ideal_image.spot_radius_um);
    }
    svg_text = plot::NullScreenSvg(layout, {.title = title});
  }
  util::StagedOutputs outputs;
  outputs.AddFile(a.out, csv);
  if (!a.svg.empty()) outputs.AddFile(a.svg, svg_text);
  if (!a.config_out.empty()) outputs.AddFile(a.config_out, model::ConfigToJson(cfg) + "\n");
  outputs.Commit();
  const int key = static_cast<int>(design.targets.size()) - printed;
  fmt::print("designed {} target points ({} failed{}) -> {}\n", printed, design.failures.size(),
             key > 0 ? fmt::format(", {} left out as the orientation key", key) : "", a.out);
  if (!a.svg.empty()) fmt::print("printable null screen (unrolled cone, 1:1, print at 100 %) -> {}\n", a.svg);
  if (!a.config_out.empty()) fmt::print("configuration of the chosen design -> {}\n", a.config_out);
}

// --optimize: the trade-off table on stdout, the chosen design's configuration; a goal no candidate meets is refused
// (ConfigError naming the goal's key) before anything is written.
model::Config Optimize(const model::Config& base, const DesignArgs& a) {
  const auto goal = a.goal.empty() ? pipeline::ScreenDesignGoal{} : pipeline::LoadScreenDesignGoal(a.goal);
  if (a.jobs < 1) throw util::InputError(fmt::format("--jobs: must be >= 1 (got {})", a.jobs));
  pipeline::ScreenDesignResult result;
  {
    Progress progress("topocal design --optimize: corneas x candidates");
    result = pipeline::OptimizeScreenDesign(
        base, goal, {a.jobs, [&progress](std::size_t done, std::size_t total) { progress.Update(done, total); }});
  }
  fmt::print("{}", pipeline::ScreenDesignTable(result, goal));
  if (!result.chosen) {
    throw util::ConfigError(fmt::format("{}: {}", a.goal.empty() ? "(default goal)" : a.goal, result.why));
  }
  return result.config;
}

}  // namespace

void AddDesignCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("design", "Design the null screen: target points on the cone for the ideal image");
  auto a = std::make_shared<DesignArgs>();
  cmd->add_option("--config", a->config, "Topographer configuration (JSON)")->required();
  cmd->add_option("--out", a->out, "Target points CSV: ring,index,x_mm,y_mm,z_mm")->required();
  cmd->add_option("--svg", a->svg, "Also write the printable null screen (unrolled cone, 1:1) as SVG");
  auto* optimize = cmd->add_flag("--optimize", a->optimize,
                                 "Choose the rings and spots per ring for a goal (docs/screen-design.md): trade-off "
                                 "table on stdout, the chosen design written");
  cmd->add_option("--goal", a->goal, "Goal of --optimize (JSON; default: the defaults of docs/screen-design.md)")
      ->needs(optimize);
  cmd->add_option("--config-out", a->config_out, "Configuration of the chosen design (JSON), for every other verb")
      ->needs(optimize);
  cmd->add_option("--jobs", a->jobs, "Threads of --optimize (the result does not depend on it)")
      ->capture_default_str()
      ->needs(optimize);
  cmd->callback([a] {
    auto cfg = model::LoadConfig(a->config);
    std::string title = std::filesystem::path(a->config).stem().string();
    if (a->optimize) {
      if (a->config_out.empty()) throw util::InputError("--optimize: needs --config-out (the chosen design's configuration)");
      cfg = Optimize(cfg, *a);
      title = std::filesystem::path(a->config_out).stem().string();
    }
    WriteDesign(cfg, *a, title);
  });
}

}  // namespace topocal::tools
