// Fuzz target: the topographer configuration (model/config.h). Bad input must be a util::ConfigError; anything else
// escaping (another exception, a crash, a sanitizer report) is a defect.
#include "fuzz/fuzz_input.h"
#include "model/config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    topocal::model::ParseConfig(topocal::fuzz::Text(data, size), "fuzz.json");
  } catch (const topocal::util::InputError&) {
  }
  return 0;
}
