// Fuzz target: the acceptance limits of the QA report (report/acceptance.h).
#include "fuzz/fuzz_input.h"
#include "report/acceptance.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    topocal::report::LoadLimits(topocal::fuzz::InputFile("limits.json", data, size));
  } catch (const topocal::util::InputError&) {
  }
  return 0;
}
