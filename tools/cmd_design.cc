#include <fmt/format.h>

#include <filesystem>

#include "model/config.h"
#include "model/null_screen.h"
#include "model/null_screen_layout.h"
#include "plot/null_screen_svg.h"
#include "tools/commands.h"
#include "util/io.h"

namespace topocal::tools {

void AddDesignCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("design", "Design the null screen: target points on the cone for the ideal image");
  auto config = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto svg = std::make_shared<std::string>();
  cmd->add_option("--config", *config, "Topographer configuration (JSON)")->required();
  cmd->add_option("--out", *out, "Target points CSV: ring,index,x_mm,y_mm,z_mm")->required();
  cmd->add_option("--svg", *svg, "Also write the printable null screen (unrolled cone, 1:1) as SVG");
  cmd->callback([=] {
    const auto cfg = model::LoadConfig(*config);
    const auto design = model::DesignNullScreen(cfg.ideal_image, cfg.topographer);
    for (const auto& f : design.failures) {
      fmt::print(stderr, "topocal design: spot ({}, {}): {}\n", f.id.ring, f.id.index, f.reason);
    }
    if (design.targets.empty()) throw std::runtime_error(fmt::format("{}: no target point could be designed", *config));
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
    if (!svg->empty()) {
      const auto layout = model::LayoutNullScreen(cfg.ideal_image, cfg.topographer);
      for (size_t k = design.failures.size(); k < layout.failures.size(); ++k) {
        const auto& f = layout.failures[k];
        fmt::print(stderr, "topocal design: spot ({}, {}): {}\n", f.id.ring, f.id.index, f.reason);
      }
      if (layout.overlapping_pairs > 0) {
        fmt::print(stderr, "topocal design: warning: {} pairs of spot circles overlap (ideal_image.spot_radius_um = {}); "
                   "their ellipses merge on the sheet\n", layout.overlapping_pairs, cfg.ideal_image.spot_radius_um);
      }
      svg_text = plot::NullScreenSvg(layout, {.title = std::filesystem::path(*config).stem().string()});
    }
    util::StagedOutputs outputs;  // the CSV and the SVG are published together or not at all
    outputs.AddFile(*out, csv);
    if (!svg->empty()) outputs.AddFile(*svg, svg_text);
    outputs.Commit();
    const int key = static_cast<int>(design.targets.size()) - printed;
    fmt::print("designed {} target points ({} failed{}) -> {}\n", printed, design.failures.size(),
               key > 0 ? fmt::format(", {} left out as the orientation key", key) : "", *out);
    if (!svg->empty()) {
      fmt::print("printable null screen (unrolled cone, 1:1, print at 100 %) -> {}\n", *svg);
    }
  });
}

}  // namespace topocal::tools
