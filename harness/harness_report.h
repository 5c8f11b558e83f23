#pragma once
// What the harness writes (docs/harness.md): every output is a pure function of the merged run — no time, path or
// host in any of them — so N merged shards and a single run give byte-identical files.
#include <string>
#include <utility>
#include <vector>

#include "harness/harness.h"
#include "harness/harness_answer.h"

namespace topocal::harness {

// (file name, content) of every output, in the order they are written:
//   cases.csv, summary.json, table.md, dk_vs_residual.svg, dP_vs_residual.svg
std::vector<std::pair<std::string, std::string>> RenderHarnessOutputs(const HarnessRun& run,
                                                                      const InverseAnswer& answer);

// The inverse answer as the few lines printed on stdout.
std::string HarnessAnswerText(const HarnessRun& run, const InverseAnswer& answer);

}  // namespace topocal::harness
