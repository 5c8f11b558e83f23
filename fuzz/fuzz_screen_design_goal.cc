// Fuzz target: the goal of `design --optimize` (pipeline/screen_design.h). Bad input must be a util::ConfigError;
// anything else escaping (another exception, a crash, a sanitizer report) is a defect. An accepted goal must also be
// valid as the optimiser judges it (IsValid), or the search would throw util::InputError.
#include <cstdlib>

#include "fuzz/fuzz_input.h"
#include "pipeline/screen_design.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const auto goal = topocal::pipeline::ParseScreenDesignGoal(topocal::fuzz::Text(data, size), "fuzz.json");
    if (!goal.IsValid(nullptr)) std::abort();
  } catch (const topocal::util::InputError&) {
  }
  return 0;
}
