#pragma once
// `topocal compare`: two measurements of one eye (reconstruct --json), each clinical number's change with its U,
// and with both measurements' map directories the change maps (pipeline/measurement_compare.h).
#include <ostream>
#include <string>

namespace topocal::pipeline {

struct CompareRequest {
  std::string a_path, b_path;          // the earlier and the later measurement's JSON
  std::string a_maps_dir, b_maps_dir;  // their --maps directories: both or neither
  std::string maps_dir;                // the change maps (needs both map directories); empty: none
  std::string json_path;               // the comparison as JSON; empty: none
};

// Publishes the change maps and the JSON together, then prints the comparison to `out`. util::InputError for bad
// input or measurements that cannot be compared.
void RunCompare(const CompareRequest& request, std::ostream& out);

}  // namespace topocal::pipeline
