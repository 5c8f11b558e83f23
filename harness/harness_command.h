#pragma once
// `topocal harness` as library calls: the residual-distortion sweep and its inverse answer, run whole or as one shard,
// and the merge of the shards' files into the outputs of a single run (docs/harness.md).
#include <ostream>
#include <string>
#include <vector>

#include "util/parallel.h"
#include "util/progress_display.h"

namespace topocal::harness {

struct HarnessRequest {
  std::string config;  // harness configuration (JSON)
  std::string out;     // output directory (created with the outputs)
  std::string shard;   // "i/N": only that shard's cases, written as OUT/shard-<i>-of-<N>.json; empty: every case
  int jobs = util::AvailableCores();  // threads; the results do not depend on it
  util::ShowProgress progress;        // "cases", done/total, while the cases run
  util::LogLine log;                  // how many cases ran and how fast
};

struct HarnessMergeRequest {
  std::string out;                  // output directory (created with the outputs)
  std::vector<std::string> shards;  // shard files, or directories holding shard-<i>-of-<N>.json files
};

// Runs the cases and writes the tables, plots and answer (or the shard's file), all or none; prints the answer (or
// what the shard wrote) to `out`. InputError for a missing option, a bad shard or an --out that is a file.
void RunHarnessCommand(const HarnessRequest& request, std::ostream& out);

// One shard at a time: memory holds the merged cases and one shard file, whatever the number of shards.
void RunHarnessMerge(const HarnessMergeRequest& request, std::ostream& out);

}  // namespace topocal::harness
