// Fuzz target: the harness configuration and a harness shard (harness/harness_config.h, harness/harness.h).
#include "fuzz/fuzz_input.h"
#include "harness/harness.h"
#include "harness/harness_config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text = topocal::fuzz::Text(data, size);
  try {
    // The design is resolved against the source tree's data/ (a relative "paper.json" in the corpus).
    topocal::harness::ParseHarnessConfig(text, "harness.json", TOPOCAL_SOURCE_DIR "/data");
  } catch (const topocal::util::InputError&) {
  }
  try {
    topocal::harness::ParseHarnessShard(text, "shard.json");
  } catch (const topocal::util::InputError&) {
  }
  return 0;
}
