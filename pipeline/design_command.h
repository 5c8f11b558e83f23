#pragma once
// `topocal design` as a library call: the null screen's target points on the cone for the configuration's ideal
// image (model/null_screen.h), its printable drawing, and with optimize the rings and spots per ring chosen for a
// goal (pipeline/screen_design.h; docs/screen-design.md).
#include <ostream>
#include <string>

#include "util/parallel.h"
#include "util/progress_display.h"

namespace topocal::pipeline {

struct DesignRequest {
  std::string config;      // topographer configuration (JSON)
  std::string out;         // target points, CSV ring,index,x_mm,y_mm,z_mm
  std::string svg;         // also the printable null screen (unrolled cone, 1:1), when not empty
  bool optimize = false;   // choose the design for `goal` first; needs config_out
  std::string goal;        // goal of optimize (JSON); empty: the defaults
  std::string config_out;  // configuration of the chosen design (JSON)
  int jobs = util::AvailableCores();  // threads of optimize; the result does not depend on it
  util::LogLine log;                  // spots that could not be designed, overlapping spots
  util::ShowProgress progress;        // "corneas x candidates" while optimizing
};

// Writes the files (all or none) and prints what was written to `out`, preceded with optimize by the trade-off
// table. InputError for bad options; ConfigError naming the goal when no candidate meets it; std::runtime_error when
// no target point can be designed.
void RunDesign(const DesignRequest& request, std::ostream& out);

}  // namespace topocal::pipeline
