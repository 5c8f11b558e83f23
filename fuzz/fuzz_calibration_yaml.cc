// Fuzz target: the calibration file (calib/calibration_file.h), OpenCV FileStorage YAML/XML/JSON.
#include "calib/calibration_file.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    topocal::calib::ParseCalibrationFile(topocal::fuzz::Text(data, size), "calibration.yaml");
  } catch (const topocal::util::InputError&) {
  }
  return 0;
}
