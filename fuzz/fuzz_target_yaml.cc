// Fuzz target: the Kalibr-style target description (calib/target.h), YAML through cv::FileStorage.
#include "calib/target.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    topocal::calib::ParseTargetDescription(topocal::fuzz::Text(data, size), "target.yaml");
  } catch (const topocal::util::InputError&) {
  }
  return 0;
}
