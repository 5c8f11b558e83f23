// Fuzz target: a Kalibr camchain as `topocal import --from kalibr` reads it (calib/camera_exchange.h): the
// PyYAML-compatibility rewrite (calib/camera_import.cc IndentCompactSequences), the line-shape check before
// OpenCV's YAML parser, the camchain reader for cam0 and cam1, and the read-back of the file import would write.
#include "calib/camera_exchange.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = topocal::fuzz::InputFile("camchain.yaml", data, size);
  for (const char* camera : {"cam0", "cam1"}) {
    try {
      (void)topocal::calib::ImportCalibrationText("kalibr", path, camera);
    } catch (const topocal::util::InputError&) {
    }
  }
  return 0;
}
