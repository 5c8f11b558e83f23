// topocal compare: two measurements of one eye, their clinical numbers' changes with U and their change maps.
#include <fmt/format.h>

#include <memory>
#include <optional>
#include <string>

#include "pipeline/measurement_compare.h"
#include "tools/commands.h"
#include "tools/output_dir.h"
#include "util/io.h"
#include "util/json_section.h"

namespace topocal::tools {
namespace {

struct CompareArgs {
  std::string a, b, a_maps, b_maps, maps, json;
};

void Run(const CompareArgs& args) {
  if (args.a_maps.empty() != args.b_maps.empty()) throw util::InputError("--a-maps and --b-maps: give both or neither");
  if (!args.maps.empty() && args.a_maps.empty()) throw util::InputError("--maps: needs --a-maps and --b-maps");
  const auto comparison = pipeline::CompareMeasurements(util::ParseJsonStrict(util::ReadFile(args.a), args.a), args.a,
                                                        util::ParseJsonStrict(util::ReadFile(args.b), args.b), args.b);
  std::optional<pipeline::MapComparison> maps;
  if (!args.a_maps.empty()) maps = pipeline::CompareMapDirectories(args.a_maps, args.b_maps);
  util::StagedOutputs outputs;  // published together or not at all
  NewDirectoryGuard guard(args.maps);
  if (!args.maps.empty()) pipeline::WriteMapComparison(outputs.AddDirectory(args.maps), *maps, comparison.eye);
  if (!args.json.empty()) {
    const nlohmann::json j = pipeline::ComparisonJson(comparison, maps);
    outputs.AddFile(args.json, util::JsonFileText(j));
  }
  outputs.Commit();
  for (const auto& line : pipeline::ComparisonLines(comparison, maps)) fmt::print("{}\n", line);
  if (!args.maps.empty()) fmt::print("change maps -> {}\n", args.maps);
}

}  // namespace

void AddCompareCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("compare", "Compare two measurements of one eye: each clinical number's change "
                                            "with its U, and the change maps (docs/compare.md)");
  auto a = std::make_shared<CompareArgs>();
  cmd->add_option("a", a->a, "The earlier measurement (reconstruct --json)")->required();
  cmd->add_option("b", a->b, "The later measurement (reconstruct --json)")->required();
  cmd->add_option("--a-maps", a->a_maps, "The earlier measurement's --maps directory");
  cmd->add_option("--b-maps", a->b_maps, "The later measurement's --maps directory");
  cmd->add_option("--maps", a->maps, "Write the change maps (CSV and PNG) into this directory");
  cmd->add_option("--json", a->json, "Also write the comparison as JSON");
  cmd->callback([a] { Run(*a); });
}

}  // namespace topocal::tools
