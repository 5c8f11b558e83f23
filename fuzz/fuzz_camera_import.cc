// Fuzz target: the readers of other tools' calibrations (calib/camera_exchange.h, calib/camera_import.cc): the
// hand-written reader of mrcal's Python-literal .cameramodel, and the ROS camera_info reader, on the same input.
#include "calib/camera_exchange.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = topocal::fuzz::InputFile("camera-import-input", data, size);
  try {
    topocal::calib::ReadMrcalCameraModel(path);
  } catch (const topocal::util::InputError&) {
  }
  try {
    topocal::calib::ReadRosCameraInfo(path);
  } catch (const topocal::util::InputError&) {
  }
  return 0;
}
