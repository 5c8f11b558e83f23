#include "pipeline/compare_command.h"

#include <fmt/format.h>

#include <optional>

#include "pipeline/measurement_compare.h"
#include "util/io.h"
#include "util/json_section.h"
#include "util/new_directory_guard.h"

namespace topocal::pipeline {

void RunCompare(const CompareRequest& request, std::ostream& out) {
  const util::NewDirectoryGuard guard(request.maps_dir);  // a failed comparison leaves no empty --maps folder
  if (request.a_maps_dir.empty() != request.b_maps_dir.empty()) {
    throw util::InputError("--a-maps and --b-maps: give both or neither");
  }
  if (!request.maps_dir.empty() && request.a_maps_dir.empty()) {
    throw util::InputError("--maps: needs --a-maps and --b-maps");
  }
  const auto comparison =
      CompareMeasurements(util::ParseJsonStrict(util::ReadFile(request.a_path), request.a_path), request.a_path,
                          util::ParseJsonStrict(util::ReadFile(request.b_path), request.b_path), request.b_path);
  std::optional<MapComparison> maps;
  if (!request.a_maps_dir.empty()) maps = CompareMapDirectories(request.a_maps_dir, request.b_maps_dir);
  util::StagedOutputs outputs;  // published together or not at all
  if (!request.maps_dir.empty()) WriteMapComparison(outputs.AddDirectory(request.maps_dir), *maps, comparison.eye);
  if (!request.json_path.empty())
    outputs.AddFile(request.json_path, util::JsonFileText(ComparisonJson(comparison, maps)));
  outputs.Commit();
  for (const auto& line : ComparisonLines(comparison, maps)) out << line << "\n";
  if (!request.maps_dir.empty()) out << fmt::format("change maps -> {}\n", request.maps_dir);
}

}  // namespace topocal::pipeline
