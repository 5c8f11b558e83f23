// Fuzz target: the topographer camera and the device file (model/topographer_camera.h, model/device.h), both JSON
// through the one strict reader.
#include "fuzz/fuzz_input.h"
#include "model/device.h"
#include "model/topographer_camera.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text = topocal::fuzz::Text(data, size);
  try {
    topocal::model::ParseTopographerCamera(text, "camera.json");
  } catch (const topocal::util::InputError&) {
  }
  try {
    topocal::model::ParseDevice(text, "device.json");
  } catch (const topocal::util::InputError&) {
  }
  return 0;
}
